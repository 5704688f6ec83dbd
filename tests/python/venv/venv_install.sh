#!/usr/bin/env bash
# The Python package as a user installs it (issue 61): the wheel built from the tree
# (client/python/tools/build_wheel.sh, as `pip install ./client/python` builds it), installed into
# a fresh virtual environment with its dependencies from PyPI, then used with no invr executable on
# PATH and no invr build beside it against a running invr-server and worker: a zoo job, a Mitsuba
# 3 scene with its files and a job file with relative textures are submitted, and their results
# read as NumPy arrays (tests/python/venv/use_installed.py).
# usage: venv_install.sh BIN_DIR WORK_DIR REPO_DIR VERSION
set -euo pipefail
BIN="$1"; WORK="$2"; REPO="$3"; VERSION="$4"
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
echo "venv_install: ok"
