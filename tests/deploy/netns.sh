#!/usr/bin/env bash
# Several hosts, simulated with network namespaces: the server in one, a worker in each of two
# others, joined by veth pairs (ip netns, as root); TLS and both tokens on. A worker with a wrong
# token is refused; a job runs with the client on a worker's host; one worker's link is taken
# down mid-job: the server hears nothing from it for the heartbeat timeout, drops it and its
# leases, its shards move to the other worker and the job completes.
set -euo pipefail
BIN="$1"
if [ "$(id -u)" -ne 0 ]; then echo "netns test: SKIPPED (needs root for ip netns)"; exit 77; fi
command -v ip > /dev/null || { echo "netns test: SKIPPED (iproute2 missing)"; exit 77; }
T="n$$"
SRV="invr-$T-srv" W1="invr-$T-w1" W2="invr-$T-w2"
DIR="$(mktemp -d)"
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -9 "$p" 2> /dev/null || true; done
  for n in "$SRV" "$W1" "$W2"; do ip netns del "$n" 2> /dev/null || true; done
  rm -rf "$DIR"
}
trap cleanup EXIT
fail() { echo "netns: $*"; for f in "$DIR"/*.log; do echo "== $f"; tail -25 "$f"; done; exit 1; }

if ! ip netns add "$SRV" 2> "$DIR/netns.err"; then echo "netns test: SKIPPED (ip netns add failed: $(cat "$DIR/netns.err"))"; exit 77; fi
ip netns add "$W1"
ip netns add "$W2"
for n in "$SRV" "$W1" "$W2"; do ip -n "$n" link set lo up; done
# server 10.231.1.1 <-> worker 1 10.231.1.2; server 10.231.2.1 <-> worker 2 10.231.2.2
ip link add "s1$T" netns "$SRV" type veth peer name "w1$T" netns "$W1"
ip link add "s2$T" netns "$SRV" type veth peer name "w2$T" netns "$W2"
ip -n "$SRV" addr add 10.231.1.1/24 dev "s1$T"
ip -n "$SRV" addr add 10.231.2.1/24 dev "s2$T"
ip -n "$W1" addr add 10.231.1.2/24 dev "w1$T"
ip -n "$W2" addr add 10.231.2.2/24 dev "w2$T"
for pair in "$SRV s1$T" "$SRV s2$T" "$W1 w1$T" "$W2 w2$T"; do set -- $pair; ip -n "$1" link set "$2" up; done

cd "$DIR"
openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem -days 2 -subj "/CN=invr netns CA" 2> /dev/null
openssl req -newkey rsa:2048 -nodes -keyout server.key -out server.csr -subj "/CN=invr-server" 2> /dev/null
printf "subjectAltName=DNS:invr-server,IP:10.231.1.1,IP:10.231.2.1\n" > server.ext
openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem -days 2 -extfile server.ext 2> /dev/null
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' > client.tok
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' > worker.tok
echo wrong > wrong.tok
PORT=50551

ip netns exec "$SRV" "$BIN/invr-server" --store store --address "0.0.0.0:$PORT" --tls-cert server.pem --tls-key server.key \
  --client-token-file client.tok --worker-token-file worker.tok --heartbeat-timeout 3 --lease-seconds 120 --assign-grace 10 --final-spp 4 \
  --port-file port > server.log 2>&1 &
PIDS+=($!)
for _ in $(seq 200); do [ -s port ] && break; sleep 0.05; done
[ -s port ] || fail "the server did not start"

# A worker with the wrong token, from worker 2's host: refused, exits 3.
set +e
timeout 30 ip netns exec "$W2" "$BIN/invr-worker" --server "10.231.2.1:$PORT" --tls-ca ca.pem --token-file wrong.tok --threads 1 > wrong.log 2>&1
code=$?
set -e
[ "$code" = 3 ] || fail "the worker with a wrong token exited $code, not 3"
grep -q "invalid bearer token" server.log || fail "the server did not log the refusal"

ip netns exec "$W1" "$BIN/invr-worker" --server "10.231.1.1:$PORT" --tls-ca ca.pem --token-file worker.tok --threads 1 --name w1 > w1.log 2>&1 &
PIDS+=($!)
ip netns exec "$W2" "$BIN/invr-worker" --server "10.231.2.1:$PORT" --tls-ca ca.pem --token-file worker.tok --threads 1 --name w2 > w2.log 2>&1 &
PIDS+=($!)
C=(--server "10.231.1.1:$PORT" --tls-ca ca.pem --token-file client.tok)
for _ in $(seq 200); do
  [ "$(ip netns exec "$W1" "$BIN/invr" workers "${C[@]}" 2> /dev/null | grep -c thread)" = 2 ] && break
  sleep 0.1
done
[ "$(ip netns exec "$W1" "$BIN/invr" workers "${C[@]}" | grep -c thread)" = 2 ] || fail "the two workers did not connect"

# backlit's 16 views in 2 shards, one per worker.
ID=$(ip netns exec "$W1" "$BIN/invr" submit backlit --steps 12 --target-spp 2 "${C[@]}")
for _ in $(seq 600); do
  step=$(ip netns exec "$W1" "$BIN/invr" status "$ID" "${C[@]}" | sed -n 's/.*step \([0-9]*\)\/.*/\1/p')
  [ "${step:-0}" -ge 3 ] && break
  sleep 0.1
done
[ "${step:-0}" -ge 3 ] || fail "the job did not reach step 3"
ip -n "$W2" link set "w2$T" down
echo "netns: worker 2's link down at step $step"
set +e
timeout 300 ip netns exec "$W1" "$BIN/invr" watch "$ID" "${C[@]}" > watch.log 2>&1
code=$?
set -e
[ "$code" = 0 ] || fail "the job did not succeed (watch exited $code)"
ip netns exec "$W1" "$BIN/invr" status "$ID" "${C[@]}" | grep -q "SUCCEEDED  step 12/12" || fail "the job is not at 12/12"
grep -q "(w2) silent for 3 s: presumed gone" server.log || fail "the server did not give up on worker 2"
grep -q "moved to worker w1" server.log || fail "worker 2's shard did not move to worker 1"
echo "netns: ok (job $ID completed on worker 1 after worker 2's link went down)"
