#!/usr/bin/env bash
# The paper-scale suite (invr-lab eval --scale paper: oxalis-hd, kitty, gallery), run by hand on a
# quiet machine; regenerates docs/results/paper/ (commit it). The first argument, if any, is the
# budget scale (default 1: about an hour on 2 cores); further arguments go to `invr-lab eval`.
set -euo pipefail
cd "$(dirname "$0")/../.."
bash deploy/build.sh
SCALE=${1:-1}
shift || true
OUT=docs/results/paper
rm -rf "$OUT.new"
./build/bin/invr-lab eval --scale paper --budget-scale "$SCALE" --out "$OUT.new" "$@" 2>&1 | tee /tmp/invr-eval-paper.log
find "$OUT.new" -path '*/images/*' -delete
find "$OUT.new" -type d -name images -empty -delete
rm -rf "$OUT"
mv "$OUT.new" "$OUT"
echo "wrote $OUT (log: /tmp/invr-eval-paper.log)"
