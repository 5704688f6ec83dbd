#!/usr/bin/python3
"""Writes the wheel of the package the build assembled (build/python/invr: the sources, the gRPC
modules Debian's protoc generated, the generated constants) with no network and no pip: a PEP 427
zip with its dist-info. Its modules come from protoc 3.21, which protobuf's Python runtime runs
from 3.20 to 5.x, hence its requirements (`pip install ./client/python` instead generates them with
grpcio-tools from PyPI and requires what that generation needs).

Usage: make_wheel.py PACKAGE_PARENT OUT_DIR VERSION"""
import base64
import hashlib
import sys
import zipfile
from pathlib import Path

REQUIRES = ["grpcio>=1.51", "protobuf>=3.20,<6", "numpy>=1.21", "OpenImageIO>=2.5"]


def digest(data):
    return "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()


def main():
    parent, out, version = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
    files = sorted(p for p in (parent / "invr").rglob("*")
                   if p.is_file() and "__pycache__" not in p.parts and p.suffix in (".py", ".typed"))
    if not any(p.name == "service_pb2_grpc.py" for p in files):
        raise SystemExit(f"make_wheel: {parent}/invr has no generated gRPC modules")
    info = f"invr-{version}.dist-info"
    meta = "\n".join(["Metadata-Version: 2.1", "Name: invr", f"Version: {version}",
                      "Summary: Client of the invr inverse-rendering service: submit jobs, watch them, read results as NumPy arrays",
                      "Requires-Python: >=3.9"] + [f"Requires-Dist: {r}" for r in REQUIRES] +
                     ["Provides-Extra: progress", 'Requires-Dist: tqdm>=4.60; extra == "progress"']) + "\n"
    wheel = "Wheel-Version: 1.0\nGenerator: invr make_wheel.py\nRoot-Is-Purelib: true\nTag: py3-none-any\n"
    entries = [(p.relative_to(parent).as_posix(), p.read_bytes()) for p in files]
    entries += [(f"{info}/METADATA", meta.encode()), (f"{info}/WHEEL", wheel.encode()), (f"{info}/top_level.txt", b"invr\n")]
    record = "".join(f"{name},{digest(data)},{len(data)}\n" for name, data in entries) + f"{info}/RECORD,,\n"
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"invr-{version}-py3-none-any.whl"
    tmp = path.with_suffix(".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in entries + [(f"{info}/RECORD", record.encode())]:
            zi = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))  # the same bytes from the same files
            zi.compress_type = zipfile.ZIP_DEFLATED
            zi.external_attr = 0o644 << 16
            z.writestr(zi, data)
    tmp.replace(path)


if __name__ == "__main__":
    main()
