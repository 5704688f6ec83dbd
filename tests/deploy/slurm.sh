#!/usr/bin/env bash
# deploy/slurm/invr.sbatch on a real Slurm: munged, slurmctld and slurmd (Debian's slurm-wlm and
# munge) configured in a temporary directory, started here and stopped on exit; a small job goes
# through `sbatch --wait` with a bounded timeout and must succeed with its results in place; a
# second one is requeued mid-run and must resume from its checkpoint and succeed.
# Skips, saying why, only where Slurm cannot start (not root, packages missing).
#   bash tests/deploy/slurm.sh BIN_DIR
set -euo pipefail
BIN="$(realpath "${1:-build/bin}")"
REPO="$(cd "$(dirname "$0")/../.." && pwd)"
skip() { echo "slurm test: SKIPPED: $*"; exit 77; }  # 77: ctest reports it as skipped (SKIP_RETURN_CODE)
[ "$(id -u)" -eq 0 ] || skip "needs root to start munged, slurmctld and slurmd"
for b in munged slurmctld slurmd sbatch scontrol sinfo; do
  command -v "$b" > /dev/null || skip "$b is not installed (deploy/setup.sh installs slurm-wlm and munge)"
done

ROOT="$(mktemp -d /tmp/invr-slurm.XXXXXX)"
chmod 755 "$ROOT"
export SLURM_CONF="$ROOT/slurm.conf"
cleanup() {
  for pid in "$ROOT/slurmd.pid" "$ROOT/slurmctld.pid" "$ROOT/munged.pid"; do
    [ -s "$pid" ] && kill "$(cat "$pid")" 2> /dev/null || true
  done
  sleep 1
  rm -rf "$ROOT"
}
trap cleanup EXIT
dump() {
  for f in slurmctld.log slurmd.log munged.log; do echo "--- $f"; tail -n 30 "$ROOT/$f" 2> /dev/null || true; done
  for f in "$ROOT"/work/invr-*.log "$ROOT"/work/out/server.log "$ROOT"/work/out/workers.log; do
    [ -e "$f" ] && { echo "--- $f"; tail -n 40 "$f"; }
  done
}
free_port() { /usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }

# munge, on its own socket and key (never the machine's).
dd if=/dev/urandom of="$ROOT/munge.key" bs=1024 count=1 status=none
chmod 400 "$ROOT/munge.key"
munged --force --socket="$ROOT/munge.sock" --key-file="$ROOT/munge.key" --pid-file="$ROOT/munged.pid" \
  --log-file="$ROOT/munged.log" --seed-file="$ROOT/munged.seed" || { dump; skip "munged cannot start"; }

HOST="$(hostname -s)"
CPUS="$(nproc)"
mkdir -p "$ROOT/state" "$ROOT/spool" "$ROOT/work"
cat > "$SLURM_CONF" << CONF
ClusterName=invrtest
SlurmctldHost=$HOST
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$ROOT/munge.sock
CredType=cred/munge
StateSaveLocation=$ROOT/state
SlurmdSpoolDir=$ROOT/spool
SlurmctldPidFile=$ROOT/slurmctld.pid
SlurmdPidFile=$ROOT/slurmd.pid
SlurmctldLogFile=$ROOT/slurmctld.log
SlurmdLogFile=$ROOT/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
NodeName=$HOST CPUs=$CPUS State=UNKNOWN
PartitionName=invr Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -i || { dump; skip "slurmctld cannot start"; }
slurmd || { dump; skip "slurmd cannot start"; }
ready=0
for _ in $(seq 1 60); do
  if sinfo -h -o '%t' 2> /dev/null | grep -qE '^(idle|mix)'; then ready=1; break; fi
  sleep 0.5
done
[ "$ready" -eq 1 ] || { dump; skip "the Slurm node never became idle"; }
echo "slurm: up ($(sinfo -h -o '%P %D %t %c'))"

# A small job: cornell's built-in job, 3 steps, low-spp targets, on 2 tasks of 1 CPU (2 workers),
# over TLS (a CA and a certificate for this node) with the batch job's own tokens.
cd "$ROOT/work"
mkdir -p "$ROOT/tls"
openssl req -x509 -newkey rsa:2048 -nodes -keyout "$ROOT/tls/ca.key" -out "$ROOT/tls/ca.pem" -days 2 -subj "/CN=invr slurm test CA" 2>/dev/null
openssl req -newkey rsa:2048 -nodes -keyout "$ROOT/tls/server.key" -out "$ROOT/tls/server.csr" -subj "/CN=$(hostname -s)" 2>/dev/null
printf "subjectAltName=DNS:%s,DNS:localhost,IP:127.0.0.1\n" "$(hostname -s)" > "$ROOT/tls/server.ext"
openssl x509 -req -in "$ROOT/tls/server.csr" -CA "$ROOT/tls/ca.pem" -CAkey "$ROOT/tls/ca.key" -CAcreateserial \
  -out "$ROOT/tls/server.pem" -days 2 -extfile "$ROOT/tls/server.ext" 2>/dev/null
set +e
timeout 600 sbatch --wait --ntasks=2 --cpus-per-task=1 --output="$ROOT/work/invr-%j.log" \
  --export=ALL,INVR_BIN="$BIN",INVR_PORT="$(free_port)",INVR_ARGS="--steps 3 --target-spp 4",INVR_SERVER_ARGS="--final-spp 4",INVR_TLS_CERT="$ROOT/tls/server.pem",INVR_TLS_KEY="$ROOT/tls/server.key",INVR_TLS_CA="$ROOT/tls/ca.pem" \
  "$REPO/deploy/slurm/invr.sbatch" cornell "$ROOT/work/out"
code=$?
set -e
if [ "$code" -ne 0 ]; then
  echo "slurm: the batch job exited with $code"
  dump
  exit 1
fi
grep -q "ended with exit code 0" "$ROOT"/work/invr-*.log || { dump; echo "slurm: no success line in the job's log"; exit 1; }
for f in parameters.json convergence.csv final_view0.exr; do
  [ -s "$ROOT/work/out/results/$f" ] || { dump; echo "slurm: results/$f missing"; exit 1; }
done
workers=$(grep -c "threads) connected" "$ROOT/work/out/server.log" || true)
[ "$workers" -ge 2 ] || { dump; echo "slurm: expected 2 workers, the server saw $workers"; exit 1; }
grep -q "(TLS; store" "$ROOT/work/out/server.log" || { dump; echo "slurm: the server did not serve TLS"; exit 1; }
grep -q "bearer tokens required: client API yes, worker API yes" "$ROOT/work/out/server.log" || { dump; echo "slurm: no tokens"; exit 1; }
[ "$(stat -c %a "$ROOT/work/out/.tokens/client")" = 600 ] || { echo "slurm: the token file is readable by others"; exit 1; }
cat "$ROOT"/work/invr-*.log
echo "slurm: first job ok ($workers workers; results in place)"

# Requeue mid-job (without INVR_PORT: the script picks a free port, again after the requeue):
# the batch job restarts with the same id, the server finds the job in its store
# and resumes from the last checkpoint, and the same request id finds that job again.
id=$(sbatch --parsable --ntasks=1 --cpus-per-task=1 --open-mode=append --output="$ROOT/work/requeue-%j.log" \
  --export=ALL,INVR_BIN="$BIN",INVR_ARGS="--steps 80 --target-spp 4",INVR_SERVER_ARGS="--final-spp 4" \
  "$REPO/deploy/slurm/invr.sbatch" cornell "$ROOT/work/requeue")
log="$ROOT/work/requeue-$id.log"
for _ in $(seq 1 240); do
  grep -qE '^step (2[0-9]|[3-9][0-9]|[0-9]{3})/' "$log" 2> /dev/null && break
  sleep 0.5
done
grep -qE '^step [0-9]+/80' "$log" || { dump; cat "$log"; echo "slurm: the second job never reached step 20"; exit 1; }
scontrol requeue "$id"
echo "slurm: requeued batch job $id mid-run"
state=""
t0=$SECONDS
for _ in $(seq 1 600); do
  info=$(scontrol show job "$id" 2> /dev/null || true)
  state=$(grep -oE 'JobState=[A-Z_]+' <<< "$info" | cut -d= -f2 || true)
  case "$state" in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY) break ;; esac
  # Slurm holds a requeued job back (Reason=BeginTime) before it may start again: start it now.
  if grep -q 'Reason=BeginTime' <<< "$info"; then scontrol update JobId="$id" StartTime=now > /dev/null 2>&1 || true; fi
  sleep 1
done
echo "slurm: the requeued job ended $state $((SECONDS - t0)) s after the requeue"
cat "$log"
[ "$state" = COMPLETED ] || { dump; echo "slurm: the requeued job ended $state"; exit 1; }
grep -q "resumed from checkpoint" "$ROOT/work/requeue/server.log" "$log" || { dump; echo "slurm: the requeued job did not resume from its checkpoint"; exit 1; }
[ "$(grep -c '^invr.sbatch: job job-000001 on' "$log")" -eq 2 ] || { echo "slurm: the requeued run submitted a new job instead of finding its own"; exit 1; }
[ -s "$ROOT/work/requeue/results/parameters.json" ] || { dump; echo "slurm: the requeued job's results are missing"; exit 1; }
echo "slurm: ok (batch job succeeded on $workers workers; a requeued job resumed from its checkpoint)"
