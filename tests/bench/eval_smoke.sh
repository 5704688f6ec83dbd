#!/usr/bin/env bash
# The evaluation suite's smoke run (CI): `invr-lab eval --quick` must finish and write a complete
# summary (every scene and method with finite errors and steps) plus its charts and images.
# The figures themselves are not judged here: one quick run on a shared machine is too noisy;
# the stability tests in ctest assert the comparisons that must hold.
set -euo pipefail
BIN="${1:-build/bin}"
OUT="${2:-build/eval-quick}"
rm -rf "$OUT"
"$BIN/invr-lab" eval --quick --out "$OUT"
/usr/bin/python3 - "$OUT" <<'PY'
import json, math, os, sys
out = sys.argv[1]
s = json.load(open(os.path.join(out, "summary.json")))
assert s["mode"] == "quick", s["mode"]
assert set(s["scenes"]) == {"cornell", "ajar", "mirror"}, list(s["scenes"])
for name, scene in s["scenes"].items():
    for key in ("chart", "image_error_chart", "side_by_side", "csv"):
        path = os.path.join(out, scene[key])
        assert os.path.getsize(path) > 0, path
    for method, m in scene["methods"].items():
        for key in ("param_error", "param_error_tail", "image_error", "seconds", "param_error_tail_ratio_vs_baseline"):
            assert isinstance(m[key], (int, float)) and math.isfinite(m[key]), (name, method, key, m[key])
        assert m["steps"] >= 1, (name, method)
        assert m["seconds"] >= scene["budget_seconds_per_method"], (name, method, "stopped before its budget")
titles = [t["benchmark"] for t in s["gradient_quality"]]
assert titles == ["gradients", "overhead", "pixel-variance", "variance", "variance", "variance"], titles
variance = {t["scene"]: t for t in s["gradient_quality"] if t["benchmark"] == "variance"}
for scene, keys in {"rings": ["detached_bias_se", "unbiased_bias_se"], "spot": ["ratio_power_over_optimized", "ratio_global_over_optimized"],
                    "roulette": ["ratio_constant_over_optimized"]}.items():
    for key in keys + ["overhead_ratio"]:
        assert isinstance(variance[scene][key], (int, float)) and math.isfinite(variance[scene][key]), (scene, key)
print("eval smoke: ok (%d scenes, %.0f s)" % (len(s["scenes"]), s["total_seconds"]))
PY
