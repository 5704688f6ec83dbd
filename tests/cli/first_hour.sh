#!/usr/bin/env bash
# What a new user meets in the first hour (issue 43): one default address for server and clients,
# JSON output that is JSON, errors in the user's words, --set, -o creating folders, a cancelled
# job's checkpoint fetched, a worker saying it retries.
# usage: first_hour.sh BIN_DIR WORK_DIR
set -euo pipefail
BIN="$1"
DIR="$2"
rm -rf "$DIR"
mkdir -p "$DIR"
cd "$DIR"
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill -9 "$p" 2>/dev/null || true; done; }
trap cleanup EXIT
fail() { echo "first hour: FAILED: $*"; exit 1; }
PY=/usr/bin/python3
json_lines() { $PY -c "import json,sys; [json.loads(l) for l in open(sys.argv[1]) if l.strip()]" "$1" || fail "$1 is not JSON lines"; }

# One default address: the server listens where every client looks (when this machine's 50051
# is free), and a second server there is refused, naming the address.
if $PY -c "import socket; s=socket.socket(); s.bind(('127.0.0.1', 50051))" 2>/dev/null; then
  "$BIN/invr-server" --store default_store > default.log 2>&1 &
  PIDS+=($!)
  for _ in $(seq 100); do "$BIN/invr" list > /dev/null 2>&1 && break; sleep 0.1; done
  "$BIN/invr" list --json > list_default.json || fail "invr list found no server at the default address"
  if "$BIN/invr-server" --store other_store > second.log 2>&1; then fail "a second server on 127.0.0.1:50051 started"; fi
  grep -q "127.0.0.1:50051" second.log || fail "the refusal does not name the address: $(cat second.log)"
  kill "${PIDS[0]}"; wait "${PIDS[0]}" 2>/dev/null || true
  echo "default address: ok"
else
  echo "default address: port 50051 is in use on this machine; that part skipped"
fi

"$BIN/invr-server" --store store --address 127.0.0.1:0 --port-file port --final-spp 4 > server.log 2>&1 &
PIDS+=($!)
for _ in $(seq 100); do [ -s port ] && break; sleep 0.05; done
export INVR_SERVER="127.0.0.1:$(cat port)"  # every client command takes it as its default

# A worker started against a server that is not there says it is retrying.
"$BIN/invr-worker" --server 127.0.0.1:1 --threads 1 > lost_worker.log 2>&1 &
LOST=$!
PIDS+=($LOST)
"$BIN/invr-worker" --threads 2 > worker.log 2>&1 &
PIDS+=($!)
for _ in $(seq 100); do "$BIN/invr" workers | grep -q thread && break; sleep 0.05; done
sleep 1
grep -q "cannot reach the server at 127.0.0.1:1; retrying" lost_worker.log || fail "the lost worker is silent: $(cat lost_worker.log)"
kill "$LOST"

# --json: JSON lines only on stdout, numbers as numbers, the final event in progress.jsonl.
"$BIN/invr" run cornell --steps 3 --target-spp 4 --server "$INVR_SERVER" --json -o run_json > run.jsonl 2> run.err
json_lines run.jsonl
grep -q '"step":{"step":1,' run.jsonl || fail "step numbers are not JSON numbers: $(head -c 300 run.jsonl)"
tail -1 run.jsonl | grep -q '"final"' || fail "the last line is not the final event"
grep -q "submitted" run.err || fail "messages did not go to stderr"
json_lines run_json/progress.jsonl
tail -1 run_json/progress.jsonl | grep -q '"state":"SUCCEEDED"' || fail "progress.jsonl has no final event"
for cmd in "list" "workers" "plan cornell" "params cornell" "status job-000001"; do
  # shellcheck disable=SC2086
  "$BIN/invr" $cmd --json > out.json || fail "invr $cmd --json failed"
  json_lines out.json
done
$PY -c "import json; s=json.load(open('out.json')); assert isinstance(s['step'], int) and s['state']=='SUCCEEDED', s" || fail "status --json"

# Errors in the user's words.
echo '{"zoo": "cornell", "optimization": {"method": "restir", "loss": "l1", "parameters": [{"name": "materials/red/albedo"}]}}' > short.json
"$BIN/invr" plan short.json > /dev/null || fail "short enum forms are refused"
printf '{"zoo": "cornell",\n "optimization": {"method": "restri"}}\n' > typo.json
"$BIN/invr" plan typo.json 2> typo.err && fail "a wrong method was accepted"
grep -q "typo.json:2:.*optimization.method: 'restri' is not a valid value; use one of: pt, ris, restir; did you mean 'restir'?" typo.err || fail "$(cat typo.err)"
printf '{"zoo": "cornell",\n "optimization": {\n' > cut.json
"$BIN/invr" plan cut.json 2> cut.err && fail "truncated JSON accepted"
grep -q "cut.json:3:1: JSON syntax error" cut.err || fail "$(cat cut.err)"
echo '{"zoo": "cornell", "optimization": {"parameters": [{"name": "materials/red/albedo", "initial": [0.1, 0.2, 0.3]}]}}' > list.json
"$BIN/invr" plan list.json 2> list.err && fail "a list for initial accepted"
grep -q "expects a single number, not a list; a list goes in 'initial_values'" list.err || fail "$(cat list.err)"
"$BIN/invr" plan cornell --param materials/rde/albedo 2> param.err && fail "a misspelt parameter accepted"
grep -q "no material named 'rde'; did you mean 'red'?" param.err || fail "$(cat param.err)"
"$BIN/invr" plan cornell --set optimization.stpes=5 2> set.err && fail "--set of an unknown field accepted"
grep -q "optimization.stpes: unknown field; did you mean 'steps'?" set.err || fail "$(cat set.err)"

# --set reaches any field; -o creates folders.
"$BIN/invr" plan cornell --set optimization.method=pt --set 'optimization.parameters[0].learning_rate=0.5' > set.txt
grep -q "materials/red/albedo: 3 value(s), bounds \[0.0001, 1\], learning rate 0.5" set.txt || fail "$(cat set.txt)"
grep -q "light sampling: pt" set.txt || fail "--set optimization.method=pt did not apply"
"$BIN/invr" import cornell -o new/dir/job.json > /dev/null
test -s new/dir/job.json || fail "import -o did not create the folder"

# A cancelled job's fetch writes its last checkpoint's parameters and convergence.
ID=$("$BIN/invr" submit cornell --steps 100000 --target-spp 2 --method pt)
for _ in $(seq 600); do "$BIN/invr" status "$ID" --json | $PY -c "import json,sys; sys.exit(0 if json.load(sys.stdin)['step'] >= 2 else 1)" && break; sleep 0.1; done
"$BIN/invr" cancel "$ID" > /dev/null
for _ in $(seq 600); do "$BIN/invr" status "$ID" > /dev/null 2>&1 || break; sleep 0.1; done
"$BIN/invr" fetch "$ID" -o cancelled > /dev/null
test -s cancelled/parameters.json && test -s cancelled/convergence.csv || fail "a cancelled job's fetch: $(ls cancelled)"
echo "first hour: ok"
