# Charts convergence CSVs (method,step,seconds,loss,param_error): one line per run, log-scale
# error axis, legend from the runs' method names. Run by `invr chart` and by the server for each
# finished job, with Debian's /usr/bin/python3 and matplotlib.
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(argv):
    out, x, y = argv[0], argv[1], argv[2]
    inputs = argv[3:]
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    runs = []
    for path in inputs:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        for col in (x, y):
            if rows and col not in rows[0]:
                sys.exit(f"{path}: no column '{col}' (has {', '.join(rows[0].keys())})")
        pts = [(float(r[x]), float(r[y])) for r in rows if float(r[y]) > 0]
        if not pts:
            print(f"{path}: no positive '{y}' values; skipped", file=sys.stderr)
            continue
        folder = os.path.basename(os.path.dirname(os.path.abspath(path)))
        runs.append((rows[0].get("method", "") or folder, folder, pts))
    # Runs of the same method are told apart by their folders.
    methods = [r[0] for r in runs]
    plotted = 0
    for method, folder, pts in runs:
        label = f"{method} ({folder})" if methods.count(method) > 1 else method
        ax.plot([p[0] for p in pts], [p[1] for p in pts], label=label, linewidth=1.4)
        plotted += 1
    if plotted == 0:
        sys.exit(f"nothing to plot: no run has positive '{y}' values")
    ax.set_yscale("log")
    ax.set_xlabel({"seconds": "wall-clock seconds", "step": "step"}.get(x, x))
    ax.set_ylabel({"param_error": "parameter RMSE", "loss": "loss"}.get(y, y))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out)


if __name__ == "__main__":
    main(sys.argv[1:])
