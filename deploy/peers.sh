#!/usr/bin/env bash
# invr beside Mitsuba 3 on the same scenes: forward images, gradients and step times
# (docs/peers.md). Installs the peer once, into a virtual environment under the build folder
# (pinned mitsuba and drjit from PyPI; Dr.Jit's LLVM backend loads Debian's libLLVM at run time),
# then runs deploy/peers/compare.py with invr's binaries from $INVR_BUILD_DIR (default build/).
# The peer is a reference for benchmarks and cross-checks, never a dependency of invr's build,
# product or default tests.
#
# usage: bash deploy/peers.sh [--scenes a,b,...] [--json] [--quick] [--install-only] [-- compare.py options]
#   --scenes        cornell,oxalis,mirror,backlit,pose,knot,pose-vertices (default: all)
#   --json          print the one JSON object {"versions": ..., "scenes": {...}} (else a table)
#   --quick         fewer evaluations and seeds (a smoke run: agreement figures are weaker)
#   --install-only  install the peer and stop
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${INVR_BUILD_DIR:-build}"
MITSUBA_VERSION=3.9.1
DRJIT_VERSION=1.5.0
NUMPY_VERSION=2.2.6
VENV="$BUILD/peers/venv"
SCENES="" JSON=0 QUICK=0 INSTALL_ONLY=0
EXTRA=()
while [ $# -gt 0 ]; do
  case "$1" in
    --scenes) SCENES="$2"; shift 2 ;;
    --scenes=*) SCENES="${1#--scenes=}"; shift ;;
    --json) JSON=1; shift ;;
    --quick) QUICK=1; shift ;;
    --install-only) INSTALL_ONLY=1; shift ;;
    --) shift; EXTRA=("$@"); break ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "peers: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done
fail() { echo "peers: cannot install the peer: $*" >&2; exit 1; }

# Dr.Jit 1.5's LLVM backend emits llvm.minimum/maximum, which LLVM 15's x86 backend cannot
# select ("LLVM ERROR: Cannot select: fminimum", measured on Debian's libllvm15); Debian 12's
# libllvm19 compiles them.
LIBLLVM=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1  # Debian 12 libllvm19 (libLLVM-19.so links to it)
if [ ! -e "$LIBLLVM" ]; then
  if [ "$(id -u)" -eq 0 ]; then
    echo "peers: installing Debian's libllvm19 (Dr.Jit's LLVM backend)" >&2
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libllvm19 > /dev/null ||
      fail "apt-get install libllvm19 failed (Debian 12's archive unreachable?)"
  else
    fail "$LIBLLVM is missing: run 'sudo apt-get install libllvm19' (or bash deploy/setup.sh), then again"
  fi
fi
export DRJIT_LIBLLVM_PATH="$LIBLLVM"

STAMP="$VENV/.invr-peer-$MITSUBA_VERSION-$DRJIT_VERSION-$NUMPY_VERSION"
if [ ! -e "$STAMP" ]; then
  /usr/bin/python3 -c "import ensurepip" 2> /dev/null || fail "Python's venv module lacks ensurepip: run 'sudo apt-get install python3-venv'"
  echo "peers: creating $VENV (mitsuba $MITSUBA_VERSION, drjit $DRJIT_VERSION from PyPI)" >&2
  rm -rf "$VENV"
  /usr/bin/python3 -m venv "$VENV" || fail "python3 -m venv $VENV failed"
  "$VENV/bin/pip" install -q --disable-pip-version-check "mitsuba==$MITSUBA_VERSION" "drjit==$DRJIT_VERSION" "numpy==$NUMPY_VERSION" >&2 ||
    fail "pip could not install mitsuba==$MITSUBA_VERSION drjit==$DRJIT_VERSION numpy==$NUMPY_VERSION from PyPI (offline, or no wheel for this Python: $(/usr/bin/python3 --version))"
  "$VENV/bin/python" -c "import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); mi.render(mi.load_dict(mi.cornell_box()), spp=1)" > /dev/null 2> "$BUILD/peers/check.log" ||
    fail "Mitsuba's llvm_ad_rgb variant does not render with $LIBLLVM: $(tail -3 "$BUILD/peers/check.log")"
  touch "$STAMP"
fi
[ "$INSTALL_ONLY" = 1 ] && { echo "peers: installed in $VENV" >&2; exit 0; }

INVR="$BUILD/bin/invr"
[ -x "$INVR" ] || { echo "peers: $INVR not found: build invr first (bash deploy/build.sh) or set INVR_BUILD_DIR" >&2; exit 1; }
ARGS=(--invr "$(readlink -f "$INVR")" --work "$BUILD/peers/work")
[ -n "$SCENES" ] && ARGS+=(--scenes "$SCENES")
[ "$QUICK" = 1 ] && ARGS+=(--evaluations 4 --mitsuba-evaluations 4 --fd-evaluations 2 --forward-seeds 4 --mitsuba-fd-evaluations 2 --time-to-error-steps 0)
OUT="$BUILD/peers/report.json"
"$VENV/bin/python" deploy/peers/compare.py "${ARGS[@]}" "${EXTRA[@]}" --out "$OUT.tmp" >&2
mv "$OUT.tmp" "$OUT"
if [ "$JSON" = 1 ]; then cat "$OUT"; else "$VENV/bin/python" deploy/peers/compare.py --table "$OUT"; fi
