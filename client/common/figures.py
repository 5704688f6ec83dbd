# Figures drawn with Debian's /usr/bin/python3 and matplotlib; compiled into invr and the server.
#   chart OUT X Y TITLE CSV...   convergence CSVs (method,step,seconds,loss,param_error,image_error[,shape_error][,image_loss],...):
#                                one line per method and file, log-scale error axis, legend from
#                                the method names; empty cells (unmeasured points) are skipped.
#   grid OUT SPEC.json           images side by side: {"title", "columns": [...], "rows":
#                                [{"label", "cells": [{"image": PNG or null, "caption"}]}]}
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

LABELS = {
    "seconds": "wall-clock seconds",
    "step": "step",
    "param_error": "parameter RMSE",
    "loss": "loss",
    "image_error": "image error (relative RMSE)",
    "shape_error": "shape error (chamfer / bounding-box diagonal)",
    "image_loss": "image loss (one render, smoothed)",
}


def number(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def chart(out, x, y, title, inputs):
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    runs = []  # (method, folder, points) in first-seen order
    # The loss is an unbiased estimate and can dip below 0 near the optimum: keep those points and
    # draw a symmetric log axis. Errors are positive by construction; non-positive ones are skipped.
    signed = y == "loss"
    for path in inputs:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        for col in (x, y):
            if rows and col not in rows[0]:
                sys.exit(f"{path}: no column '{col}' (has {', '.join(rows[0].keys())})")
        folder = os.path.basename(os.path.dirname(os.path.abspath(path)))
        by_method = {}
        for r in rows:
            xv, yv = number(r.get(x)), number(r.get(y))
            if xv is None or yv is None or (yv <= 0 and not signed):
                continue
            by_method.setdefault(r.get("method", "") or folder, []).append((xv, yv))
        if not by_method:
            print(f"{path}: no positive '{y}' values; skipped", file=sys.stderr)
        for method, pts in by_method.items():
            runs.append((method, folder, pts))
    if not runs:
        sys.exit(f"nothing to plot: no run has positive '{y}' values")
    # Runs of the same method are told apart by their folders.
    methods = [r[0] for r in runs]
    smoothed = False
    for method, folder, pts in runs:
        label = f"{method} ({folder})" if methods.count(method) > 1 else method
        xs, ys = [p[0] for p in pts], [p[1] for p in pts]
        if len(pts) > 100:
            # Long noisy runs (a scalar oscillating around its optimum) are unreadable raw: draw
            # them faintly, and over them the RMS of the last 2 % of the points.
            line = ax.plot(xs, ys, linewidth=0.5, alpha=0.25)[0]
            w = max(5, len(ys) // 50)
            acc, rms = 0.0, []
            for i, v in enumerate(ys):
                # A signed series (the loss) is smoothed by its mean, an error by its RMS.
                acc += v if signed else v * v
                if i >= w:
                    acc -= ys[i - w] if signed else ys[i - w] * ys[i - w]
                rms.append(acc / min(i + 1, w) if signed else (max(acc, 0.0) / min(i + 1, w)) ** 0.5)
            ax.plot(xs, rms, label=label, linewidth=1.6, color=line.get_color())
            smoothed = True
        else:
            marker = "o" if len(pts) <= 12 else None  # sparse series (image error) show their points
            ax.plot(xs, ys, label=label, linewidth=1.4, marker=marker, markersize=3)
    values = [v for _, _, pts in runs for _, v in pts]
    if signed and min(values) <= 0:
        tiny = [abs(v) for v in values if v != 0]
        ax.set_yscale("symlog", linthresh=min(tiny) if tiny else 1e-12)
    else:
        ax.set_yscale("log")
    ax.set_xlabel(LABELS.get(x, x))
    ax.set_ylabel(LABELS.get(y, y) + ("\n(bold: " + ("mean" if signed else "RMS") + " over the last 2 % of steps; faint: every step)" if smoothed else ""))
    if title:
        ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out)


def grid(out, spec_path):
    with open(spec_path) as f:
        spec = json.load(f)
    rows, columns = spec["rows"], spec["columns"]
    if not rows or not columns:
        sys.exit("grid: no rows or no columns")
    fig, axes = plt.subplots(len(rows), len(columns), figsize=(2.6 * len(columns), 2.5 * len(rows) + 0.5), dpi=110,
                             squeeze=False)
    for i, row in enumerate(rows):
        for j, cell in enumerate(row["cells"]):
            ax = axes[i][j]
            ax.set_xticks([])
            ax.set_yticks([])
            if cell.get("image"):
                ax.imshow(mpimg.imread(cell["image"]), interpolation="nearest")
            else:
                for side in ax.spines.values():
                    side.set_visible(False)
            ax.set_xlabel(cell.get("caption", ""), fontsize=8)
            if i == 0:
                ax.set_title(columns[j], fontsize=9)
            if j == 0:
                ax.set_ylabel(row["label"], fontsize=9)
    if spec.get("title"):
        fig.suptitle(spec["title"], fontsize=11)
    fig.tight_layout()
    fig.savefig(out)


def main(argv):
    if argv and argv[0] == "chart":
        chart(argv[1], argv[2], argv[3], argv[4], argv[5:])
    elif argv and argv[0] == "grid":
        grid(argv[1], argv[2])
    else:
        sys.exit("usage: figures.py chart|grid ...")


if __name__ == "__main__":
    main(sys.argv[1:])
