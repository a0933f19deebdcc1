#!/usr/bin/env python3
"""The three series of `tandem bench soak --json > soak.json` against iteration.

    bench/plot_soak.py soak.json soak.png

Resident memory (MiB), live device buffers (count, and MiB on the right axis) and the mean time
per iteration (ms), each with its least-squares line and slope ± standard error. The PNG is
deterministic: no timestamp or software tag in its metadata. Needs matplotlib (plotting only).
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def line(ax, x, fit, scale, color):
    mean_x = sum(x) / len(x)
    y = [scale * (fit["mean"] + fit["slope_per_iteration"] * (v - mean_x)) for v in x]
    ax.plot(x, y, "--", color=color, linewidth=1)


def label(fit, scale, unit):
    return (f"slope {scale * fit['slope_per_iteration']:.3g} ± {scale * fit['stderr']:.2g} {unit}"
            f" / iteration ({'flat' if fit['flat'] else 'not flat'} within 3 s.e.)")


def main(argv):
    if len(argv) != 3:
        sys.stderr.write("usage: plot_soak.py SOAK.json PNG\n")
        return 2
    with open(argv[1]) as f:
        r = json.load(f)
    s = r["samples"]
    if len(s) < 2:
        sys.stderr.write(f"{argv[1]}: need at least two samples\n")
        return 1
    x = [v["iteration"] for v in s]
    slopes = r["slopes"]
    mib = 1.0 / (1 << 20)
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)

    ax = axes[0]
    ax.plot(x, [v["rss_bytes"] * mib for v in s], ".", color="C0", markersize=3)
    line(ax, x, slopes["rss_bytes"], mib, "C0")
    ax.set_ylabel("resident memory (MiB)")
    ax.set_title(label(slopes["rss_bytes"], 1.0, "bytes"), fontsize=9)

    ax = axes[1]
    ax.plot(x, [v["live_buffers"] for v in s], ".", color="C1", markersize=3)
    ax.set_ylabel("live device buffers", color="C1")
    ax.set_title(label(slopes["live_buffers"], 1.0, "buffers") + "; bytes: " +
                 label(slopes["live_buffer_bytes"], 1.0, "bytes"), fontsize=8)
    right = ax.twinx()
    right.plot(x, [v["live_buffer_bytes"] * mib for v in s], "-", color="C2", linewidth=1)
    right.set_ylabel("live device MiB", color="C2")

    ax = axes[2]
    ax.plot(x, [1e3 * v["seconds_per_iteration"] for v in s], ".", color="C3", markersize=3)
    line(ax, x, slopes["seconds_per_iteration"], 1e3, "C3")
    ax.set_ylabel("ms / iteration (mean of window)")
    ax.set_xlabel("iteration")
    ax.set_title(label(slopes["seconds_per_iteration"], 1e3, "ms"), fontsize=9)

    fig.suptitle(f"tandem bench soak: {r['iterations']} iterations, {r['res']}², {r['spp']} spp, "
                 f"CV-PS, ReSTIR {r['restir'].split(' ')[0]}\n{r['device']}", fontsize=10)
    fig.tight_layout()
    fig.savefig(argv[2], dpi=100, metadata={"Software": None})
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
