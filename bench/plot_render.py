#!/usr/bin/env python3
"""Log-log plot of RMSE against wall seconds from `tandem bench render --csv FILE`.

    bench/plot_render.py render.csv render_convergence.png

Draws the measured points, the least-squares fit, and a reference line of slope -1/2 through the
first point. The PNG is deterministic: no timestamp or software tag in its metadata.
Needs matplotlib and numpy (not needed by the C++ build).
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main(argv):
    if len(argv) != 3:
        sys.stderr.write("usage: plot_render.py CSV PNG\n")
        return 2
    src, dst = argv[1], argv[2]
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    if len(rows) < 2:
        sys.stderr.write(f"{src}: need at least two convergence rows\n")
        return 1
    spp = np.array([int(r["spp"]) for r in rows])
    t = np.array([float(r["seconds"]) for r in rows])
    rmse = np.array([float(r["rmse"]) for r in rows])
    slope, intercept = np.polyfit(np.log(t), np.log(rmse), 1)

    fig, ax = plt.subplots(figsize=(6.0, 4.5), dpi=100)
    ax.loglog(t, rmse, "o-", color="tab:blue", label="measured")
    for x, y, n in zip(t, rmse, spp):
        ax.annotate(f"{n}", (x, y), textcoords="offset points", xytext=(5, 4), fontsize=8)
    span = np.array([t.min(), t.max()])
    ax.loglog(span, np.exp(intercept) * span**slope, "-", color="tab:orange", lw=1,
              label=f"fit: slope {slope:.3f}")
    ax.loglog(span, rmse[0] * (span / t[0]) ** -0.5, "--", color="gray", lw=1,
              label="slope -1/2")
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("RMSE against reference")
    ax.set_title("tandem bench render: error against time (labels: spp)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()

    tmp = dst + ".tmp.png"
    fig.savefig(tmp, metadata={"Software": None})
    plt.close(fig)
    os.replace(tmp, dst)
    print(f"{dst}: slope {slope:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
