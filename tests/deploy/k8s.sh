#!/usr/bin/env bash
# deploy/k8s, offline: kubectl renders the kustomization, and every object is validated against
# the Kubernetes API schema (deploy/k8s/validator: the kubernetes-models package's validators,
# installed by deploy/setup.sh). Then what the manifests promise is checked: the kinds, native
# gRPC probes on the health port, tokens and TLS from Secrets, a worker's drain time inside its
# grace period, non-root pods, and that every flag the manifests pass exists in the executables.
# The validator is shown to reject a broken object.
set -euo pipefail
REPO="$(cd "$(dirname "$0")/../.." && pwd)"
BIN="$1"
VAL="$REPO/deploy/k8s/validator"
fail() { echo "k8s: $*"; exit 1; }
command -v kubectl > /dev/null || fail "kubectl missing (deploy/setup.sh installs kubernetes-client)"
command -v node > /dev/null || fail "node missing (deploy/setup.sh installs nodejs)"
[ -d "$VAL/node_modules/kubernetes-models" ] || fail "validator packages missing (deploy/setup.sh runs npm ci in $VAL)"
DIR="$(mktemp -d)"
trap 'rm -rf "$DIR"' EXIT

kubectl kustomize "$REPO/deploy/k8s" > "$DIR/all.yaml" 2> "$DIR/kustomize.err" || { cat "$DIR/kustomize.err"; fail "kustomize failed"; }
node "$VAL/validate.js" "$DIR/all.yaml" | tee "$DIR/validate.txt"
for k in "v1 Namespace/invr" "v1 Service/invr-server" "apps/v1 StatefulSet/invr-server" "apps/v1 Deployment/invr-worker" \
         "policy/v1 PodDisruptionBudget/invr-worker" "autoscaling/v2 HorizontalPodAutoscaler/invr-worker" \
         "networking.k8s.io/v1 NetworkPolicy/invr-server" "networking.k8s.io/v1 NetworkPolicy/invr-worker"; do
  grep -qx "ok $k" "$DIR/validate.txt" || fail "missing or invalid: $k"
done

# What the objects must say, read from the rendered YAML.
node - "$DIR/all.yaml" "$VAL" << 'JS' > "$DIR/flags.txt" || fail "manifest checks failed"
const fs = require("fs");
const YAML = require(process.argv[3] + "/node_modules/yaml");
const objs = YAML.parseAllDocuments(fs.readFileSync(process.argv[2], "utf8")).map((d) => d.toJSON()).filter(Boolean);
const find = (kind, name) => objs.find((o) => o.kind === kind && o.metadata.name === name) || fail(`no ${kind}/${name}`);
function fail(m) { console.error("k8s: " + m); process.exit(1); }
const sts = find("StatefulSet", "invr-server"), dep = find("Deployment", "invr-worker");
if (!(sts.spec.volumeClaimTemplates || []).some((v) => v.metadata.name === "store")) fail("the server has no store PersistentVolumeClaim");
const server = sts.spec.template.spec.containers[0], worker = dep.spec.template.spec.containers[0];
const healthPort = Number((server.args.find((a) => a.startsWith("--health-address=")) || fail("no --health-address")).split(":").pop());
for (const p of ["readinessProbe", "livenessProbe"])
  if (!server[p] || !server[p].grpc || server[p].grpc.port !== healthPort) fail(`server ${p} is not a gRPC probe on the health port ${healthPort}`);
const secretEnv = (c, name) => (c.env || []).some((e) => e.name === name && e.valueFrom && e.valueFrom.secretKeyRef);
if (!secretEnv(server, "INVR_CLIENT_TOKEN") || !secretEnv(server, "INVR_WORKER_TOKEN")) fail("the server's tokens do not come from a Secret");
if (!secretEnv(worker, "INVR_WORKER_TOKEN")) fail("the worker's token does not come from a Secret");
if (secretEnv(worker, "INVR_CLIENT_TOKEN")) fail("workers must not hold the client token");
for (const [o, c] of [[sts, server], [dep, worker]]) {
  const vols = o.spec.template.spec.volumes || [];
  if (!vols.some((v) => v.secret && v.secret.secretName === "invr-tls")) fail(`${o.metadata.name}: TLS material not from the invr-tls Secret`);
  if (!o.spec.template.spec.securityContext.runAsNonRoot) fail(`${o.metadata.name}: not runAsNonRoot`);
  if (!c.resources || !c.resources.requests || !c.resources.limits) fail(`${o.metadata.name}: no resource requests and limits`);
}
const drain = Number((worker.args.find((a) => a.startsWith("--drain-seconds=")) || fail("no --drain-seconds")).split("=")[1]);
const grace = dep.spec.template.spec.terminationGracePeriodSeconds;
if (!(grace > drain + 5)) fail(`worker grace period ${grace} s does not cover --drain-seconds ${drain} plus the hand-back`);
const svcPorts = find("Service", "invr-server").spec.ports.map((p) => p.port);
if (!worker.args.includes(`--server=invr-server:${svcPorts[0]}`)) fail("workers do not dial the server's Service");
// The flags each executable is given, for the --help check below.
for (const a of server.args) console.log("invr-server " + a.split("=")[0]);
for (const a of worker.args) console.log("invr-worker " + a.split("=")[0]);
JS
while read -r exe flag; do
  "$BIN/$exe" --help | grep -q -- "$flag" || fail "$exe has no $flag (used by the manifests)"
done < "$DIR/flags.txt"

# The validator can fail: a StatefulSet whose replicas is a string.
sed 's/^  replicas: 1$/  replicas: one/' "$DIR/all.yaml" > "$DIR/broken.yaml"
grep -q "replicas: one" "$DIR/broken.yaml" || fail "could not break the StatefulSet for the negative check"
if node "$VAL/validate.js" "$DIR/broken.yaml" > "$DIR/broken.txt"; then fail "the validator accepted replicas: one"; fi
grep -q "INVALID apps/v1 StatefulSet/invr-server" "$DIR/broken.txt" || fail "the validator did not name the broken object"
echo "k8s: ok ($(grep -c '^ok ' "$DIR/validate.txt") objects valid; manifests and executables agree)"
