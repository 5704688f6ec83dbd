#!/usr/bin/env bash
# Snapshots (issue 43, item 4): --snapshot-every N writes snapshots/step<k>_view<v>.png and
# snapshots/step<k>/parameters.json during a service run, fetched with the results, and does not
# change the run's numbers: the same job with and without snapshots ends bit-identical. Checked on
# a ReSTIR texture job and on a ReSTIR vertex (mesh) job, whose reservoirs keep past geometry.
# usage: snapshots.sh BIN_DIR WORK_DIR
set -euo pipefail
BIN="$1"
DIR="$2"
rm -rf "$DIR"
mkdir -p "$DIR"
cd "$DIR"
fail() { echo "snapshots: FAILED: $*"; exit 1; }
PY=/usr/bin/python3

# The columns that are numbers of the optimisation (not timings) must be equal, row by row.
same_numbers() {
  $PY - "$1" "$2" <<'PYEOF' || fail "$1 and $2 differ"
import csv, sys
rows = [list(csv.DictReader(open(p))) for p in sys.argv[1:]]
assert len(rows[0]) == len(rows[1]) > 0, "row counts differ"
for a, b in zip(*rows):
    for k in a:
        if "second" in k or k in ("rate",): continue
        assert a[k] == b[k], f"step {a['step']}: {k} {a[k]} != {b[k]}"
PYEOF
}

same_pixels() {
  $PY -c "
import sys, numpy as np, OpenImageIO as oiio
a, b = (oiio.ImageBuf(p).get_pixels(oiio.FLOAT) for p in sys.argv[1:])
assert a.shape == b.shape and np.array_equal(a, b), 'pixels differ'
" "$1" "$2" || fail "$1 and $2 differ"
}

check() {  # job, steps, every, extra args
  local job="$1" steps="$2" every="$3"; shift 3
  "$BIN/invr" run "$job" --steps "$steps" --workers 2 --final-spp 4 "$@" -o "$job.plain" > "$job.plain.log" 2>&1 || fail "$job without snapshots: $(tail -3 "$job.plain.log")"
  "$BIN/invr" run "$job" --steps "$steps" --workers 2 --final-spp 4 "$@" --snapshot-every "$every" -o "$job.snap" > "$job.snap.log" 2>&1 || fail "$job with snapshots: $(tail -3 "$job.snap.log")"
  for k in $(seq "$every" "$every" "$steps"); do
    [ -s "$job.snap/snapshots/step${k}_view0.png" ] || fail "$job: snapshots/step${k}_view0.png not fetched"
    [ -s "$job.snap/snapshots/step${k}/parameters.json" ] || fail "$job: snapshots/step${k}/parameters.json not fetched"
  done
  [ ! -e "$job.plain/snapshots" ] || fail "$job: snapshots written without --snapshot-every"
  # The same numbers with and without snapshots: parameters, their files, the convergence.
  for f in "$job.plain"/*.json "$job.plain"/*.exr "$job.plain"/*.ply; do
    [ -e "$f" ] || continue
    case "$(basename "$f")" in final_view*|initial_view*|target_view*|job.json) continue ;; esac  # job.json names snapshot_every
    case "$f" in
      *.exr) same_pixels "$f" "$job.snap/$(basename "$f")" ;;  # EXR headers hold a time stamp
      *) cmp -s "$f" "$job.snap/$(basename "$f")" || fail "$job: $(basename "$f") differs with snapshots" ;;
    esac
  done
  same_numbers "$job.plain/convergence.csv" "$job.snap/convergence.csv"
  # The last snapshot holds the final parameters.
  cmp -s "$job.plain/parameters.json" "$job.snap/snapshots/step${steps}/parameters.json" || fail "$job: the last snapshot's parameters are not the final ones"
  grep -q "snapshot at step $every" "$job.snap/progress.jsonl" || fail "$job: the log does not say a snapshot was written"
  echo "$job: ok"
}

check oxalis 6 3 --target-spp 16
check octagon 4 2 --target-spp 8

# A bound on their number, named in the user's words.
if "$BIN/invr" plan cornell --steps 5000 --snapshot-every 1 > many.log 2>&1; then fail "5000 snapshots accepted"; fi
grep -q "at most 1000 snapshots per job: with 5000 steps, snapshot every 5 steps or more" many.log || fail "the bound is not explained: $(cat many.log)"

# A running job's snapshots are results at once: fetch gets them before the job ends.
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill -9 "$p" 2>/dev/null || true; done; }
trap cleanup EXIT
"$BIN/invr-server" --store store --address 127.0.0.1:0 --port-file port --final-spp 4 > server.log 2>&1 &
PIDS+=($!)
for _ in $(seq 100); do [ -s port ] && break; sleep 0.05; done
export INVR_SERVER="127.0.0.1:$(cat port)"
"$BIN/invr-worker" --threads 2 > worker.log 2>&1 &
PIDS+=($!)
ID=$("$BIN/invr" submit cornell --steps 1000 --target-spp 4 --snapshot-every 1)
for _ in $(seq 600); do "$BIN/invr" status "$ID" --json | grep -q '"step":[2-9]' && break; sleep 0.1; done
"$BIN/invr" fetch "$ID" -o running > fetch.log 2>&1 || fail "fetch of a running job: $(cat fetch.log)"
[ -s running/snapshots/step1_view0.png ] && [ -s running/snapshots/step1/parameters.json ] || fail "a running job's snapshots were not fetched: $(ls -R running)"
"$BIN/invr" cancel "$ID" > /dev/null
echo "running job: ok"
echo "snapshots: ok"
