#!/usr/bin/env bash
# The Python package as a user installs it (issue 61): the wheel built from the tree
# (client/python/tools/build_wheel.sh, as `pip install ./client/python` builds it), installed into
# a fresh virtual environment with its dependencies from PyPI, then used with no invr executable on
# PATH and no invr build beside it against a running invr-server and worker: a zoo job, a Mitsuba
# 3 scene with its files and a job file with relative textures are submitted, and their results
# read as NumPy arrays (tests/python/venv/use_installed.py). Then the wheel the build wrote
# (BUILD_WHEEL, from build/python with Debian's protoc) in a venv of its own: a zoo job's results.
# usage: venv_install.sh BIN_DIR WORK_DIR REPO_DIR VERSION BUILD_WHEEL
set -euo pipefail
BIN="$1"; WORK="$2"; REPO="$3"; VERSION="$4"; BUILD_WHEEL="$5"
fail() { echo "venv_install: FAILED: $*"; exit 1; }
rm -rf "$WORK" && mkdir -p "$WORK"
cd "$WORK"

bash "$REPO/client/python/tools/build_wheel.sh" "$WORK/wheels" "$WORK/pip-venv" > wheel.log 2>&1 || fail "wheel: $(tail -5 wheel.log)"
/usr/bin/python3 -m venv "$WORK/venv"
"$WORK/venv/bin/pip" install --quiet "$WORK"/wheels/invr-*.whl > install.log 2>&1 || fail "pip install: $(tail -5 install.log)"
# The installed package is what is imported, not the tree's or the build's.
"$WORK/venv/bin/python" -c "import invr; assert invr.__file__.startswith('$WORK/venv/'), invr.__file__" || fail "imported another invr package"

port_file="$WORK/port"
"$BIN/invr-server" --store "$WORK/store" --address 127.0.0.1:0 --port-file "$port_file" --final-spp 4 > server.log 2>&1 &
server=$!
trap 'kill $server $worker 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -s "$port_file" ] && break; sleep 0.1; done
[ -s "$port_file" ] || fail "the server wrote no port: $(tail -3 server.log)"
address="127.0.0.1:$(cat "$port_file")"
"$BIN/invr-worker" --server "$address" --threads 2 > worker.log 2>&1 &
worker=$!

mkdir -p user && cd user
env -i HOME="$WORK" PATH=/usr/bin:/bin "$WORK/venv/bin/python" "$REPO/tests/python/venv/use_installed.py" "$address" "$REPO" "$VERSION" \
  || fail "the installed package (server log: $(tail -3 ../server.log))"

/usr/bin/python3 -m venv "$WORK/venv-build"
"$WORK/venv-build/bin/pip" install --quiet "$BUILD_WHEEL" > ../install-build.log 2>&1 || fail "pip install of the build's wheel: $(tail -5 ../install-build.log)"
env -i HOME="$WORK" PATH=/usr/bin:/bin "$WORK/venv-build/bin/python" - "$address" "$VERSION" <<'PYEOF' || fail "the build's wheel"
import shutil, sys
import numpy as np
import invr
assert shutil.which("invr") is None and "venv-build" in invr.__file__, invr.__file__
assert invr.__version__ == sys.argv[2], invr.__version__
r = invr.Client(sys.argv[1]).submit("cornell", steps=2, target_spp=4).result("build-wheel")
assert isinstance(r.parameters["materials/red/albedo"], np.ndarray)
print("the build's wheel: ok")
PYEOF
echo "venv_install: ok"
