"""invr's Python package against real server and worker processes, and its embedded run()."""

import json
import math
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import invr

REPO = Path(__file__).resolve().parents[2]
SMALL = {"steps": 3, "target_spp": 4}


def _same(a, b):
    """Equal JSON values, floats to float precision (the CLI prints a float field at its own)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(a, (int, float)) and isinstance(b, (int, float)) and math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-30)
    return a == b and type(a) == type(b)


def test_run_embedded_returns_arrays(tmp_path):
    events = []
    result = invr.run("cornell", workers=2, out=tmp_path / "run", on_event=events.append, final_spp=4, **SMALL)
    assert set(result.parameters) == {"materials/red/albedo", "materials/green/albedo", "materials/white/albedo"}
    assert result.parameters["materials/red/albedo"].shape == (3,)
    assert result.images["final_view0.exr"].shape == (256, 256, 3)
    assert result.images["final_view0.exr"].dtype == np.float32
    assert list(result.convergence["step"]) == [1, 2, 3]
    # The smoothed image loss exists for every job and is positive; the unbiased loss is beside it.
    assert np.all(result.convergence["image_loss"] > 0)
    steps = [e for e in events if e.kind == "step"]
    assert [e.step for e in steps] == [1, 2, 3]
    assert isinstance(steps[0].step, int) and isinstance(steps[0].loss, float)
    assert steps[-1].image_loss > 0 and steps[-1].param_error is not None
    assert set(steps[-1].parameters) == set(result.parameters)  # scalar and small parameters ride along
    np.testing.assert_allclose(steps[-1].parameters["materials/red/albedo"], result.parameters["materials/red/albedo"], rtol=1e-5)
    assert events[-1].kind == "final" and events[-1].state == "SUCCEEDED"


def test_submit_watch_result(service, tmp_path):
    c = service.client
    job = c.submit({"zoo": "cornell", "optimization": {
        "parameters": [{"name": "materials/red/albedo", "initial": 0.3}], "method": "pt", "steps": 4, "target_spp": 4}})
    seen = list(job.watch())
    kinds = [e.kind for e in seen]
    assert kinds[-1] == "final" and seen[-1].state == "SUCCEEDED"
    steps = [e for e in seen if e.kind == "step"]
    assert [e.step for e in steps] == [1, 2, 3, 4]
    assert all(e.image_loss > 0 for e in steps)
    # No silent wait: the sessions' build (targets, burn-in) is announced and timed before step 1.
    before = [e.message for e in seen[:kinds.index("step")] if e.kind == "message"]
    assert any(m.startswith("preparing: the workers build each shard's session") for m in before), before
    assert any(m.startswith("sessions ready: ") for m in before), before
    st = job.status()
    assert st["state"] == "SUCCEEDED" and st["step"] == 4 and isinstance(st["step"], int)
    r = job.result(tmp_path / "out")
    assert r.parameters["materials/red/albedo"].shape == (3,)
    assert "target_view0.exr" in r.images
    assert "progress.jsonl" in r.files
    # The fetched log ends with the final event, every line JSON with numbers as numbers.
    lines = [json.loads(l) for l in (tmp_path / "out" / "progress.jsonl").read_text().splitlines()]
    assert "final" in lines[-1] and lines[-1]["final"]["state"] == "SUCCEEDED"
    assert isinstance(lines[-1]["sequence"], int)
    # One JSON mapping (issue 61): Python's dict of a status is `invr status --json`'s object.
    cli = subprocess.run([invr.binary(), "status", job.id, "--json", "--server", service.address], capture_output=True, text=True)
    assert cli.returncode == 0, cli.stderr
    assert _same(json.loads(cli.stdout), job.status()), (cli.stdout, job.status())
    assert any(j["job_id"] == job.id for j in c.jobs())
    assert len(c.workers()) == 1  # the module's one worker


def test_texture_result_is_an_image(service, tmp_path):
    job = service.client.submit("oxalis", steps=2, target_spp=2, sets={"optimization.restir.burn_in": 1}, snapshot_every=1)
    r = job.result(tmp_path / "oxalis")
    tex = r.parameters["materials/painting/albedo"]
    assert tex.shape == (64, 64, 3)
    assert np.all(np.isfinite(tex))
    # Snapshots every step, fetched into snapshots/: the renders, and the parameters of that step.
    assert list(r.snapshots) == [1, 2]
    assert r.snapshots[2].images[0].shape == r.images["final_view0.exr"].shape
    np.testing.assert_array_equal(r.snapshots[2].parameters["materials/painting/albedo"], tex)
    assert not np.array_equal(r.snapshots[1].parameters["materials/painting/albedo"], tex)
    # Written back as a Mitsuba scene whose painting is the recovered texture.
    xml = invr.export(r, tmp_path / "exported" / "scene.xml")
    assert xml.exists() and (tmp_path / "exported" / "scene.json").exists()
    exported = invr.read_image(tmp_path / "exported" / "textures" / "painting_reflectance.exr")
    np.testing.assert_allclose(exported, tex, rtol=1e-6)


def test_parameters_locally_and_from_the_server(service):
    local = invr.parameters("cornell")
    remote = service.client.parameters("cornell")
    assert [p["name"] for p in local] == [p["name"] for p in remote]
    red = next(p for p in local if p["name"] == "materials/red/albedo")
    assert red["size"] == 3 and red["kind"] == "albedo" and "red.reflectance.value" in red["aliases"]
    oxalis = {p["name"]: p for p in invr.parameters("oxalis")}
    painting = oxalis["materials/painting/albedo"]
    assert (painting["width"], painting["height"], painting["channels"]) == (64, 64, 3)
    assert oxalis["lights/fill/intensity"]["upper"] is None  # unbounded: JSON null
    remote_oxalis = {p["name"]: p for p in service.client.parameters("oxalis")}
    assert remote_oxalis["lights/fill/intensity"]["upper"] is None
    assert remote_oxalis["materials/painting/albedo"] == painting
    with pytest.raises(invr.InputError, match="unknown scene"):
        invr.parameters("no_such_scene")


def test_errors_in_the_users_words(service):
    c = service.client
    with pytest.raises(invr.InputError, match=r"'restri' is not a valid value; use one of: pt, ris, restir; did you mean 'restir'\?"):
        c.submit({"zoo": "cornell", "optimization": {"method": "restri", "parameters": [{"name": "materials/red/albedo"}]}})
    with pytest.raises(invr.InputError, match=r"a list goes in 'initial_values'"):
        c.submit({"zoo": "cornell", "optimization": {"parameters": [{"name": "materials/red/albedo", "initial": [0.1, 0.2, 0.3]}]}})
    with pytest.raises(invr.InputError, match=r"no material named 'rde'; did you mean 'red'\?"):
        c.submit("cornell", params=["materials/rde/albedo"])
    with pytest.raises(invr.ServerUnavailable):
        invr.Client("127.0.0.1:1").job("job-000001").status()


def test_cancel_keeps_the_checkpoint(service, tmp_path):
    c = service.client
    job = c.submit("cornell", steps=100000, target_spp=2, method="pt")
    for e in job.watch():
        if e.kind == "step" and e.step >= 2:
            job.cancel()
            break
    with pytest.raises(invr.JobCancelled):
        job.wait(timeout=120)
    r = job.result(tmp_path / "cancelled")
    assert set(r.parameters) == {"materials/red/albedo", "materials/green/albedo", "materials/white/albedo"}
    assert len(r.convergence["step"]) >= 2


def test_watch_rides_out_a_server_restart(fresh_service):
    service = fresh_service
    c = service.client
    job = c.submit("cornell", steps=40, target_spp=2, method="pt")
    seen = []
    restarted = threading.Event()
    for e in job.watch(reconnect_seconds=60):
        seen.append(e)
        if e.kind == "step" and e.step == 3 and not restarted.is_set():
            restarted.set()
            service.stop_server()
            service.start_server()
    assert restarted.is_set()
    assert seen[-1].kind == "final" and seen[-1].state == "SUCCEEDED"
    sequences = [e.sequence for e in seen]
    assert sequences == sorted(set(sequences))  # resumed after the last event seen: no repeats, no gaps
    assert sequences == list(range(sequences[0], sequences[0] + len(sequences)))


@pytest.mark.parametrize("example", ["texture.py", "photo.py", "pose.py"])
def test_examples_run_at_small_size(example, tmp_path):
    env = dict(os.environ)
    proc = subprocess.run([sys.executable, str(REPO / "docs" / "examples" / "python" / example), "--steps", "3", "--out", str(tmp_path),
                           "--target-spp", "4", "--final-spp", "4"],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "done" in proc.stdout
