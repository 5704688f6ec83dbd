"""A job's results as NumPy arrays: parameters (textures as H x W x C, meshes' vertices as N x 3),
images (EXR and PNG, read with OpenImageIO: the pip package's dependency, or Debian's
python3-openimageio for build/python) and the convergence CSV."""

import csv
import json
import re
from pathlib import Path

import numpy as np

from invr._errors import InvrError


def read_image(path):
    """An image file (.exr, .png, .hdr) as a float32 H x W x C array (PNG scaled to [0, 1])."""
    try:
        import OpenImageIO as oiio
    except ImportError as e:  # pragma: no cover - deploy/setup.sh installs it
        raise InvrError("reading images needs OpenImageIO's Python bindings: pip install OpenImageIO (the package depends on "
                        "it), or Debian's python3-openimageio (deploy/setup.sh installs it)") from e
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise InvrError(f"cannot read image '{path}': {oiio.geterror()}")
    try:
        pixels = inp.read_image("float")
    finally:
        inp.close()
    if pixels is None:
        raise InvrError(f"cannot read image '{path}'")
    return np.asarray(pixels, dtype=np.float32)


def read_ply(path):
    """(vertices N x 3 float32, faces M x 3 uint32) of a binary little-endian triangle PLY as invr
    writes it (mesh_<shape>.ply; normals, when present, are skipped)."""
    data = Path(path).read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise InvrError(f"'{path}': not a PLY file")
    header = data[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise InvrError(f"'{path}': only binary little-endian PLY (as invr writes) is read here")
    nverts = nfaces = 0
    vprops = []
    element = None
    for line in header:
        words = line.split()
        if words[:1] == ["element"]:
            element = words[1]
            if element == "vertex":
                nverts = int(words[2])
            elif element == "face":
                nfaces = int(words[2])
        elif words[:1] == ["property"] and element == "vertex":
            if words[1] != "float":
                raise InvrError(f"'{path}': vertex property '{words[-1]}' is not float")
            vprops.append(words[-1])
    body = data[end + len(b"end_header\n"):]
    stride = 4 * len(vprops)
    verts = np.frombuffer(body, dtype="<f4", count=nverts * len(vprops)).reshape(nverts, len(vprops))
    xyz = [vprops.index(c) for c in ("x", "y", "z")]
    faces = np.frombuffer(body, dtype=np.dtype([("n", "u1"), ("i", "<u4", (3,))]), count=nfaces, offset=nverts * stride)
    if nfaces and not np.all(faces["n"] == 3):
        raise InvrError(f"'{path}': a face is not a triangle")
    return np.ascontiguousarray(verts[:, xyz]), np.ascontiguousarray(faces["i"])


class Result:
    """The files of a finished (or failed, or cancelled) job in `dir`:

    - parameters: name -> NumPy array (scalars and colours as 1-D arrays; textures H x W x C;
      vertex parameters the optimised mesh's vertices, N x 3; its faces in meshes[name][1])
    - images: file name -> H x W x C float32 array (final_view0.exr, target_view0.exr, ...)
    - convergence: column name -> NumPy array (step, seconds, loss, image_error, param_error, ...)
    - files: every file name in the folder itself
    - snapshots: step -> Snapshot (optimization.snapshot_every), in step order
    """

    def __init__(self, dir):
        self.dir = Path(dir)
        self.files = sorted(p.name for p in self.dir.iterdir() if p.is_file()) if self.dir.is_dir() else []
        self.parameters = {}
        self.meshes = {}
        pj = self.dir / "parameters.json"
        if pj.exists():
            for name, value in json.loads(pj.read_text()).items():
                if isinstance(value, dict) and "texture" in value:
                    self.parameters[name] = read_image(self.dir / value["texture"])
                elif isinstance(value, dict) and "mesh" in value:
                    self.meshes[name] = read_ply(self.dir / value["mesh"])
                    self.parameters[name] = self.meshes[name][0]
                else:
                    self.parameters[name] = np.asarray(value, dtype=np.float64)
        self._images = None
        self.convergence = _read_csv(self.dir / "convergence.csv")

    @property
    def images(self):
        """Every EXR image (and PNGs without an EXR twin), read on first use."""
        if self._images is None:
            self._images = {}
            for f in self.files:
                p = self.dir / f
                if p.suffix == ".exr" or (p.suffix == ".png" and not p.with_suffix(".exr").exists() and f != "convergence.png"):
                    if f.replace("/", "_") in {v.get("texture") for v in self._parameter_files()}:
                        continue
                    self._images[f] = read_image(p)
        return self._images

    @property
    def snapshots(self):
        """step -> Snapshot: the renders (view -> H x W x C array) and parameters written every
        snapshot_every steps (snapshots/step<k>_view<v>.png, snapshots/step<k>/parameters.json)."""
        if getattr(self, "_snapshots", None) is None:
            found = {}
            root = self.dir / "snapshots"
            if root.is_dir():
                for p in root.iterdir():
                    m = re.fullmatch(r"step(\d+)(?:_view(\d+)\.png)?", p.name)
                    if not m:
                        continue
                    snap = found.setdefault(int(m.group(1)), Snapshot(int(m.group(1)), root))
                    if m.group(2) is not None:
                        snap._views[int(m.group(2))] = p
            self._snapshots = dict(sorted(found.items()))
        return self._snapshots

    def _parameter_files(self):
        pj = self.dir / "parameters.json"
        if not pj.exists():
            return []
        return [v for v in json.loads(pj.read_text()).values() if isinstance(v, dict)]

    def __repr__(self):
        return f"Result({str(self.dir)!r}: {len(self.parameters)} parameters, {len(self.files)} files)"


class Snapshot:
    """One snapshot: .step, .images (view -> float32 H x W x C, PNG in [0, 1]) and .parameters
    (as Result.parameters), read on first use."""

    def __init__(self, step, root):
        self.step = step
        self._root = root
        self._views = {}
        self._images = None
        self._result = None

    @property
    def images(self):
        if self._images is None:
            self._images = {v: read_image(p) for v, p in sorted(self._views.items())}
        return self._images

    @property
    def parameters(self):
        if self._result is None:
            self._result = Result(self._root / f"step{self.step}")
        return self._result.parameters

    def __repr__(self):
        return f"Snapshot(step {self.step}: {len(self._views)} view(s))"


def _read_csv(path):
    if not path.exists():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    header, body = rows[0], rows[1:]
    out = {}
    for i, name in enumerate(header):
        cells = [r[i] if i < len(r) else "" for r in body]
        try:
            out[name] = np.array([float(c) if c != "" else np.nan for c in cells], dtype=np.float64)
        except ValueError:
            out[name] = np.array(cells)
    return out


def read_results(dir):
    """The Result of a results folder (from invr run, fetch or optimize)."""
    if not Path(dir).is_dir():
        raise InvrError(f"'{dir}': no such results folder")
    return Result(dir)
