#!/usr/bin/python3
"""Prints the results table of docs/results/README.md from a committed `invr-lab eval` run (docs/results/summary.json),
so every figure there is copied by a program, not by hand. Usage:
    /usr/bin/python3 tests/bench/readme_results.py [docs/results/summary.json]
"""
import json
import sys


def f(v, digits=3):
    if v is None:
        return "n/a"
    if isinstance(v, str):
        return v
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 100:
        return f"{v:.0f}"
    if a >= 0.01:
        return f"{v:.{digits}g}"
    return f"{v:.2e}"


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "docs/results/summary.json"
    d = json.load(open(path))
    out = []
    out.append(f"From [docs/results/summary.json](summary.json) ({d['mode']} run of {d['date']}, "
               f"{d['machine']['cores']} cores). Parameter error: RMS over the last quarter of the budget; image error: "
               "per-pixel relative RMSE of renders at the result. Ratios are baseline / method: above 1, the method is "
               "closer to the truth. One run per method: ratios within about 1.2 of each other are ties.")
    out.append("")
    out.append("| scene (budget per method) | method | steps | parameter error | image error | parameter ratio | image ratio |")
    out.append("|---|---|---:|---:|---:|---:|---:|")
    for name, s in d["scenes"].items():
        first = True
        for m, r in s["methods"].items():
            label = f"{name} ({f(s['budget_seconds_per_method'])} s; start {f(s['initial_param_error'])})" if first else ""
            out.append(f"| {label} | {m} | {r['steps']} | {f(r['param_error_tail'])} | {f(r['image_error'])} | "
                       f"{f(r['param_error_tail_ratio_vs_baseline'])} | {f(r['image_error_ratio_vs_baseline'])} |")
            first = False
    out.append("")
    for name, s in d["scenes"].items():
        if s.get("setting"):
            out.append(f"- {name}: {s['setting']}")
    out.append("")
    for t in d.get("gradient_quality", []):
        b = t.get("benchmark")
        if b == "gradients":
            se = t.get("ratio_ris_over_restir_standard_error")
            line = (f"- `bench gradients --scene {t['scene']}` (equal time, against independent RIS evaluations): relMSE "
                    f"RIS / ReSTIR = {f(t['ratio_ris_over_restir'])} ± {f(se)}, PT / ReSTIR = {f(t['ratio_pt_over_restir'])}")
            if "ratio_ris_over_restir_changing_theta" in t:
                line += (f"; with θ changing every step RIS / ReSTIR = {f(t['ratio_ris_over_restir_changing_theta'])} "
                         f"(ReSTIR relMSE {f(t['relmse_restir_changing_theta'])} against {f(t['relmse']['restir'])} at fixed θ)")
            out.append(line + " (target ≥ 10 vs RIS)")
        elif b == "overhead":
            out.append(f"- `bench overhead --scene {t['scene']}`: ReSTIR overhead fraction over RIS at equal samples "
                       f"{f(t['restir_overhead_fraction'])}, with kd-tree neighbours {f(t['restir_kd_tree_overhead_fraction'])} "
                       "(target ≤ 0.20)")
        elif b == "pixel-variance":
            out.append(f"- `bench pixel-variance --scene {t['scene']}` at θ fraction {f(t['theta_fraction'])}: gradient variance "
                       f"loss_grad / adaptive = {f(t['ratio_loss_grad_over_adaptive'])}, uniform / adaptive = "
                       f"{f(t['ratio_uniform_over_adaptive'])}; stage-1 overhead {f(t['stage1_overhead_fraction'])}")
    print("\n".join(out))


if __name__ == "__main__":
    main()
