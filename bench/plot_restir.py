#!/usr/bin/env python3
"""relMSE against device time of the ReSTIR ablations, from `tandem bench restir --ablations --json`.

    build/tandem bench restir --ablations --json > restir.json
    /usr/bin/python3 bench/plot_restir.py restir.json restir_ablations.png

One point per ablation variant (ReSTIR with one setting changed from the default), with its
standard error, at the ablation's t of the first case; plain PRB at ReSTIR's spp and at its
equal-time spp, joined by a line of relMSE proportional to 1/time (what more samples buy), and RIS
likewise. A point below the PRB line is more efficient than PRB. The PNG is deterministic: no
timestamp or software tag in its metadata. Needs matplotlib and numpy (not the C++ build).
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main(argv):
    if len(argv) != 3:
        sys.stderr.write("usage: plot_restir.py RESTIR_JSON PNG\n")
        return 2
    src, dst = argv[1], argv[2]
    with open(src) as f:
        data = json.load(f)
    if not data.get("ablations"):
        sys.stderr.write(f"{src}: no ablations (run with --ablations)\n")
        return 1
    t = data["ablation_t"]
    case = data["cases"][0]
    point = next(p for p in case["points"] if p["t"] == t)
    est = {e["name"]: e for e in point["estimators"]}

    fig, ax = plt.subplots(figsize=(9.5, 5.0), dpi=100)
    for base, color in (("prb", "tab:gray"), ("ris", "tab:green")):
        pair = [est[base + "_equal_spp"], est[base]]
        x = np.array([e["seconds"] for e in pair])
        y = np.array([e["relmse"] for e in pair])
        span = np.array([x.min() * 0.7, max(x.max(), 1e-9) * 1.6])
        ax.loglog(span, y[1] * x[1] / span, "--", color=color, lw=1,
                  label=f"{base.upper()}, relMSE ∝ 1/time")
        ax.errorbar(x, y, yerr=[e["relmse_se"] for e in pair], fmt="s", color=color, ms=5)
        for e in pair:
            ax.annotate(f"{base.upper()} {e['spp']} spp", (e["seconds"], e["relmse"]),
                        textcoords="offset points", xytext=(5, -10), fontsize=7, color=color)
    markers = "o^vs<>DpPX*h"
    tab10 = plt.get_cmap("tab10").colors
    colors = [c for i, c in enumerate(tab10) if i not in (2, 7)]  # green and gray: RIS, PRB
    for i, a in enumerate(data["ablations"]):
        ax.errorbar([a["seconds"]], [a["relmse"]], yerr=[a["relmse_se"]],
                    fmt=markers[i % len(markers)], color=colors[i % len(colors)], ms=6,
                    capsize=2, label=a["name"])
    ax.set_xlabel("device seconds per iteration (resampling + adjoint, burn-in / t)")
    ax.set_ylabel("relMSE against the reference gradient")
    name = os.path.basename(case["scene"])
    # the scene's -D (in the JSON since the hidden-ledge runs), bar those the title gives anyway
    defines = {k: v for k, v in case.get("defines", {}).items() if k not in ("res", "max_depth")}
    if defines:
        name += " " + " ".join(f"{k}={v}" for k, v in sorted(defines.items()))
    ax.set_title(f"ReSTIR ablations: {name}, max_depth {case['max_depth']}, t = {t}, "
                 f"{data['res']}², spp_grad {data['spp_grad']}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5),
              title="ReSTIR variants", title_fontsize=7)
    fig.tight_layout()

    tmp = dst + ".tmp.png"
    fig.savefig(tmp, metadata={"Software": None})
    plt.close(fig)
    os.replace(tmp, dst)
    print(f"{dst}: {len(data['ablations'])} variants")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
