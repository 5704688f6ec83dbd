"""What runs on this machine: the invr binaries (resolving job arguments, the embedded server with
local workers of `invr run`, a scene's parameter names)."""

import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from invr._errors import InvrError, InputError, JobFailed, JobCancelled

# Exit codes of the CLI (client/common/exit_codes.h).
_EXIT_INPUT = 1
_EXIT_USAGE = 2
_EXIT_JOB_FAILED = 4
_EXIT_UNAVAILABLE = 5
_EXIT_CANCELLED = 6


def binary(name="invr"):
    """The path of an invr executable: $INVR_BIN/<name>, else the build's bin/ folder next to this
    package (build/python/invr -> build/bin), else <name> on $PATH."""
    candidates = []
    if os.environ.get("INVR_BIN"):
        candidates.append(Path(os.environ["INVR_BIN"]) / name)
    candidates.append(Path(__file__).resolve().parents[2] / "bin" / name)
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return str(c)
    found = shutil.which(name)
    if found:
        return found
    raise InvrError(f"cannot find the '{name}' executable: set $INVR_BIN to the folder holding it "
                    f"(build/bin after `bash deploy/build.sh`), or put it on $PATH")


def _cli_error(proc_stderr, code):
    """The CLI's own message ("invr: error: ..."), as the matching exception."""
    lines = [l for l in proc_stderr.strip().splitlines() if l.strip()]
    msg = lines[-1] if lines else f"invr exited with status {code}"
    for prefix in ("invr: error: ", "invr: "):
        if msg.startswith(prefix):
            msg = msg[len(prefix):]
            break
    if code in (_EXIT_INPUT, _EXIT_USAGE):
        return InputError(msg, code)
    if code == _EXIT_UNAVAILABLE:
        from invr._errors import ServerUnavailable
        return ServerUnavailable(msg, code)
    return InvrError(msg, code)


def _job_argument(job):
    """(argument, stdin text) for the CLI: a dict goes as JSON on standard input (`-`; relative
    paths from the working directory), a path or zoo name as it is."""
    if isinstance(job, dict):
        return "-", json.dumps(job)
    if isinstance(job, os.PathLike):
        return os.fspath(job), None
    if isinstance(job, str):
        return job, None
    raise InputError(f"a job is a dict, a job file (.json), a Mitsuba scene (.xml) or a zoo name; got {type(job).__name__}")


def _override_args(params=None, defines=None, sets=None, steps=None, method=None, target_spp=None, seed=None,
                   snapshot_every=None):
    """The CLI options that carry a job's overrides."""
    args = []
    items = params.items() if isinstance(params, dict) else (params or [])
    for p in items:
        # "name", "name=0.5", ("name", 0.5), ("name", [0.1, 0.2, 0.3]); a dict maps names to values (or None)
        if isinstance(p, (tuple, list)):
            name, value = p
            if value is None:
                args += ["--param", str(name)]
            else:
                values = np.ravel(np.asarray(value, dtype=float)).tolist()
                args += ["--param", f"{name}=" + ",".join(repr(float(v)) for v in values)]
        else:
            args += ["--param", str(p)]
    for k, v in (defines or {}).items():
        args += ["-D", f"{k}={v}"]
    all_sets = dict(sets or {})
    if steps is not None:
        all_sets["optimization.steps"] = int(steps)
    if method is not None:
        all_sets["optimization.method"] = method
    if target_spp is not None:
        all_sets["optimization.target_spp"] = int(target_spp)
    if seed is not None:
        all_sets["optimization.seed"] = int(seed)
    if snapshot_every is not None:
        all_sets["optimization.snapshot_every"] = int(snapshot_every)
    for k, v in all_sets.items():
        text = v if isinstance(v, str) else json.dumps(v)
        args += ["--set", f"{k}={text}"]
    return args


def resolve_job(job, **overrides):
    """The job as one self-contained JSON dict (zoo names kept by name, Mitsuba scenes imported,
    overrides applied, asset paths absolute), through `invr import`."""
    arg, stdin = _job_argument(job)
    with tempfile.TemporaryDirectory(prefix="invr-job-") as tmp:
        out = Path(tmp) / "job.json"
        proc = subprocess.run([binary(), "import", arg, "-o", str(out)] + _override_args(**overrides),
                              input=stdin, capture_output=True, text=True)
        if proc.returncode != 0:
            raise _cli_error(proc.stderr, proc.returncode)
        spec = json.loads(out.read_text())
    _absolute_paths(spec, Path(tmp))
    return spec


def _absolute_paths(node, base):
    """AssetRef {"path": ...} objects made absolute against base (where `invr import` wrote them
    relative to)."""
    if isinstance(node, dict):
        for k, v in node.items():
            if isinstance(v, dict) and set(v.keys()) == {"path"} and isinstance(v["path"], str) and k != "mitsuba":
                if not os.path.isabs(v["path"]):
                    v["path"] = os.path.normpath(str(base / v["path"]))
            else:
                _absolute_paths(v, base)
    elif isinstance(node, list):
        for v in node:
            _absolute_paths(v, base)


def run(job, workers=None, out=None, params=None, defines=None, sets=None, steps=None, method=None, target_spp=None,
        seed=None, store=None, on_event=None, snapshot_every=None, final_spp=None):
    """Runs a job to its end on an embedded server with local worker processes, as `invr run` does,
    and returns its Result. `job`: a dict, a job file, a Mitsuba scene (with params=) or a zoo name.
    `on_event(event)` sees every progress event. `final_spp`: samples per pixel of the initial and
    final renders written with the results (`invr run --final-spp`, default 64). Raises JobFailed /
    JobCancelled (with the results fetched into .result where there were any), InputError for a
    wrong job."""
    from invr._events import Event
    from invr._results import read_results

    arg, stdin = _job_argument(job)
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="invr-run-"))
    cmd = [binary(), "run", arg, "--json", "-o", str(out)]
    if workers is not None:
        cmd += ["--workers", str(int(workers))]
    if store is not None:
        cmd += ["--store", str(store)]
    if final_spp is not None:
        cmd += ["--final-spp", str(int(final_spp))]
    cmd += _override_args(params=params, defines=defines, sets=sets, steps=steps, method=method, target_spp=target_spp, seed=seed,
                          snapshot_every=snapshot_every)
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE if stdin is not None else subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if stdin is not None:
        proc.stdin.write(stdin)
        proc.stdin.close()
    final = None
    try:
        for line in proc.stdout:
            line = line.strip()
            if not line:
                continue
            event = Event(json.loads(line))
            if event.kind == "final":
                final = event
            if on_event is not None:
                on_event(event)
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    err = proc.stderr.read()
    code = proc.wait()
    if code in (_EXIT_JOB_FAILED, _EXIT_CANCELLED):
        status = final.status if final is not None else None
        reason = status.get("reason", "") if status else err.strip()
        cls = JobCancelled if code == _EXIT_CANCELLED else JobFailed
        e = cls(f"job {'cancelled' if code == _EXIT_CANCELLED else 'failed'}: {reason}", status)
        e.result = read_results(out) if (out / "parameters.json").exists() else None
        raise e
    if code != 0:
        raise _cli_error(err, code)
    return read_results(out)


def parameters(scene, defines=None):
    """The optimisable names of a scene (zoo name, job file, Mitsuba scene or dict): a list of
    dicts with name, kind, size, width, height, channels, lower, upper (None for no bound),
    learning_rate and aliases (Mitsuba names), as `invr params SCENE --json` lists them (no
    server needed; Client.parameters asks a server)."""
    arg, stdin = _job_argument(scene)
    proc = subprocess.run([binary(), "params", arg, "--json"] + _override_args(defines=defines), input=stdin,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise _cli_error(proc.stderr, proc.returncode)
    return json.loads(proc.stdout)["parameters"]


def export(results, out="export/scene.xml", assets=()):
    """Writes a results folder (a Result or its folder) as a Mitsuba 3 scene with the optimised
    values, as `invr export` does: out (.xml), meshes/ and textures/ beside it, and the job over
    it (out with .json). assets: folders holding the job's uploaded meshes and textures. Returns
    the path of the scene file; mitsuba.load_file() reads it."""
    folder = getattr(results, "dir", results)
    cmd = [binary(), "export", os.fspath(folder), "-o", os.fspath(out)]
    for a in ([assets] if isinstance(assets, (str, os.PathLike)) else assets):
        cmd += ["--assets", os.fspath(a)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise _cli_error(proc.stderr, proc.returncode)
    return Path(out)
