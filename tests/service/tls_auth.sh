#!/usr/bin/env bash
# Transport security against real processes: a non-loopback bind needs TLS or --insecure; with TLS
# and both tokens on, wrong or missing credentials are refused with the right codes (and logged
# without the secret), the right ones run a job end to end; mutual TLS refuses a client without
# a certificate.
set -euo pipefail
BIN="$1"
DIR="$(mktemp -d)"
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill -9 "$p" 2>/dev/null || true; done; rm -rf "$DIR"; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; for f in "$DIR"/*.log; do echo "== $f"; tail -20 "$f"; done; exit 1; }

# A CA, a server certificate for localhost / 127.0.0.1, and a client certificate.
cd "$DIR"
openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem -days 2 -subj "/CN=invr test CA" 2>/dev/null
openssl req -newkey rsa:2048 -nodes -keyout server.key -out server.csr -subj "/CN=localhost" 2>/dev/null
printf "subjectAltName=DNS:localhost,IP:127.0.0.1\n" >server.ext
openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem -days 2 -extfile server.ext 2>/dev/null
openssl req -newkey rsa:2048 -nodes -keyout client.key -out client.csr -subj "/CN=invr client" 2>/dev/null
openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out client.pem -days 2 2>/dev/null
echo "client-secret-$RANDOM$RANDOM" >client.tok
echo "worker-secret-$RANDOM$RANDOM" >worker.tok

waitport() { for _ in $(seq 200); do [ -s "$1" ] && return 0; sleep 0.05; done; fail "no port file $1"; }

# 1. Beyond loopback: refused without TLS, allowed (with a warning) with --insecure.
if "$BIN/invr-server" --store s0 --address 0.0.0.0:0 >plain.log 2>&1; then fail "plaintext on 0.0.0.0 was accepted"; fi
grep -q "needs TLS (--tls-cert and --tls-key) or --insecure" plain.log || fail "no clear error for a plaintext non-loopback bind"
"$BIN/invr-server" --store s1 --address 0.0.0.0:0 --insecure --port-file p1 >insecure.log 2>&1 &
PIDS+=($!)
waitport p1
grep -q "without TLS (--insecure)" insecure.log || fail "no warning for --insecure"
kill "${PIDS[-1]}"

# 2. TLS and tokens.
"$BIN/invr-server" --store s2 --address 0.0.0.0:0 --tls-cert server.pem --tls-key server.key --final-spp 4 \
  --client-token-file client.tok --worker-token-file worker.tok --port-file p2 >server.log 2>&1 &
PIDS+=($!)
waitport p2
ADDR="127.0.0.1:$(cat p2)"
C=(--server "$ADDR" --tls-ca ca.pem)

# Clients: no token -> 7 (UNAUTHENTICATED); the worker's token -> 7 (PERMISSION_DENIED); no TLS -> 5.
set +e
"$BIN/invr" list "${C[@]}" 2>err1; e1=$?
"$BIN/invr" list "${C[@]}" --token-file worker.tok 2>err2; e2=$?
INVR_TOKEN="$(cat client.tok)" "$BIN/invr" list --server "$ADDR" 2>err3; e3=$?
set -e
[ "$e1" = 7 ] && grep -q "no bearer token" err1 || fail "no token: exit $e1 $(cat err1)"
[ "$e2" = 7 ] && grep -q "a worker token cannot use the client API" err2 || fail "worker token as client: exit $e2 $(cat err2)"
[ "$e3" = 5 ] || fail "plaintext to a TLS server: exit $e3 $(cat err3)"
INVR_TOKEN="$(cat client.tok)" "$BIN/invr" list "${C[@]}" >/dev/null || fail "client token from \$INVR_TOKEN refused"

# Workers: a wrong token and the client's token are refused; the worker exits 3.
set +e
timeout 30 "$BIN/invr-worker" "${C[@]}" --token-file client.tok --threads 1 >wclient.log 2>&1; w1=$?
echo "not-the-token" >wrong.tok
timeout 30 "$BIN/invr-worker" "${C[@]}" --token-file wrong.tok --threads 1 >wwrong.log 2>&1; w2=$?
set -e
[ "$w1" = 3 ] && grep -q "PERMISSION_DENIED" wclient.log || fail "client token as worker: exit $w1"
[ "$w2" = 3 ] && grep -q "UNAUTHENTICATED" wwrong.log || fail "wrong worker token: exit $w2"
grep -q "a client token cannot connect a worker" server.log || fail "the refusal is not in the server log"
grep -q "invalid bearer token" server.log || fail "the wrong token's refusal is not in the server log"
if grep -q "$(cat client.tok)\|$(cat worker.tok)\|not-the-token" server.log; then fail "a token appears in the server log"; fi

# The right credentials: a job runs end to end over TLS.
INVR_WORKER_TOKEN="$(cat worker.tok)" "$BIN/invr-worker" "${C[@]}" --threads 2 >worker.log 2>&1 &
PIDS+=($!)
"$BIN/invr" run cornell --steps 2 --target-spp 4 "${C[@]}" --token-file client.tok -o run >run.log 2>&1 || fail "job over TLS failed"
grep -q "SUCCEEDED" run.log || fail "job did not succeed: $(tail -3 run.log)"
test -s run/parameters.json || fail "no results fetched"

# 3. Mutual TLS: a client without a certificate cannot even connect; with one it can.
"$BIN/invr-server" --store s3 --tls-cert server.pem --tls-key server.key --tls-client-ca ca.pem --address 127.0.0.1:0 --port-file p3 >mtls.log 2>&1 &
PIDS+=($!)
waitport p3
A3="127.0.0.1:$(cat p3)"
set +e
"$BIN/invr" list --server "$A3" --tls-ca ca.pem 2>err4; e4=$?
set -e
[ "$e4" = 5 ] || fail "mutual TLS without a client certificate: exit $e4"
# (Up to three tries: on a loaded machine the first handshake after the refused one above has
# been seen to fail once, "Handshake write failed"; a certificate that is refused fails all three.)
ok=0
for _ in 1 2 3; do
  if "$BIN/invr" list --server "$A3" --tls-ca ca.pem --tls-cert client.pem --tls-key client.key >/dev/null 2>err5; then ok=1; break; fi
  sleep 1
done
[ "$ok" = 1 ] || fail "mutual TLS with a certificate refused: $(cat err5)"
echo "tls and tokens: ok"
