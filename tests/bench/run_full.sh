#!/usr/bin/env bash
# The full evaluation suite, run by hand on a quiet machine; regenerates docs/results/ (commit it).
# Extra arguments go to `invr-lab eval` (e.g. --scenes mirror,backlit or --budget-scale 0.5).
set -euo pipefail
cd "$(dirname "$0")/../.."
bash deploy/build.sh
OUT=docs/results
rm -rf "$OUT.new"
./build/bin/invr-lab eval --out "$OUT.new" "$@" 2>&1 | tee /tmp/invr-eval-full.log
# Keep only what a reader looks at: the grids' tiles are regenerated on every run.
find "$OUT.new" -path '*/images/*' -delete
find "$OUT.new" -type d -name images -empty -delete
# Folders other runs own (shapes: docs/shapes.md's figures; paper: run_paper.sh).
for keep in shapes paper; do
  if [ -d "$OUT/$keep" ] && [ ! -e "$OUT.new/$keep" ]; then mv "$OUT/$keep" "$OUT.new/$keep"; fi
done
rm -rf "$OUT"
mv "$OUT.new" "$OUT"
echo "wrote $OUT (log: /tmp/invr-eval-full.log)"
