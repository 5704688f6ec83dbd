#!/usr/bin/env bash
# invr-lab bench gradient-vector (issue 58: the invr half of deploy/peers.sh): a job's gradient at its
# start per component with standard errors, per method, beside central finite differences of
# invr's own renders; errors for impossible settings. A smoke test of the command: the estimators
# themselves are validated against finite differences in tests/core/diff.
# usage: gradient_vector.sh BIN_DIR WORK_DIR
set -euo pipefail
BIN="$1"
DIR="$2"
rm -rf "$DIR"
mkdir -p "$DIR"
cd "$DIR"
fail() { echo "gradient_vector: FAILED: $*"; exit 1; }

"$BIN/invr-lab" bench gradient-vector cornell --set optimization.target_spp=16 --methods pt,ris --evaluations 4 --fd-evaluations 4 \
  --fd-components 0 --per-evaluation --targets-out targets --json > g.json 2> g.err || fail "the command failed: $(tail -3 g.err)"
[ -s targets/target_view0.exr ] || fail "no target image written"
/usr/bin/python3 - g.json <<'PYEOF' || fail "the report is wrong"
import json, sys, math
d = json.load(open(sys.argv[1]))
n = sum(p["size"] for p in d["parameters"])
assert n == 9 and len(d["theta"]) == 9 and len(d["truth"]) == 9, "three albedos, nine values"
assert d["loss"] == "relative_l2" and d["views"] == 1
fd = d["fd"]
assert fd["mode"] == "direction" and len(fd["values"]) == 1 and len(fd["direction"]) == 9  # --fd-components 0
u = fd["direction"]
for m in ("pt", "ris"):
    g = d["methods"][m]
    assert len(g["gradient"]) == 9 and len(g["se"]) == 9 and len(g["samples"]) == 4 and g["step_seconds"] > 0
    for k in range(9):
        mean = sum(s[k] for s in g["samples"]) / 4
        assert abs(mean - g["gradient"][k]) <= 2e-5 * max(1e-3, abs(mean)), "the mean is the samples' mean"
    # g.u against the difference along u: a sanity bound (5 standard errors), not a validation of
    # the estimator.
    gu = [sum(a * b for a, b in zip(s, u)) for s in g["samples"]]
    mean = sum(gu) / 4
    se = math.sqrt(sum((x - mean) ** 2 for x in gu) / 3 / 4)
    z = (mean - fd["values"][0]) / math.sqrt(se ** 2 + fd["se"][0] ** 2)
    print(f"{m}: g.u {mean:.5g} +- {se:.2g}, finite difference {fd['values'][0]:.5g} +- {fd['se'][0]:.2g}, z {z:.2f}")
    assert abs(z) < 5, f"{m}: z {z:.1f} against finite differences"
print("gradient-vector report ok")
PYEOF
if "$BIN/invr-lab" bench gradient-vector cornell --evaluations 1 > one.log 2>&1; then fail "--evaluations 1 was accepted"; fi
grep -q "at least 2" one.log || fail "the error does not say why: $(cat one.log)"
echo "gradient_vector: ok"
