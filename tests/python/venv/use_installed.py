"""Run by venv_install.sh with the installed package only: no invr executable on PATH.
usage: use_installed.py ADDRESS REPO_DIR VERSION"""
import json
import shutil
import sys
from pathlib import Path

import numpy as np

import invr
from invr import _constants

address, repo, version = sys.argv[1], Path(sys.argv[2]), sys.argv[3]
assert shutil.which("invr") is None, "an invr executable is on PATH"
assert invr.__version__ == version, f"package version {invr.__version__}, build {version}"
# The constants come from the C++ headers.
exit_codes = (repo / "client/common/exit_codes.h").read_text()
assert f"kJobFailed = {_constants.EXIT_JOB_FAILED};" in exit_codes
c = invr.Client(address)
c.wait_for_workers(1, timeout=60)

# A zoo job, with overrides.
job = c.submit("cornell", steps=3, target_spp=4, sets={"render.spp": 2})
r = job.result("zoo")
albedo = r.parameters["materials/red/albedo"]
assert isinstance(albedo, np.ndarray) and albedo.shape[-1] == 3, albedo
final = r.images["final_view0.exr"]  # EXR through the OpenImageIO wheel
assert final.ndim == 3 and final.shape[2] >= 3 and np.isfinite(final).all(), final.shape
print("zoo job:", job.status()["state"], albedo.ravel()[:3], "final render", final.shape)

# A Mitsuba 3 scene: its meshes are uploaded as the server asks for them.
xml = repo / "docs/examples/mitsuba/cornell-box.xml"
job = c.submit(str(xml), params={"red.reflectance.value": [0.01, 0.2, 0.9]}, defines={"res": "32", "spp": "2"}, steps=2,
               target_spp=4)
r = job.result("xml")
names = list(r.parameters)
assert any("red" in n for n in names), names
print("Mitsuba scene:", job.status()["state"], names)

# A job file whose textures and meshes are relative to it.
tabletop = repo / "docs/examples/tabletop_optimize.json"
small = {"scene.film.width": 80, "scene.film.height": 60}
plan = c.plan(str(tabletop), steps=2, sets=small)
assert int(plan["parameter_values"]) > 0, plan
job = c.submit(str(tabletop), steps=2, target_spp=4, sets=small)
r = job.result("tabletop")
assert r.parameters, "no parameters"
print("job file:", job.status()["state"], list(r.parameters))

# A dict whose mesh is named by an absolute path (uploaded by content), and a scene's names as the
# server lists them.
spec = json.loads(tabletop.read_text())
spec["scene"]["shapes"][1]["mesh"]["path"] = str(tabletop.parent / "wedge.obj")
assert int(c.plan(spec, steps=2)["parameter_values"]) > 0
assert [p["name"] for p in c.parameters("oxalis")], "no parameters of oxalis"

# A misspelt zoo name: an input error naming the closest one.
try:
    c.submit("cornel")
    raise SystemExit("a misspelt zoo name was accepted")
except invr.InputError as e:
    assert "did you mean 'cornell'" in str(e), str(e)
print("use_installed: ok")
