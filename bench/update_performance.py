#!/usr/bin/env python3
"""Writes a benchmark's current table into docs/performance.md.

    python3 bench/update_performance.py SECTION RESULT [--machine NAME] [--date YYYY-MM-DD]
                                        [--doc docs/performance.md] [--print]

SECTION names a table of docs/performance.md, the text between `<!-- table: SECTION -->` and
`<!-- end table -->`. RESULT is what the benchmark wrote:

    trace       build/tandem bench trace --json
    det-math-pocl  build/tandem bench render --scene S --json (one scene per file; its row is
                replaced, with its own machine and date, the other rows are kept)
    grad        build/tandem bench grad --json
    cv          build/tandem bench cv --json
    restir      build/tandem bench restir --json (one film size per file; the row for its size
                is replaced, with its own machine and date, the other rows are kept)
    soak        build/tandem bench soak --json
    refit       build/tandem bench refit --json
    python      bench/python_overhead.py --json FILE
    peer        bench/peer_mitsuba.py --json (its JSON output)
    restir-e2e  OUT_DIR/restir_optimize.json of bench/restir_optimize.py
    any other   a Markdown file, used as it is (cv_convergence.py's OUT_DIR/summary.md, ...)

--format KIND reads RESULT as one of the kinds above for a table of another name (gpu-grad
takes bench/gpu_check.sh's grad_*.json with --format grad).

The table is preceded by a line naming the machine and the date: --machine (default: the device
the result names; docs/performance.md's "Machines" table gives the short names) and --date
(default: today, UTC). --print prints the new block instead of writing the file. Standard library
only.
"""

import argparse
import datetime
import json
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def row(*cells):
    return "| " + " | ".join(str(c) for c in cells) + " |"


def header(*cells):
    return [row(*cells), "|" + "---|" * len(cells)]


def trace(r, old, stamp):
    lines = header("rays", f"{r['bvh']['layout'].replace('_pf', '')}", "+prefetch",
                   "Embree's best", "**ratio**")
    for name in ("coherent", "incoherent", "shadow"):
        s = r[name]
        plain = s.get(f"tandem_{r['bvh']['layout'].replace('_pf', '')}_mrays_s", s["tandem_mrays_s"])
        pf = s.get("tandem_bvh8_tri4_pf_mrays_s")
        lines.append(row(name, f"{plain:.2f}", f"{pf:.2f}" if pf else "-",
                         f"{s['embree_mrays_s']:.2f} (`{s['embree_mode']}`)",
                         f"**{s['ratio']:.3f}**"))
    lines += ["", f"{r['rays']} rays per set; `hit_mismatches` "
              f"{sum(r[n]['hit_mismatches'] for n in ('coherent', 'incoherent', 'shadow'))}, "
              f"`layout_mismatches` "
              f"{sum(r[n]['layout_mismatches'] for n in ('coherent', 'incoherent', 'shadow'))}."]
    return lines


def grad(r, old, stamp):
    lines = header("size", "iteration", "primal (device time)", "adjoint (device time)",
                   "adjoint ÷ primal")
    for x in r["rows"]:
        lines.append(row(f"{x['size']}²", f"{x['iteration_seconds']:.4f} s",
                         f"{x['primal_seconds']:.4f} s", f"{x['adjoint_seconds']:.4f} s",
                         f"{x['adjoint_over_primal']:.2f}"))
    return lines


def cv(r, old, stamp):
    lines = [f"`fused_cost_ratio` **{r['fused_cost_ratio']:.2f}**, `pss_cost_ratio` "
             f"{r['pss_cost_ratio']:.2f} ({r['cost_size']}², 1 spp); steady state at "
             f"{r['steady_size']}², {r['steady_runs']} runs:", ""]
    names = list(r["effective_spp"])
    lines += header("iterations", "ideal spp", *[f"`{n}` spp" for n in names],
                    "bias mean \\|z\\| (beyond 3): running mean", *[f"`{n}`" for n in names])

    def z(x):
        return f"{x['mean_abs']:.2f} ({100 * x['beyond_3']:.1f} %)"

    for it in sorted(r["effective_spp"][names[0]], key=int):
        lines.append(row(it, int(it) - 1, *[f"{r['effective_spp'][n][it]:.1f}" for n in names],
                         z(r["bias_z"]["running_mean"][it]), *[z(r["bias_z"][n][it]) for n in names]))
    return lines


def restir(r, old, stamp):
    """One row per film size, each with its own machine and date (the section keeps the other
    sizes' rows)."""
    res = r["res"]
    new = row(f"{res}²", r["seeds"], f"{r['relmse_vs_prb']:.3g} ± {r['relmse_vs_prb_se']:.2g}",
              f"{r['relmse_vs_ris']:.3g} ± {r['relmse_vs_ris_se']:.2g}", stamp)
    rows = [x for x in old if re.match(r"\| \d+²", x) and not x.startswith(f"| {res}²")]
    rows.append(new)
    rows.sort(key=lambda x: int(re.match(r"\| (\d+)", x).group(1)))
    return header("film", "seeds", "`relmse_vs_prb`", "`relmse_vs_ris`", "measured") + rows


def det_math(r, old, stamp):
    """One row per scene, each with its own machine and date."""
    scene = pathlib.Path(r["scene"]).stem
    d = r["det_math"]
    new = row(scene, f"{d['det_kernel_seconds']:.4f}", f"{d['builtin_kernel_seconds']:.4f}",
              f"{100 * d['cost']:+.1f} %", stamp)
    rows = [x for x in old if x.startswith("| ") and not x.startswith("| scene")]
    mine = [i for i, x in enumerate(rows) if x.startswith(f"| {scene} |")]
    if mine:
        rows[mine[0]] = new
    else:
        rows.append(new)
    return header("scene", "det_math s", "built-ins s", "det_math's cost", "measured") + rows


def soak(r, old, stamp):
    first, last = r["samples"][0], r["samples"][-1]
    lines = header("series", f"iteration {first['iteration']}", f"iteration {last['iteration']}",
                   "slope / iteration", "std. error", "over the run", "flat (3 s.e.)")
    for key, name in (("seconds_per_iteration", "time per iteration (s)"),
                      ("live_buffers", "live device buffers"),
                      ("live_buffer_bytes", "live device bytes"),
                      ("heap_bytes", "host heap in use (bytes)"),
                      ("rss_bytes", "resident memory (bytes)")):
        s = r["slopes"][key]
        lines.append(row(name, f"{first[key]:.4g}", f"{last[key]:.4g}",
                         f"{s['slope_per_iteration']:.3g}", f"{s['stderr']:.2g}",
                         f"{100 * s['drift_over_run']:+.2f} %", "yes" if s["flat"] else "no"))
    lines += ["", f"{r['iterations']} iterations, {r['res']}², {r['spp']} spp, ReSTIR "
              f"{r['restir']}, in {r['seconds']:.0f} s."]
    return lines


def refit(r, old, stamp):
    lines = header("triangles", "layout", "build (ms)", "refit (ms)", "**build / refit**",
                   "SAH, 1 step", f"SAH, {r['steps']} steps")
    for x in r["rows"]:
        lines.append(row(f"{x['triangles']:,}", x["layout"], f"{x['build_ms']:.3f}",
                         f"{x['refit_ms']:.3f}", f"**{x['build_ms'] / x['refit_ms']:.1f}**",
                         f"{x['sah_one']:.3f}", f"{x['sah_many']:.3f}"))
    lines += ["", f"Best of {r['repeats']}, alternating; Embree on {r['threads']} threads; each step "
              f"moves every vertex by {r['step']:.3g} of the extent. SAH: the refit tree's cost over a "
              f"new build's."]
    return lines


def python(r, old, stamp):
    lines = header("loop", "Python ms/iteration", "CLI ms/iteration", "overhead")
    for mode, label in (("none", "plain (cv none)"), ("ps", "recursive CV (cv ps)")):
        x = r[mode]
        lines.append(row(label, f"{1e3 * x['python_seconds_per_iteration']:.1f}",
                         f"{1e3 * x['cli_seconds_per_iteration']:.1f}",
                         f"{100 * x['overhead']:+.1f} %"))
    return lines


def peer(r, old, stamp):
    variant = r.get("variant", "llvm_ad_rgb")
    lines = []
    if r.get("render"):
        lines += header(f"scene, {r['res']}², {r['spp']} spp", "Tandem M samples/s",
                        f"Mitsuba `{variant}`", "**Tandem ÷ Mitsuba**")
        for x in r["render"]:
            lines.append(row(x["scene"], f"{x['tandem_msps']:.2f}", f"{x['llvm_msps']:.2f}",
                             f"**{x['tandem_msps'] / x['llvm_msps']:.2f}**"))
    if r.get("grad"):
        sys.path.insert(0, str(ROOT / "bench"))
        from peer_mitsuba_report import best
        warm = r["grad_warmup"]
        lines += ["", "Gradient step, best of the steps after the warm-up:", ""]
        lines += header("size", "Tandem s/step", "Mitsuba `prb` s/step", "Tandem ÷ Mitsuba")
        for g in r["grad"]:
            t, m = best(g["tandem"], warm), best(g["mitsuba"], warm)
            lines.append(row(f"{g['size']}²", f"{t:.4f}", f"{m:.4f}", f"{t / m:.2f}"))
    return lines


def restir_e2e(r, old, stamp):
    lines = header("arm", "seed", "baseline final", "baseline time", "time to it", "speed-up",
                   "final")
    for key, h in r["headline"].items():
        arm, _, seed = str(key).rpartition("/")
        t = h["restir_seconds_to_reach"]
        lines.append(row(arm or "prb+cv+restir", seed, f"{h['baseline_param_error']:.4f}",
                         f"{h['baseline_seconds']:.2f} s", f"{t:.2f} s" if t else "never",
                         f"**{h['speedup']:.2f}×**" if h["speedup"] else "-",
                         f"{h['restir_final_param_error']:.4f}"))
    return lines


PER_ROW = {"restir", "det-math-pocl"}  # tables whose rows carry their own machine and date
CONVERTERS = {"trace": trace, "det-math-pocl": det_math, "grad": grad, "cv": cv, "restir": restir, "soak": soak, "refit": refit,
              "python": python, "peer": peer, "restir-e2e": restir_e2e}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("section")
    ap.add_argument("result", type=pathlib.Path)
    ap.add_argument("--machine")
    ap.add_argument("--date", default=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d"))
    ap.add_argument("--doc", type=pathlib.Path, default=ROOT / "docs" / "performance.md")
    ap.add_argument("--print", action="store_true")
    ap.add_argument("--format", help="read RESULT as this section's kind (default: SECTION)")
    a = ap.parse_args()
    doc = a.doc.read_text()
    begin, end = f"<!-- table: {a.section} -->\n", "<!-- end table -->"
    if begin not in doc:
        sys.exit(f"{a.doc}: no table named {a.section}")
    start = doc.index(begin) + len(begin)
    stop = doc.index(end, start)
    old = doc[start:stop].splitlines()
    text = a.result.read_text()
    kind = a.format or a.section
    if kind in CONVERTERS:
        result = json.loads(text)
        device = result.get("device") or (result.get("machine") or {}).get("cpu")
        machine = a.machine or (f"Device `{device}`" if device else "Measured")
        body = CONVERTERS[kind](result, old, f"{machine}, {a.date}")
    else:
        machine = a.machine or "Measured"
        body = text.strip().splitlines()
    caption = [] if kind in PER_ROW else [f"{machine}, {a.date}:", ""]
    block = "\n".join(caption + body) + "\n"
    if a.print:
        print(block, end="")
        return
    a.doc.write_text(doc[:start] + block + doc[stop:])
    print(f"{a.doc}: table {a.section} rewritten")


if __name__ == "__main__":
    main()
