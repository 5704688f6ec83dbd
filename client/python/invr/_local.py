"""What runs on this machine: the invr binaries (the embedded server with local workers of
`invr run`, a scene's parameter names without a server, export). Nothing a server can do runs here:
Client resolves jobs through the server's ResolveJob."""

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from invr._errors import InvrError, InputError, JobFailed, JobCancelled

# Exit codes of the CLI (generated from client/common/exit_codes.h).
from invr._constants import (EXIT_INPUT_ERROR as _EXIT_INPUT, EXIT_USAGE as _EXIT_USAGE, EXIT_JOB_FAILED as _EXIT_JOB_FAILED,
                             EXIT_SERVER_UNAVAILABLE as _EXIT_UNAVAILABLE, EXIT_CANCELLED as _EXIT_CANCELLED, EXIT_INTERNAL,
                             EXIT_REFUSED)


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


# The gRPC status name each exit status of the CLI stands for (InvrError.code has one type).
_CODE_OF_EXIT = {_EXIT_INPUT: "INVALID_ARGUMENT", _EXIT_USAGE: "INVALID_ARGUMENT", EXIT_INTERNAL: "INTERNAL",
                 _EXIT_JOB_FAILED: "ABORTED", _EXIT_UNAVAILABLE: "UNAVAILABLE", _EXIT_CANCELLED: "CANCELLED",
                 EXIT_REFUSED: "UNAUTHENTICATED"}


def _cli_error(proc_stderr, code):
    """The CLI's own message ("invr: error: ..."), as the matching exception."""
    lines = [l for l in proc_stderr.strip().splitlines() if l.strip()]
    msg = lines[-1] if lines else f"invr exited with status {code}"
    for prefix in ("invr: error: ", "invr: "):
        if msg.startswith(prefix):
            msg = msg[len(prefix):]
            break
    name = _CODE_OF_EXIT.get(code, "UNKNOWN")
    if code in (_EXIT_INPUT, _EXIT_USAGE):
        return InputError(msg, name, exit_code=code)
    if code == _EXIT_UNAVAILABLE:
        from invr._errors import ServerUnavailable
        return ServerUnavailable(msg, name, exit_code=code)
    return InvrError(msg, name, exit_code=code)


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


def _override_args(**overrides):
    """The CLI options that carry a job's overrides."""
    from invr._resolve import override_lists
    params, defines, sets = override_lists(**overrides)
    args = []
    for p in params:
        args += ["--param", p]
    for d in defines:
        args += ["-D", d]
    for s in sets:
        args += ["--set", s]
    return args


class _Progress:
    """invr.run's progress: a tqdm bar (a terminal's or a notebook's) when tqdm is installed, else
    one line per 5 % of the steps on stderr; lifecycle messages (preparing, burn-in, ...) above it."""

    def __init__(self):
        self.bar = None
        self.next_line = 0
        try:
            from tqdm.auto import tqdm
            self._tqdm = tqdm
        except ImportError:
            self._tqdm = None

    def __call__(self, e):
        if e.kind == "message":
            self._write(e.message)
        elif e.kind == "step":
            text = f"loss {e.loss:.4g}, image loss {e.image_loss:.4g}" + (
                f", param error {e.param_error:.4g}" if e.param_error is not None else "")
            if self._tqdm is not None:
                if self.bar is None:
                    self.bar = self._tqdm(total=e.steps, unit="step", desc="invr", initial=e.step - 1)
                self.bar.update(e.step - self.bar.n)
                self.bar.set_postfix_str(text, refresh=False)
            elif e.step >= self.next_line or e.step == e.steps:
                sys.stderr.write(f"invr: step {e.step}/{e.steps}: {text}\n")
                self.next_line = e.step + max(1, e.steps // 20)
        elif e.kind == "final":
            if self.bar is not None:
                self.bar.close()
            self._write(f"{e.state.lower()}" + (f": {e.reason}" if e.reason else ""))

    def _write(self, text):
        if self.bar is not None:
            self.bar.write("invr: " + text, file=sys.stderr)
        else:
            sys.stderr.write(f"invr: {text}\n")


def _interactive():
    """A terminal on stderr, or a Jupyter kernel."""
    if sys.stderr.isatty():
        return True
    return "ipykernel" in sys.modules


def run(job, workers=None, out=None, params=None, defines=None, sets=None, steps=None, method=None, target_spp=None,
        seed=None, store=None, on_event=None, snapshot_every=None, final_spp=None, progress=None):
    """Runs a job to its end on an embedded server with local worker processes, as `invr run` does,
    and returns its Result. `job`: a dict, a job file, a Mitsuba scene (with params=) or a zoo name.
    `on_event(event)` sees every progress event. `final_spp`: samples per pixel of the initial and
    final renders written with the results (`invr run --final-spp`, default 64). Raises JobFailed /
    JobCancelled (with the results fetched into .result where there were any), InputError for a
    wrong job. `progress`: show the lifecycle messages and a progress bar (tqdm when installed,
    else a line per 5 % of the steps) on stderr; None (the default) shows them in a terminal or a
    notebook only."""
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
    show = _Progress() if (progress if progress is not None else _interactive()) else None
    try:
        for line in proc.stdout:
            line = line.strip()
            if not line:
                continue
            event = Event(json.loads(line))
            if event.kind == "final":
                final = event
            if show is not None:
                show(event)
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
