"""invr beside Mitsuba 3 on the same scenes (deploy/peers.sh runs this in the peer's venv).

Per scene: `invr export <zoo scene>` writes the scene once (Mitsuba XML, PLY meshes, EXR
textures) and the job over it; both renderers read that file. Then
  forward   K renders per renderer at equal spp (different seeds); the two mean images compared
            per 8x8 block against the spread of the seeds (ratio 1 = agreement within noise);
  gradient  the loss gradient at the job's start with respect to its parameters: invr's PT, RIS
            and ReSTIR (`invr-lab bench gradient-vector`, independent evaluations, plus finite
            differences of invr's own renders) against Mitsuba's (llvm_ad_rgb, independent seeds
            for primal and adjoint), per component as a z-score;
  speed     the median time of one gradient step at equal spp on the same threads, Mitsuba's first
            (JIT-compiling) step reported apart;
  time to error  the job's own optimisation (Adam, its rates and half-life) in both, the time each
            takes to reach the same parameter error.
Prints one JSON object (or writes it to --out); progress goes to stderr. Mitsuba's step time
includes its params.update() (a BVH rebuild when vertices move), as each step of a Mitsuba
optimisation does; invr's is GradientEngine::evaluate, the parameters already written.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

import numpy as np

import drjit as dr
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
# Mitsuba's log writes to standard output; the report goes to --out.
mi.set_log_level(mi.LogLevel.Error)

# The zoo jobs compared, and variants of them. pose-vertices: the pose box's vertices as the
# parameter, started from a copy of the box moved by 3 % of its size. Two variants remove a
# modelling difference found here (docs/peers.md) from the exported file that both renderers
# read: oxalis-hard-spots (each spot's beam width set to its cut-off: no fall-off ramp, whose
# shape differs) and backlit-fine-sky (the sky's texels repeated 8x8: Mitsuba interpolates the
# map bilinearly with rows from pole to pole, invr looks it up piecewise constant).
SCENES = ["cornell", "oxalis", "mirror", "backlit", "pose", "knot", "pose-vertices", "oxalis-hard-spots", "backlit-fine-sky"]
# The default run leaves out backlit-fine-sky: its 64x larger sky makes invr's ReSTIR evaluations
# over 16 views take over 10 minutes; name it with --scenes.
DEFAULT_SCENES = [s for s in SCENES if s != "backlit-fine-sky"]
# Finite differences step h = this times each value's learning rate (default 1). pose-vertices: at
# the rate (0.0088, 1.2 % of the box) the moved corner's difference is 17 % off its limit (x of
# vertex 2: 3.25e-3 at h, 3.42e-3 at h/2, 3.81e-3 +- 1e-4 at h/4; invr's PT 3.66e-3 +- 6e-5), so
# both renderers' differences take a quarter of it (docs/peers.md).
FD_SCALE = {"pose-vertices": 0.25}
ZOO = {"pose-vertices": "pose", "oxalis-hard-spots": "oxalis", "backlit-fine-sky": "backlit"}


def weld_moving_meshes(xml, job):
    """Mitsuba's projective integrators find a mesh's edges from its vertex indices: a flat-shaded
    mesh written with a copy of each vertex per face (as invr exports face_normals meshes) has an
    open edge along every crease, and its boundary terms then count each crease's jump once per
    copy (measured on pose: primary term 2.1x, secondary 3.6x Mitsuba's own finite differences).
    With --weld-moving-meshes the meshes that shape parameters move are rewritten with one vertex
    per position (flat shading, no texture coordinates: nothing else changes); both renderers
    read the rewrite. Mitsuba then samples silhouettes only and misses the creases' term."""
    import re
    shapes = {p["name"].split("/")[1] for p in json.load(open(job))["optimization"]["parameters"] if p["name"].startswith("shapes/")}
    text = open(xml).read()
    for sid, rel in re.findall(r'<shape type="ply" id="([^"]+)">\s*<string name="filename" value="([^"]+)"', text):
        if sid not in shapes:
            continue
        path = os.path.join(os.path.dirname(xml), rel)
        mesh = mi.load_dict({"type": "ply", "filename": path, "face_normals": True})
        mp = mi.traverse(mesh)
        block = re.search(rf'<shape type="ply" id="{sid}">(.*?)</shape>', text, re.S).group(1)
        bsdf = re.search(r'<ref id="([^"]+)"', block).group(1)
        if "<texture" in re.search(rf'<bsdf [^>]*id="{bsdf}">(.*?)\n  </bsdf>', text, re.S).group(1):
            raise ValueError(f"{sid}: a textured moving mesh: welding would lose its uv seams")
        pos = np.array(mp["vertex_positions"], dtype=np.float64).reshape(-1, 3)
        faces = np.array(mp["faces"], dtype=np.int64).reshape(-1, 3)
        uniq, first, inverse = np.unique(pos, axis=0, return_index=True, return_inverse=True)
        order = np.argsort(first)  # keep first-occurrence order, as invr welds
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        welded = mi.Mesh(sid, len(uniq), len(faces), has_vertex_normals=False, has_vertex_texcoords=False)
        wp = mi.traverse(welded)
        wp["vertex_positions"] = mi.Float(uniq[order].astype(np.float32).ravel())
        wp["faces"] = mi.UInt32(rank[inverse.ravel()][faces].astype(np.uint32).ravel())
        wp.update()
        out = rel[:-4] + "_welded.ply"
        welded.write_ply(os.path.join(os.path.dirname(xml), out))
        text = text.replace(f'value="{rel}"', f'value="{out}"')
    open(xml, "w").write(text)


def make_variant(scene, xml):
    import re
    text = open(xml).read()
    if scene == "oxalis-hard-spots":
        def hard(m):
            block = m.group(0)
            cutoff = re.search(r'name="cutoff_angle" value="([^"]+)"', block).group(1)
            return re.sub(r'(name="beam_width" value=")[^"]+(")', lambda b: b.group(1) + cutoff + b.group(2), block)
        text = re.sub(r'<emitter type="spot".*?</emitter>', hard, text, flags=re.S)
        open(xml, "w").write(text)
    elif scene == "backlit-fine-sky":
        path = os.path.join(os.path.dirname(xml), re.search(r'<emitter type="envmap".*?name="filename" value="([^"]+)"', text, re.S).group(1))
        sky = np.array(mi.Bitmap(path), dtype=np.float32)
        mi.Bitmap(np.repeat(np.repeat(sky, 8, axis=0), 8, axis=1)).write(path)


def log(*a):
    print("peers:", *a, file=sys.stderr, flush=True)


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {r.returncode}: {r.stderr.strip()[-2000:]}")
    return r.stdout


def read_exr(path):
    return np.array(mi.Bitmap(str(path)), dtype=np.float64)[..., :3]


def blocks(x):
    h, w = x.shape[0] // 8 * 8, x.shape[1] // 8 * 8
    return x[:h, :w].reshape(h // 8, 8, w // 8, 8, 3).mean(axis=(1, 3))


# ---------------------------------------------------------------- the scene in Mitsuba


class MitsubaJob:
    """The exported scene with the job's parameters bound to Mitsuba's differentiable values."""

    def __init__(self, xml, invr_vec, targets, spp):
        self.scene = mi.load_file(str(xml))
        self.params = mi.traverse(self.scene)
        self.spp = spp
        self.loss_kind = invr_vec["loss"]
        self.targets = [mi.TensorXf(t.astype(np.float32)) for t in targets]
        self.theta = np.array(invr_vec["theta"], dtype=np.float64)
        self.truth = np.array(invr_vec["truth"], dtype=np.float64)
        self.slots = invr_vec["parameters"]
        depth = int(invr_vec["max_depth"])
        shapes = any(s["name"].startswith("shapes/") for s in self.slots)
        # Direct illumination: Mitsuba's projective direct integrator (boundary terms for shapes);
        # paths: PRB (projective for shapes). Mitsuba counts the emitter's vertex: depth + 1.
        if depth <= 1:
            spec = {"type": "direct_projective"} if shapes else {"type": "prb", "max_depth": 2}
        else:
            spec = {"type": "prb_projective" if shapes else "prb", "max_depth": depth + 1, "rr_depth": int(invr_vec["rr_depth"]) + 1}
        self.integrator = mi.load_dict(spec)
        self.integrator_name = ", ".join(f"{k} {v}" for k, v in spec.items())
        self.keys = [self.key_of(s) for s in self.slots]
        self.forward = mi.load_dict({"type": "path", "max_depth": depth + 1, "rr_depth": int(invr_vec["rr_depth"]) + 1})
        self.rest = {}  # shape slots: the rest positions (the exported truth) and pivot
        for s, k in zip(self.slots, self.keys):
            if s["name"].startswith("shapes/"):
                p = np.array(self.params[k], dtype=np.float64).reshape(-1, 3)
                self.rest[s["name"]] = (p, 0.5 * (p.min(axis=0) + p.max(axis=0)))
        self.check_order()

    def key_of(self, slot):
        name = slot["name"]
        parts = name.split("/")
        keys = list(self.params.keys())
        def find(*suffixes):
            for suf in suffixes:
                for k in keys:
                    if k in (parts[1] + suf, parts[1] + ".brdf_0" + suf):
                        return k
            raise KeyError(f"{name}: no Mitsuba key among {[k for k in keys if k.startswith(parts[1])]}")
        if parts[0] == "materials" and parts[2] == "albedo":
            return find(".reflectance.value", ".reflectance.data", ".diffuse_reflectance.value", ".diffuse_reflectance.data")
        if parts[0] == "materials" and parts[2] == "roughness":
            return find(".alpha.value", ".alpha")
        if parts[0] == "lights":
            try:
                return find(".radiance.value", ".intensity.value", ".radiance.data")
            except KeyError:  # an area light is named after its emitter, keyed by its shape
                for k in keys:
                    if k.endswith(".emitter.radiance.value") and parts[1] in k:
                        return k
                raise
        if parts[0] == "shapes":
            return find(".vertex_positions")
        raise KeyError(f"{name}: no Mitsuba equivalent in this comparison")

    def slot(self, name):
        return next(s for s in self.slots if s["name"] == name)

    def theta_of(self, name):
        s = self.slot(name)
        return self.theta[s["offset"]: s["offset"] + s["size"]]

    def truth_of(self, name):
        s = self.slot(name)
        return self.truth[s["offset"]: s["offset"] + s["size"]]

    def check_order(self):
        # The exported values must read back as theta's truth in theta's order (texel order,
        # channels): a transposed or flipped texture would show here, not as a gradient mismatch.
        for s, k in zip(self.slots, self.keys):
            if s["name"].startswith("shapes/"):
                continue
            mine = np.array(self.params[k], dtype=np.float64).ravel()
            truth = self.truth[s["offset"]: s["offset"] + s["size"]]
            if mine.size != truth.size or np.max(np.abs(mine - truth)) > 1e-4 * max(1.0, np.max(np.abs(truth))):
                raise ValueError(f"{s['name']}: Mitsuba's {k} does not read back as invr's values (size {mine.size} against {truth.size})")

    def set_theta(self, theta, grad=False):
        """Writes theta into the scene; returns the differentiable leaves per slot."""
        leaves = []
        motions = {}  # shape key -> {kind: leaf}: a shape's translation and rotation act together
        for s, k in zip(self.slots, self.keys):
            v = theta[s["offset"]: s["offset"] + s["size"]]
            name = s["name"]
            if name.startswith("shapes/"):
                leaf = mi.Float(v.astype(np.float32))
                if grad:
                    dr.enable_grad(leaf)
                motions.setdefault(k, {"name": name})[name.split("/")[2]] = leaf
            else:
                cur = self.params[k]
                if isinstance(cur, mi.TensorXf):
                    leaf = mi.TensorXf(v.astype(np.float32).reshape(cur.shape))
                elif isinstance(cur, mi.Color3f):
                    leaf = mi.Color3f(*[float(x) for x in v])
                else:
                    leaf = type(cur)(float(v[0]))
                if grad:
                    dr.enable_grad(leaf)
                self.params[k] = leaf
            leaves.append(leaf)
        for k, m in motions.items():
            self.params[k] = self.moved(m)
        self.params.update()
        return leaves

    def moved(self, m):
        """A shape's vertex positions under its parameters: its vertices themselves, or
        p -> pivot + R (rest - pivot) + translation (core/scene/shape_motion.h)."""
        name = m["name"]
        rest, pivot = self.rest[name]
        if "vertices" in m:
            # invr's values are welded vertices (copies at one position are one vertex): each of
            # Mitsuba's vertices gathers the welded vertex at its position.
            leaf = m["vertices"]
            truth = self.truth_of(name).reshape(-1, 3)
            dist = np.linalg.norm(rest[:, None, :] - truth[None, :, :], axis=2)
            w = dist.argmin(axis=1)
            if dist[np.arange(len(w)), w].max() > 1e-5:
                raise ValueError(f"{name}: Mitsuba's vertices do not match invr's welded vertices")
            idx = (3 * w[:, None] + np.arange(3)[None, :]).ravel()
            return dr.gather(mi.Float, leaf, mi.UInt32(idx.astype(np.uint32)))
        unknown = set(m) - {"name", "translation", "rotation"}
        if unknown:
            raise KeyError(f"{name}: {', '.join(sorted(unknown))} not in this comparison")
        r = mi.Point3f(*[mi.Float(rest[:, i].astype(np.float32)) for i in range(3)])
        piv = mi.Point3f(*[float(x) for x in pivot])
        p = mi.Vector3f(r - piv)
        if "rotation" in m:  # Euler degrees about x, then y, then z, about the pivot
            c = [dr.gather(mi.Float, m["rotation"], i) for i in range(3)]  # differentiable components
            t = (mi.Transform4f().rotate([0, 0, 1], c[2]) @ mi.Transform4f().rotate([0, 1, 0], c[1])
                 @ mi.Transform4f().rotate([1, 0, 0], c[0]))
            p = t @ p
        p = piv + p
        if "translation" in m:
            c = [dr.gather(mi.Float, m["translation"], i) for i in range(3)]
            p = p + mi.Vector3f(c[0], c[1], c[2])
        return dr.ravel(p)

    def loss(self, img, v):
        t = self.targets[v]
        d = img - t
        if self.loss_kind == "relative_l2":
            return dr.mean(dr.square(d) / (dr.square(t) + 0.01), axis=None)
        if self.loss_kind == "l2":
            return dr.mean(dr.square(d), axis=None)
        raise ValueError(f"loss {self.loss_kind}: not in this comparison")

    def gradient(self, theta, seed, views=None):
        """dL/dtheta and the seconds it took (primal and adjoint passes of every view, or of the
        mini-batch `views`, the loss their mean)."""
        t0 = time.perf_counter()
        leaves = self.set_theta(theta, grad=True)
        if views is None:
            views = list(range(len(self.scene.sensors())))
        total = 0
        for v in views:
            img = mi.render(self.scene, self.params, integrator=self.integrator, sensor=v, spp=self.spp, seed=seed * 64 + v,
                            seed_grad=(seed * 64 + v) ^ 0x5bd1e995)
            total = total + self.loss(img, v) / len(views)
        dr.backward(total)
        g = np.concatenate([np.array(dr.grad(l), dtype=np.float64).ravel() for l in leaves])
        return g, time.perf_counter() - t0

    def unbiased_loss(self, theta, rep, spp):
        """The loss of the expected image from two independent renders per view (loss.h's
        unbiasedImageLoss), rendered by Mitsuba's (non-differentiable) path integrator; rep picks
        the random numbers, the same at theta + h and theta - h."""
        self.set_theta(theta)
        views = len(self.scene.sensors())
        total = 0.0
        for v in range(views):
            a, b = (np.array(mi.render(self.scene, self.params, integrator=self.forward, sensor=v, spp=spp,
                                       seed=(rep * views + v) * 2 + k + 7919), dtype=np.float64) for k in (0, 1))
            t = np.array(self.targets[v], dtype=np.float64)
            w = 1.0 / (t * t + 0.01) if self.loss_kind == "relative_l2" else 1.0
            total += float(np.mean((a - t) * (b - t) * w)) / views
        return total

    def finite_differences(self, fd, reps, spp):
        """Central differences as invr's bench takes them (fd: its mode, direction and scale; h
        the scale times each value's learning rate, along a direction the smallest of them):
        per-rep values."""
        lr = np.concatenate([[s["learning_rate"]] * s["size"] for s in self.slots])
        dirs = [np.eye(len(self.theta))[k] for k in range(len(self.theta))] if fd["mode"] == "components" else [np.array(fd["direction"])]
        out = np.zeros((reps, len(dirs)))
        for j, d in enumerate(dirs):
            h = float(fd.get("scale", 1.0)) * float(np.min(lr[d != 0]))
            for r in range(reps):
                out[r, j] = (self.unbiased_loss(self.theta + h * d, r, spp) - self.unbiased_loss(self.theta - h * d, r, spp)) / (2 * h)
        return out

    def render(self, v, seed, spp):
        self.set_theta(self.truth, grad=False)  # the scene as exported, as `invr render` reads it
        return np.array(mi.render(self.scene, self.params, integrator=self.integrator, sensor=v, spp=spp, seed=seed), dtype=np.float64)


# ---------------------------------------------------------------- statistics


def value_groups(slots):
    """Index arrays: one per value, or per 8x8 texel tile and channel of a texture."""
    groups = []
    for s in slots:
        off, size, w, h, c = s["offset"], s["size"], s.get("width", 0), s.get("height", 0), s.get("channels", 3)
        if w > 0 and h > 0 and w * h * c == size:
            idx = np.arange(size).reshape(h, w, c)
            for y in range(0, h, 8):
                for x in range(0, w, 8):
                    for ch in range(c):
                        groups.append(off + idx[y:y + 8, x:x + 8, ch].ravel())
        else:
            groups.extend(np.array([off + k]) for k in range(size))
    return groups


def z_threshold(alpha, n):
    """|z| that the largest of n independent standard normals exceeds with probability alpha."""
    target = alpha / n  # two-sided tail per value (Bonferroni)
    lo, hi = 0.0, 40.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if math.erfc(mid / math.sqrt(2)) > target else (lo, mid)
    return lo


def z_scores(a, sa, b, sb):
    """(a - b) over the combined standard error, per value. Both renderers accumulate gradients
    in single precision, so a value below about 1e-6 of its vector's largest is zero within
    their arithmetic: the error gets that floor. Without it a derivative that is zero (a hidden
    vertex moved along its own edge: the finite difference is exactly 0 with 0 spread) against
    an analytic value of 2e-11 +- 1e-12, a rounding residue, reads as |z| 16."""
    a, sa, b, sb = (np.asarray(x, dtype=np.float64) for x in (a, sa, b, sb))
    floor = 1e-6 * max(float(np.max(np.abs(a), initial=0.0)), float(np.max(np.abs(b), initial=0.0)))
    return (a - b) / np.sqrt(sa ** 2 + sb ** 2 + floor ** 2 + 1e-300)


def fd_z(fd, samples):
    """Largest |z| of finite differences against per-evaluation gradients (per value, or g.u
    along the difference's direction)."""
    fv, fs = np.array(fd["values"]), np.array(fd["se"])
    if fd["mode"] == "components":
        g = samples
    else:
        g = (samples @ np.array(fd["direction"]))[:, None]
    gm, gse = g.mean(0), g.std(0, ddof=1) / math.sqrt(len(g))
    return float(np.max(np.abs(z_scores(fv, fs, gm, gse))))


# ---------------------------------------------------------------- one scene


def compare(scene, a, work):
    d = os.path.join(work, scene)
    os.makedirs(d, exist_ok=True)
    zoo = ZOO.get(scene, scene)
    xml = os.path.join(d, "scene.xml")
    run([a.invr, "export", zoo, "-o", xml])
    make_variant(scene, xml)
    job = os.path.join(d, "scene.json")
    if a.weld_moving_meshes:
        weld_moving_meshes(xml, job)
    out = {"zoo": zoo}
    extra = []
    if scene == "pose-vertices":
        # The box's welded vertices (first occurrence first, as invr welds), started 3 % of its
        # size away along a diagonal.
        shape = next(p["name"].split("/")[1] for p in json.load(open(job))["optimization"]["parameters"] if p["name"].startswith("shapes/"))
        raw = np.array(mi.traverse(mi.load_file(xml))[shape + ".vertex_positions"], dtype=np.float64).reshape(-1, 3)
        welded = []
        for v in raw:
            if not any(np.array_equal(v, w) for w in welded):
                welded.append(v)
        welded = np.array(welded)
        start = welded + 0.03 * np.ptp(welded, axis=0).max() * np.array([1.0, 0.5, -0.5])
        extra = ["--param", f"shapes/{shape}/vertices=" + ",".join(f"{x:.7g}" for x in start.ravel())]
    # invr's gradients (and its targets, which Mitsuba's loss uses too).
    log(scene, "invr gradients")
    vec = json.loads(run([a.invr_lab, "bench", "gradient-vector", job, *extra, "--evaluations", str(a.evaluations), "--spp", str(a.spp),
                          "--fd-evaluations", str(a.fd_evaluations), "--fd-scale", str(FD_SCALE.get(scene, 1.0)), "--targets-out", os.path.join(d, "targets"), "--per-evaluation",
                          "--json"]))
    json.dump(vec, open(os.path.join(d, "invr_gradient.json"), "w"))
    views = int(vec["views"])
    targets = [read_exr(os.path.join(d, "targets", f"target_view{v}.exr")) for v in range(views)]
    mj = MitsubaJob(xml, vec, targets, a.spp)
    out["integrator_mitsuba"] = mj.integrator_name
    out["parameters"] = [s["name"] for s in vec["parameters"]]
    out["method_job"] = vec["job_method"]
    out["mitsuba_keys"] = mj.keys

    # Forward: K seeds each at equal spp, view 0, the scene as exported (its truth).
    log(scene, "forward")
    K, spp = a.forward_seeds, a.forward_spp
    inv, mit = [], []
    for k in range(K):
        p = os.path.join(d, f"invr_{k}.exr")
        run([a.invr, "render", "--scene", xml, "--spp", str(spp), "--seed", str(k + 1), "-o", p])
        inv.append(blocks(read_exr(p)))
        mit.append(blocks(mj.render(0, k + 1, spp)))
    inv, mit = np.array(inv), np.array(mit)
    cross = np.mean((inv.mean(0) - mit.mean(0)) ** 2)
    expected = np.mean(inv.var(0, ddof=1) / K + mit.var(0, ddof=1) / K)
    nb = inv[0].size
    out["forward_block_ratio"] = float(cross / expected)
    # Under agreement the ratio is about 1; its spread is wider than sqrt(2 / blocks) because a
    # few blocks (an emitter's outline) hold most of the noise. cli.export's bound for one render
    # per side is 2; means of many seeds get a tighter one.
    out["forward_within_noise"] = bool(cross / expected < 1.5)
    out["forward_mean_invr"] = float(inv.mean())
    out["forward_mean_mitsuba"] = float(mit.mean())
    out["forward_blocks"] = int(nb // 3)

    # Mitsuba's gradients: independent seeds, the first (JIT) step timed apart.
    log(scene, "mitsuba gradients")
    gs, ts = [], []
    first = None
    for i in range(a.mitsuba_evaluations + 1):
        g, t = mj.gradient(mj.theta, seed=i + 1)
        if i == 0:
            first = t
            continue
        gs.append(g)
        ts.append(t)
    gs = np.array(gs)
    g_mi, se_mi = gs.mean(0), gs.std(0, ddof=1) / math.sqrt(len(gs))

    # Agreement: z-scores of groups of values, each value alone except a texture's, summed over
    # 8x8-texel tiles per channel (a texel's own derivative is mostly noise, a tile's is not).
    # Standard errors from the spread of independent evaluations on each side. Under agreement
    # the largest of n |z| exceeds z_threshold (normal tails, 1 % for the whole vector) once in
    # a hundred comparisons.
    groups = value_groups(vec["parameters"])
    n = len(groups)
    out["gradient_groups"] = n
    out["gradient_z_threshold"] = z_threshold(0.01, n)
    def grouped(samples):
        return np.stack([samples[:, g].sum(axis=1) for g in groups], axis=1)
    def mean_se(x):
        return x.mean(0), x.std(0, ddof=1) / math.sqrt(len(x))
    gm_g, sm_g = mean_se(grouped(gs))
    per = {}
    for m, mv in vec["methods"].items():
        samples = np.array(mv["samples"])
        gi, si = mean_se(grouped(samples))
        z = z_scores(gi, si, gm_g, sm_g)
        full = samples.mean(0)
        per[m] = {"max_abs_z": float(np.max(np.abs(z))), "mean_z2": float(np.mean(z ** 2)),
                  "worst_group": int(np.argmax(np.abs(z))),
                  "rel_diff": float(np.linalg.norm(full - g_mi) / max(np.linalg.norm(g_mi), 1e-300)),
                  "step_seconds": mv["step_seconds"], "evaluations": len(samples)}
        if "fd" in vec:
            per[m]["fd_max_abs_z"] = fd_z(vec["fd"], samples)
    if "fd" in vec:
        per["mitsuba"] = {"fd_max_abs_z": fd_z(vec["fd"], gs), "evaluations": len(gs)}
        if a.mitsuba_fd_evaluations > 1:
            # Mitsuba's own finite differences: which renderer's derivative its own images support.
            log(scene, "mitsuba finite differences")
            mfd = mj.finite_differences(vec["fd"], a.mitsuba_fd_evaluations, int(vec["fd"]["spp"]))
            mfd_spec = {"mode": vec["fd"]["mode"], "direction": vec["fd"].get("direction"),
                        "values": mfd.mean(0).tolist(), "se": (mfd.std(0, ddof=1) / math.sqrt(len(mfd))).tolist()}
            out["mitsuba_fd"] = {"values": mfd_spec["values"], "se": mfd_spec["se"]}
            per["mitsuba"]["mitsuba_fd_max_abs_z"] = fd_z(mfd_spec, gs)
            for m, mv in vec["methods"].items():
                per[m]["mitsuba_fd_max_abs_z"] = fd_z(mfd_spec, np.array(mv["samples"]))
            fv, fs = np.array(vec["fd"]["values"]), np.array(vec["fd"]["se"])
            out["fd_invr_vs_mitsuba_max_abs_z"] = float(np.max(np.abs(z_scores(fv, fs, mfd.mean(0), mfd_spec["se"]))))
    out["gradient_by_method"] = per
    if "skipped_methods" in vec:
        out["gradient_skipped_methods"] = vec["skipped_methods"]
    out["gradient_mitsuba"] = g_mi.tolist() if g_mi.size <= 48 else None
    out["gradient_mitsuba_se"] = se_mi.tolist() if g_mi.size <= 48 else None
    out["gradient_invr"] = {m: mv["gradient"] for m, mv in vec["methods"].items()} if g_mi.size <= 48 else None
    out["gradient_max_abs_z"] = max(per[m]["max_abs_z"] for m in vec["methods"])
    out["gradient_rel_diff"] = max(per[m]["rel_diff"] for m in vec["methods"])
    out["gradient_within_noise"] = bool(out["gradient_max_abs_z"] <= out["gradient_z_threshold"])
    out["step_seconds_mitsuba"] = float(np.median(ts))
    out["first_step_seconds_mitsuba"] = float(first)
    # The headline pair: invr with the job's own method (ReSTIR where the job says so).
    job_method = vec["job_method"] if vec["job_method"] in vec["methods"] else "pt"
    out["step_seconds_invr"] = vec["methods"][job_method]["step_seconds"]
    out["step_method_invr"] = job_method
    out["ratio_step_mitsuba_over_invr"] = float(np.median(ts)) / out["step_seconds_invr"]
    out["step_seconds_invr_by_method"] = {m: mv["step_seconds"] for m, mv in vec["methods"].items()}
    out["ratio_step_mitsuba_over_invr_by_method"] = {m: float(np.median(ts)) / mv["step_seconds"] for m, mv in vec["methods"].items()}
    out["spp"] = a.spp
    if a.terms and any(p.startswith("shapes/") for p in out["parameters"]):
        out["terms"] = boundary_terms(scene, a, d, job, extra, mj)
    if a.time_to_error_steps > 0:
        try:
            out.update(time_to_error(scene, a, d, job, extra, vec, mj))
        except Exception as e:  # the figures above stand; this one says why it is missing
            log(scene, "time to error FAILED:", e)
            out["time_to_error_error"] = str(e)
    return out


def boundary_terms(scene, a, d, job, extra, mj):
    """Shape gradients split by term: Mitsuba's projective integrator with its primary (sppp) or
    secondary (sppi) boundary samples off, invr with optimization.boundary.primary or .secondary
    false. The interior is what remains with both off."""
    log(scene, "gradient terms")
    out = {"mitsuba": {}, "invr_pt": {}}
    n = a.mitsuba_evaluations
    base = {"type": "direct_projective"}
    for name, extra_spec in (("all", {}), ("no_primary", {"sppp": 0}), ("no_secondary", {"sppi": 0}), ("interior", {"sppp": 0, "sppi": 0})):
        keep = mj.integrator
        mj.integrator = mi.load_dict({**base, **extra_spec})
        g = np.array([mj.gradient(mj.theta, seed=i + 1)[0] for i in range(n)])
        mj.integrator = keep
        out["mitsuba"][name] = {"gradient": g.mean(0).tolist(), "se": (g.std(0, ddof=1) / math.sqrt(n)).tolist()}
    for name, sets in (("all", []), ("no_primary", ["optimization.boundary.primary=false"]), ("no_secondary", ["optimization.boundary.secondary=false"])):
        cmd = [a.invr_lab, "bench", "gradient-vector", job, *extra, "--methods", "pt", "--evaluations", str(a.evaluations), "--spp", str(a.spp), "--json"]
        for x in sets:
            cmd += ["--set", x]
        v = json.loads(run(cmd))["methods"]["pt"]
        out["invr_pt"][name] = {"gradient": v["gradient"], "se": v["se"]}
    return out


def time_to_error(scene, a, d, job, extra, vec, mj):
    """The job's optimisation in both renderers (its method in invr; Adam with the job's rates,
    half-life and bounds in both; the job's spp and views per step): the seconds each needs to
    reach the same parameter error, half the starting error or, when invr does not halve it,
    1.05 times invr's best. Mitsuba runs until it gets there, for up to 3x invr's steps or
    --time-to-error-budget seconds; when it does not, the ratio is a lower bound (reached: false)."""
    import csv
    import re
    steps = a.time_to_error_steps
    log(scene, f"time to error: invr, {steps} steps")
    res = os.path.join(d, "optimize")
    txt = run([a.invr, "optimize", job, *extra, "--steps", str(steps), "--final-spp", "4", "-o", res])
    m = re.search(r"\(targets ([0-9.e+-]+) s\)", txt)
    targets_s = float(m.group(1)) if m else 0.0  # the targets' render is not part of the optimisation
    rows = list(csv.DictReader(open(os.path.join(res, "convergence.csv"))))
    if not rows or not rows[0].get("param_error"):
        return {"time_to_error_note": "the job has no parameter error (no known truth)"}
    t_inv = [float(r["seconds"]) - targets_s for r in rows]
    e_inv = [float(r["param_error"]) for r in rows]
    truth = mj.truth
    theta = mj.theta.copy()
    e0 = float(np.sqrt(np.mean((theta - truth) ** 2)))
    target = max(0.5 * e0, 1.05 * min(e_inv))
    ti = next(t for t, e in zip(t_inv, e_inv) if e <= target)
    log(scene, f"time to error: mitsuba, to {target:.4g} (invr took {ti:.3g} s)")
    bound = lambda x, inf: inf if x is None else x  # the bench prints infinite bounds as null
    lo = np.concatenate([[bound(s["lower"], -np.inf)] * s["size"] for s in mj.slots])
    hi = np.concatenate([[bound(s["upper"], np.inf)] * s["size"] for s in mj.slots])
    lr = np.concatenate([[s["learning_rate"]] * s["size"] for s in mj.slots])
    half = float(vec["learning_rate_half_life"])
    views = int(vec["views"])
    vps = int(vec["views_per_step"]) or views
    mj.spp = max(int(vec["job_spp_primal"]), int(vec["job_spp_gradient"]))
    mm, vv = np.zeros_like(theta), np.zeros_like(theta)
    tm, e_mi, elapsed = None, e0, 0.0
    start = time.perf_counter()
    for t in range(3 * steps):
        batch = [(t * vps + j) % views for j in range(vps)]
        g, _ = mj.gradient(theta, seed=100000 + t, views=batch)
        mm = 0.9 * mm + 0.1 * g
        vv = 0.999 * vv + 0.001 * g * g
        mh, vh = mm / (1 - 0.9 ** (t + 1)), vv / (1 - 0.999 ** (t + 1))
        rate = lr * (half / (half + t) if half > 0 else 1.0)
        theta = np.clip(theta - rate * mh / (np.sqrt(vh) + 1e-8), lo, hi)
        elapsed = time.perf_counter() - start  # Mitsuba's JIT compilation included: a user waits for it too
        e_mi = float(np.sqrt(np.mean((theta - truth) ** 2)))
        if e_mi <= target:
            tm = elapsed
            break
        if elapsed > a.time_to_error_budget:
            break
    mj.spp = a.spp
    return {"time_to_error_target": target, "time_to_error_start": e0, "time_to_error_invr_s": ti,
            "time_to_error_mitsuba_s": tm, "time_to_error_mitsuba_reached": tm is not None,
            "time_to_error_mitsuba_over_invr": (tm if tm is not None else elapsed) / ti if ti > 0 else None,
            "time_to_error_steps_invr": steps, "time_to_error_steps_mitsuba": t + 1,
            "final_error_invr": e_inv[-1], "last_error_mitsuba": e_mi}


def print_table(rep):
    v = rep["versions"]
    print(f"invr beside Mitsuba {v['mitsuba']} (drjit {v['drjit']}, {v['variant']}); {v['invr']}")
    cols = ["forward_block_ratio", "forward_within_noise", "gradient_max_abs_z", "gradient_z_threshold", "gradient_within_noise",
            "gradient_rel_diff", "step_seconds_mitsuba",
            "step_method_invr", "step_seconds_invr", "ratio_step_mitsuba_over_invr", "ratio_step_mitsuba_over_invr_by_method",
            "fd_invr_vs_mitsuba_max_abs_z", "time_to_error_target", "time_to_error_invr_s", "time_to_error_mitsuba_s",
            "time_to_error_mitsuba_over_invr", "time_to_error_mitsuba_reached"]
    for name, s in rep["scenes"].items():
        if "error" in s:
            print(f"  {name}: FAILED: {s['error']}")
            continue
        print(f"  {name} ({', '.join(s['parameters'])}; job method {s['method_job']})")
        for c in cols:
            x = s.get(c)
            if isinstance(x, dict):
                x = ", ".join(f"{k} {y:.3g}" for k, y in x.items())
            elif isinstance(x, float):
                x = f"{x:.4g}"
            print(f"    {c:34s} {x}")
        for m, g in s["gradient_by_method"].items():
            line = f"    {m:10s}"
            if "max_abs_z" in g:
                line += f" against Mitsuba: max |z| {g['max_abs_z']:.2f}, rel diff {g['rel_diff']:.3g};"
            if "fd_max_abs_z" in g:
                line += f" against invr's finite differences: max |z| {g['fd_max_abs_z']:.2f}"
            if "mitsuba_fd_max_abs_z" in g:
                line += f", Mitsuba's: {g['mitsuba_fd_max_abs_z']:.2f}"
            print(line)


def print_markdown(rep):
    """The report as docs/peers.md's table."""
    def f(x, fmt="{:.3g}"):
        return "–" if x is None else fmt.format(x)
    print("| scene | forward ratio | grad max \\|z\\| (threshold) | rel diff | invr vs own FD \\|z\\| | Mitsuba vs its FD \\|z\\| "
          "| step invr s (method) | step Mitsuba s (first) | Mitsuba/invr step | time to error Mitsuba/invr |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, s in rep["scenes"].items():
        if "error" in s:
            print(f"| {name} | failed: {s['error'][:80]} |||||||||")
            continue
        per = s["gradient_by_method"]
        inv_fd = max((g.get("fd_max_abs_z", 0) for m, g in per.items() if m != "mitsuba"), default=None)
        mi_fd = per.get("mitsuba", {}).get("mitsuba_fd_max_abs_z")
        tte = s.get("time_to_error_mitsuba_over_invr")
        tte_s = "–" if tte is None else (f"{tte:.3g}" if s.get("time_to_error_mitsuba_reached", True) else f"> {tte:.3g}")
        print(f"| {name} | {f(s['forward_block_ratio'])} | {f(s['gradient_max_abs_z'], '{:.2f}')} ({s['gradient_z_threshold']:.2f}) "
              f"| {f(s['gradient_rel_diff'])} | {f(inv_fd, '{:.2f}')} | {f(mi_fd, '{:.2f}')} "
              f"| {s['step_seconds_invr']:.3g} ({s['step_method_invr']}) | {s['step_seconds_mitsuba']:.3g} ({s['first_step_seconds_mitsuba']:.3g}) "
              f"| {s['ratio_step_mitsuba_over_invr']:.3g} | {tte_s} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--invr", help="the invr executable")
    ap.add_argument("--invr-lab", help="the invr-lab executable (default: invr-lab next to --invr)")
    ap.add_argument("--work", help="folder for the exported scenes and renders")
    ap.add_argument("--scenes", default=",".join(DEFAULT_SCENES))
    ap.add_argument("--spp", type=int, default=4, help="samples per pixel of each gradient pass, both renderers")
    ap.add_argument("--evaluations", type=int, default=12, help="invr's independent evaluations per method")
    ap.add_argument("--mitsuba-evaluations", type=int, default=12)
    ap.add_argument("--fd-evaluations", type=int, default=8)
    ap.add_argument("--forward-seeds", type=int, default=12)
    ap.add_argument("--forward-spp", type=int, default=16)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--time-to-error-steps", type=int, default=40, help="invr's optimisation steps (0: skip); Mitsuba's at most 3x")
    ap.add_argument("--time-to-error-budget", type=float, default=90.0, help="seconds Mitsuba's optimisation may take at most")
    ap.add_argument("--table", metavar="REPORT", help="print REPORT (this script's JSON) as a table and stop")
    ap.add_argument("--out", help="write the JSON report here (default: standard output)")
    ap.add_argument("--markdown", metavar="REPORT", help="print REPORT as docs/peers.md's table and stop")
    ap.add_argument("--weld-moving-meshes", action="store_true",
                    help="rewrite the meshes shape parameters move with one vertex per position (docs/peers.md: Mitsuba then "
                         "misses the creases' term instead of counting it twice)")
    ap.add_argument("--terms", action="store_true",
                    help="shape scenes: each renderer's gradient with its primary or secondary boundary term off (report: terms)")
    ap.add_argument("--mitsuba-fd-evaluations", type=int, default=8,
                    help="central differences of Mitsuba's own renders (its non-differentiable integrator; 0: none)")
    a = ap.parse_args()
    if a.table:
        print_table(json.load(open(a.table)))
        return
    if a.markdown:
        print_markdown(json.load(open(a.markdown)))
        return
    dr.set_thread_count(a.threads)
    if not a.invr or not a.work:
        ap.error("--invr and --work are required")
    if not a.invr_lab:
        a.invr_lab = os.path.join(os.path.dirname(a.invr), "invr-lab")
    versions = {"mitsuba": mi.__version__, "drjit": dr.__version__, "variant": mi.variant(),
                "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH", ""),
                "invr": run([a.invr, "--version"]).strip()}
    res = {"versions": versions, "scenes": {}}
    for s in a.scenes.split(","):
        s = s.strip()
        if s not in SCENES:
            raise SystemExit(f"peers: unknown scene '{s}' (known: {', '.join(SCENES)})")
        try:
            res["scenes"][s] = compare(s, a, a.work)
        except Exception as e:  # one scene's failure is reported, the others still run
            log(s, "FAILED:", e)
            res["scenes"][s] = {"error": str(e)}
    if a.out:
        with open(a.out, "w") as f:
            json.dump(res, f)
    else:
        print(json.dumps(res))


if __name__ == "__main__":
    main()
