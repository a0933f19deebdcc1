#!/usr/bin/env python3
"""Several views: what a batch of B views costs per iteration, what the control variate keeps of
its strength when views are revisited after other steps, and what views cost a one-sensor scene.

1. Batches (scenes/globe-recover.json, eight 96x96 views of the painted globe): for each B of
   --batches, `tandem optimize` with "batch": B for --view-renders / B iterations (every run renders
   the same number of views, --view-renders), alternating the B over --rounds rounds. Reported per
   B: the seconds per iteration (metrics.csv's last "seconds" over the iterations; the median over
   rounds), that time over B times the time at B = 1 (1.0: exactly linear, no overhead per view
   beyond its render), the mean control weight alpha over the second half of the run, the
   effective spp of each view's control-variate image at the end, and the parameter RMSE. The
   effective spp of a view is the variance of a 1-spp render of the final parameters (per element,
   over --variance-renders seeds, averaged over the view's elements) over the variance the control
   variate estimates for its image (variance_NNNN.exr, eq. 10 of "Recursive Control Variates for
   Inverse Rendering"), averaged over the views.
2. One sensor (--baseline OTHER_TANDEM, a build of the commit before views): the README's main job
   (scenes/cbox-wall-recover.json) for --iterations iterations with both binaries, alternating
   over --rounds rounds; the ratio of the iterations' seconds, with its standard error.

    PYTHONPATH=build/python .venv/bin/python bench/views_bench.py [--tandem build/tandem]
        [--batches 1 2 4 8] [--view-renders 384] [--rounds 3] [--baseline OTHER] [--out FILE.md]

Needs numpy and the Python module (for the variance renders).
"""

import argparse
import csv
import json
import math
import pathlib
import statistics
import subprocess
import tempfile

import numpy as np

import tandem

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"


def run(tandem_bin, config, out, extra=()):
    subprocess.run([tandem_bin, "optimize", str(config), "--out", str(out), *extra], check=True,
                   capture_output=True, text=True)
    with open(out / "metrics.csv") as f:
        return list(csv.DictReader(f))


def batch_config(tmp, batch, iterations):
    c = json.loads((SCENES / "globe-recover.json").read_text())
    c["scene"] = str(SCENES / c["scene"])
    c["target"]["scene"] = str(SCENES / c["target"]["scene"])
    c["batch"] = batch
    c["iterations"] = iterations
    c["checkpoint_every"] = iterations
    path = tmp / f"batch{batch}.json"
    path.write_text(json.dumps(c))
    return path, c


def effective_spp(out, config, renders):
    """The mean over views of Var[1-spp image] / Var[C] (the CV's estimate), per view's elements."""
    scene = tandem.load(config["scene"], **{k: str(v) for k, v in config["defines"].items()})
    scene.params["globe.reflectance"] = tandem.read_image(str(out / "globe.reflectance.exr"))
    ratios = []
    for k in range(len(scene.sensors)):
        var_c = sorted((out / "views" / str(k)).glob("variance_*.exr"))[-1]
        imgs = np.stack([scene.render(spp=1, seed=1000 + s, sensor=k) for s in range(renders)])
        var1 = imgs.astype(np.float64).var(axis=0, ddof=1)
        vc = tandem.read_image(str(var_c)).astype(np.float64)
        ratios.append(float(var1.mean() / vc.mean()))
    return statistics.mean(ratios)


def batches(args, tmp):
    rows = {}
    for r in range(args.rounds):
        for b in args.batches:
            iterations = args.view_renders // b
            config, c = batch_config(tmp, b, iterations)
            out = tmp / f"b{b}-r{r}"
            m = run(args.tandem, config, out)
            half = m[len(m) // 2:]
            row = rows.setdefault(b, {"seconds": [], "iterations": iterations})
            row["seconds"].append(float(m[-1]["seconds"]) / iterations)
            row["alpha"] = statistics.mean(float(x["alpha_mean"]) for x in half)
            row["param_error"] = float(m[-1]["param_error"])
            if r == 0:
                row["effective_spp"] = effective_spp(out, c, args.variance_renders)
    t1 = statistics.median(rows[min(rows)]["seconds"]) / min(rows)
    lines = ["| views per batch | iterations | s / iteration | ÷ (B × s at B = 1) | mean α (2nd half) "
             "| effective spp of C | param RMSE |", "|---|---|---|---|---|---|---|"]
    for b, row in sorted(rows.items()):
        s = statistics.median(row["seconds"])
        lines.append(f"| {b} | {row['iterations']} | {s:.4f} | {s / (b * t1):.3f} | {row['alpha']:.3f} "
                     f"| {row['effective_spp']:.1f} | {row['param_error']:.4f} |")
    return "\n".join(lines)


def overhead(args, tmp):
    c = json.loads((SCENES / "cbox-wall-recover.json").read_text())
    c["scene"] = str(SCENES / c["scene"])
    c["target"]["scene"] = str(SCENES / c["target"]["scene"])
    c["iterations"] = args.iterations
    c["checkpoint_every"] = args.iterations
    config = tmp / "main.json"
    config.write_text(json.dumps(c))
    ratios = []
    for r in range(args.rounds):
        t = {}
        for name, binary in (("new", args.tandem), ("base", args.baseline)):
            m = run(binary, config, tmp / f"{name}-{r}")
            t[name] = float(m[-1]["seconds"])
        ratios.append(t["new"] / t["base"])
    mean = statistics.mean(ratios)
    se = statistics.stdev(ratios) / math.sqrt(len(ratios)) if len(ratios) > 1 else float("nan")
    return (f"One sensor (scenes/cbox-wall-recover.json, {args.iterations} iterations, {args.rounds} "
            f"alternating rounds): iteration time with views ÷ before = {mean:.4f} ± {se:.4f} "
            f"(rounds: {', '.join(f'{x:.4f}' for x in ratios)})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tandem", default=str(ROOT / "build" / "tandem"))
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--view-renders", type=int, default=384)
    ap.add_argument("--variance-renders", type=int, default=16)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--baseline", help="a tandem binary of the commit before views")
    ap.add_argument("--iterations", type=int, default=40, help="of the one-sensor comparison")
    ap.add_argument("--out", type=pathlib.Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        text = batches(args, tmp) if args.batches else ""
        if args.baseline:
            text += "\n\n" + overhead(args, tmp)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
