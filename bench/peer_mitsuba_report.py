"""Tables, CSV and plot of bench/peer_mitsuba.py's result (a dict, as its --json prints)."""
import csv
import sys


def best(steps, warmup):
    """The least step time after the warm-up: other load only ever adds time."""
    return min(steps["seconds"][warmup:])


def fmt3(values, digits):
    return " / ".join(f"{v:+.{digits}f}" for v in values)


def tables(result):
    r = result
    variant = r.get("variant", "llvm_ad_rgb")
    lines = [f"Tandem {r['machine']['tandem_commit']} against Mitsuba {r['mitsuba']['mitsuba']} "
             f"(Dr.Jit {r['mitsuba']['drjit']}, {', '.join(r['mitsuba']['libllvm'])}), "
             f"{r['threads']} threads each, on {r['machine']['cpu']} "
             f"({r['machine']['logical_cpus']} logical CPUs); 1-minute load average before "
             "each scene and size: " + ", ".join(
                 f"{x['loadavg_before']:.1f}" for x in r["render"] + r["grad"]) +
             f"; after: {r['loadavg_after']:.1f}", ""]
    if r["render"]:
        lines += [f"Samples/s, {r['res']}x{r['res']}, {r['spp']} spp, best of {r['seeds']} seeds "
                  f"(Tandem wall = render passes + download; Mitsuba = warm mi.render, "
                  "evaluated and synchronised):", "",
                  f"| scene | Tandem M samples/s (wall) | Tandem (kernel) | Mitsuba {variant} "
                  "| Mitsuba scalar_rgb | Tandem ÷ llvm | Tandem ÷ scalar "
                  "| cores busy T / llvm / scalar |",
                  "|---|---|---|---|---|---|---|---|"]
        for row in r["render"]:
            scalar = row.get("scalar_msps")
            scalar_ratio = f"{row['tandem_msps'] / scalar:.2f}" if scalar else "-"
            lines.append(
                f"| {row['scene']} | {row['tandem_msps']:.2f} | {row['tandem_kernel_msps']:.2f} | "
                f"{row['llvm_msps']:.2f} | {f'{scalar:.2f}' if scalar else '-'} | "
                f"{row['tandem_msps'] / row['llvm_msps']:.2f} | "
                f"{scalar_ratio} | {row['tandem_cores']:.2f} / {row['llvm_cores']:.2f} / "
                f"{row.get('scalar_cores', float('nan')):.2f} |")
        lines += ["", f"Image difference, Tandem − Mitsuba {variant}, {r['seeds']} seeds each "
                      f"(R / G / B; z: in standard errors of the difference; tiles: "
                      f"{r['tile']}² blocks with |z| > 3, 0.27 % for pure noise):", "",
                  "| scene | mean rel. diff (%) | z | tiles beyond 3 | worst tile z (rel. diff) "
                  "| variance ratio T/M |", "|---|---|---|---|---|---|"]
        for row in r["render"]:
            im = row["image"]
            t = im["tile"]
            lines.append(
                f"| {row['scene']} | {fmt3([100 * v for v in im['rel_diff']], 2)} | "
                f"{fmt3(im['z'], 1)} | {100 * t['share_beyond_3']:.1f} % | "
                f"{t['worst_z']:+.1f} ({100 * t['worst_rel_diff']:+.1f} %, "
                f"{t['worst_at']['channel']} at row {t['worst_at']['row']}, col "
                f"{t['worst_at']['col']}) | "
                + " / ".join(f"{v:.2f}" for v in im["variance_ratio"]) + " |")
    if r["grad"]:
        g0 = r["grad"][0]
        lines += ["", f"Gradient step, {g0['param']} (Mitsuba {g0['mitsuba_param']}), "
                      f"{g0['loss'].upper()}, {g0['spp']} + {g0['spp_grad']} spp, Adam; best "
                      f"(and mean) of {r['grad_iterations']} steps after {r['grad_warmup']} "
                      "(Tandem: tandem optimize, cv none; Mitsuba: prb):", "",
                  "| size | Tandem s/step | Mitsuba prb s/step | Tandem ÷ Mitsuba "
                  "| cores busy T / M |",
                  "|---|---|---|---|---|"]
        for g in r["grad"]:
            t, m = best(g["tandem"], r["grad_warmup"]), best(g["mitsuba"], r["grad_warmup"])
            tm, mm = g["tandem"]["mean_seconds"], g["mitsuba"]["mean_seconds"]
            lines.append(f"| {g['size']}² | {t:.3f} ({tm:.3f}) | {m:.3f} ({mm:.3f}) | "
                         f"{t / m:.2f} ({tm / mm:.2f}) | "
                         f"{g['tandem']['cores']:.2f} / {g['mitsuba']['cores']:.2f} |")
    return "\n".join(lines) + "\n"


def write_csv(result, path):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["section", "key", "measure", "value"])
        for row in result["render"]:
            for k in ("tandem_msps", "tandem_kernel_msps", "llvm_msps", "scalar_msps"):
                if k in row:
                    w.writerow(["render", row["scene"], k, row[k]])
            for k in ("rel_diff", "z", "variance_ratio"):
                for c, v in zip("rgb", row["image"][k]):
                    w.writerow(["image", row["scene"], f"{k}_{c}", v])
            w.writerow(["image", row["scene"], "tiles_beyond_3",
                        row["image"]["tile"]["share_beyond_3"]])
        for g in result["grad"]:
            for who in ("tandem", "mitsuba"):
                w.writerow(["grad", g["size"], f"{who}_best_seconds",
                            best(g[who], result["grad_warmup"])])
                w.writerow(["grad", g["size"], f"{who}_mean_seconds", g[who]["mean_seconds"]])


def plot(result, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit(f"peer_mitsuba: --plot needs matplotlib, which {sys.executable} lacks "
                 "(try /usr/bin/python3)")
    panels = [p for p in ("render", "grad") if result[p]]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 3.6), squeeze=False)
    for ax, panel in zip(axes[0], panels):
        if panel == "render":
            rows = result["render"]
            series = [("Tandem", "tandem_msps"), ("Mitsuba llvm_ad_rgb", "llvm_msps"),
                      ("Mitsuba scalar_rgb", "scalar_msps")]
            series = [s for s in series if all(s[1] in row for row in rows)]
            width = 0.8 / len(series)
            for i, (label, key) in enumerate(series):
                ax.bar([j + i * width for j in range(len(rows))], [row[key] for row in rows],
                       width, label=label)
            ax.set_xticks([j + width * (len(series) - 1) / 2 for j in range(len(rows))])
            ax.set_xticklabels([row["scene"] for row in rows], fontsize=8)
            ax.set_ylabel("M samples/s")
            ax.set_title(f"render {result['res']}², {result['spp']} spp, "
                         f"{result['threads']} threads", fontsize=9)
        else:
            rows = result["grad"]
            for i, (label, key) in enumerate([("Tandem", "tandem"), ("Mitsuba prb", "mitsuba")]):
                ax.bar([j + i * 0.4 for j in range(len(rows))],
                       [best(g[key], result["grad_warmup"]) for g in rows], 0.4, label=label)
            ax.set_xticks([j + 0.2 for j in range(len(rows))])
            ax.set_xticklabels([f"{g['size']}²" for g in rows])
            ax.set_ylabel("seconds per gradient step (best)")
            ax.set_title(f"{rows[0]['param']}, {rows[0]['loss'].upper()}, {rows[0]['spp']} + "
                         f"{rows[0]['spp_grad']} spp, Adam", fontsize=9)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90, metadata={"Software": None})
