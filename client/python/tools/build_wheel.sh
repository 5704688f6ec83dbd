#!/usr/bin/env bash
# Builds the invr wheel from the source tree into OUT_DIR, as `pip install ./client/python` builds
# it (grpcio-tools and setuptools from PyPI, in pip's isolated build environment). It builds from a
# copy of what the package needs (client/python, proto/, the headers of its constants), so the
# tree gets no build/ or egg-info. pip comes from a virtual environment of Debian's python3
# (python3-venv), kept in VENV_DIR.
# Usage: build_wheel.sh OUT_DIR [VENV_DIR]
set -euo pipefail
root="$(cd "$(dirname "$0")/../../.." && pwd)"
out="$(mkdir -p "$1" && cd "$1" && pwd)"
venv="${2:-$out/.pip-venv}"
[ -x "$venv/bin/pip" ] || /usr/bin/python3 -m venv "$venv"
src="$(mktemp -d)"
trap 'rm -rf "$src"' EXIT
mkdir -p "$src/client/common" "$src/proto/wire"
cp -r "$root/client/python" "$src/client/python"
cp -r "$root/proto/invr" "$src/proto/invr"
cp "$root/client/common/exit_codes.h" "$src/client/common/"
cp "$root/proto/wire/wire.h" "$src/proto/wire/"
rm -rf "$src/client/python/build" "$src/client/python"/*.egg-info
"$venv/bin/pip" wheel --quiet --no-deps -w "$out" "$src/client/python"
ls "$out"/invr-*.whl
