#!/usr/bin/env bash
# The client commands against a real invr-server and invr-worker: submit, watch (also resumed),
# status, list, workers, fetch, cancel, and the exit codes of each outcome.
set -euo pipefail
BIN="$1"
DIR="$(mktemp -d)"
cleanup() { kill -9 "${SERVER:-0}" "${WORKER:-0}" 2>/dev/null || true; rm -rf "$DIR"; }
trap cleanup EXIT

"$BIN/invr-server" --store "$DIR/store" --address 127.0.0.1:0 --port-file "$DIR/port" --final-spp 4 >"$DIR/server.log" 2>&1 &
SERVER=$!
for _ in $(seq 100); do [ -s "$DIR/port" ] && break; sleep 0.05; done
ADDR="127.0.0.1:$(cat "$DIR/port")"
"$BIN/invr-worker" --server "$ADDR" --threads 2 >"$DIR/worker.log" 2>&1 &
WORKER=$!
for _ in $(seq 100); do "$BIN/invr" workers --server "$ADDR" | grep -q "thread" && break; sleep 0.05; done

# The plan from the server's view (memory for its worker's 2 threads), and a job it would refuse
# refused by plan with the submission's message.
"$BIN/invr" plan cornell --server "$ADDR" | grep -q "memory per worker (largest shard, 2 threads)"
echo '{"zoo": "cornell", "optimization": {"parameters": [{"name": "materials/red/albedo", "lower": 0}]}}' >"$DIR/zero.json"
if "$BIN/invr" plan "$DIR/zero.json" --server "$ADDR" 2>"$DIR/plan.err"; then echo "plan accepted a zero bound"; exit 1; fi
grep -q "parameters\[0\].lower" "$DIR/plan.err"

ID=$("$BIN/invr" submit cornell --steps 3 --target-spp 4 --server "$ADDR")
echo "submitted $ID"
"$BIN/invr" watch "$ID" --server "$ADDR" >"$DIR/watch.txt"
grep -q "step 3/3" "$DIR/watch.txt"
grep -q "$ID JOB_STATE_SUCCEEDED\|$ID SUCCEEDED" "$DIR/watch.txt"
# Resumed from a sequence number, as JSON: the first event is that one.
"$BIN/invr" watch "$ID" --from 4 --json --server "$ADDR" >"$DIR/watch.json"
head -1 "$DIR/watch.json" | grep -q '"sequence":4,'
tail -1 "$DIR/watch.json" | grep -q '"final"'
"$BIN/invr" status "$ID" --server "$ADDR" | grep -q "SUCCEEDED  step 3/3"
"$BIN/invr" list --server "$ADDR" | grep -q "$ID  SUCCEEDED  cornell"
"$BIN/invr" fetch "$ID" -o "$DIR/results" --server "$ADDR" | grep -q "wrote 12 file"  # with truth/parameters.json
test -s "$DIR/results/truth/parameters.json" && test -s "$DIR/results/parameters.json" && test -s "$DIR/results/job.json" && test -s "$DIR/results/final_view0.exr" && test -s "$DIR/results/convergence.png"

# A long job, cancelled: watch exits with 6, cancel is idempotent.
LONG=$("$BIN/invr" submit cornell --steps 100000 --target-spp 4 --server "$ADDR")
for _ in $(seq 200); do "$BIN/invr" status "$LONG" --server "$ADDR" | grep -q "step [1-9]" && break; sleep 0.1; done
"$BIN/invr" cancel "$LONG" --server "$ADDR"
"$BIN/invr" cancel "$LONG" --server "$ADDR"
set +e
"$BIN/invr" watch "$LONG" --server "$ADDR" >/dev/null 2>&1
CODE=$?
"$BIN/invr" status nosuch-job --server "$ADDR" >/dev/null 2>&1
MISSING=$?
set -e
test "$CODE" -eq 6 || { echo "watch of a cancelled job exited $CODE, expected 6"; exit 1; }
test "$MISSING" -eq 1 || { echo "status of an unknown job exited $MISSING, expected 1"; exit 1; }
echo "cli against server: ok"
