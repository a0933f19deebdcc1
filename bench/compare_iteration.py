#!/usr/bin/env python3
"""Time per optimization iteration of two builds of Tandem, side by side in one run.

    bench/compare_iteration.py BEFORE/tandem AFTER/tandem [--rounds R] [--sizes 64,128]

For each round, in alternating order (so that machine noise hits both alike), runs
  1. `tandem bench grad --sizes S --iterations 20 --json` (one gradient evaluation and Adam step
     per iteration: the time per iteration and its host-side remainder, "other"), and
  2. `tandem optimize` of the bundled texture recovery (scenes/cbox-wall-recover.json: CV-PS,
     L2, Adam) at 128x128, for 10 and for 40 iterations: the difference of the two wall times
     over 30 is the whole cost of an iteration, its metrics (loss, parameter error, mean alpha)
     and their read-back included, without the set-up and the final outputs. (The metrics'
     `seconds` column is not comparable across the two builds: before, it left out the
     per-iteration downloads of the metrics; now the metrics arrive with the iteration's one
     wait.)
Prints the median over rounds of each, for both builds, and their ratio (after / before).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def bench_grad(tandem, sizes):
    out = subprocess.run([tandem, "bench", "grad", "--sizes", sizes, "--iterations", "20", "--json"],
                         check=True, capture_output=True, text=True).stdout
    return {r["size"]: r for r in json.loads(out)["rows"]}


def optimize_wall(tandem, iterations):
    """Wall seconds of `tandem optimize` of the texture recovery for `iterations` iterations."""
    with tempfile.TemporaryDirectory() as tmp:
        config = json.load(open(os.path.join(ROOT, "scenes", "cbox-wall-recover.json")))
        for key in ("scene",):
            config[key] = os.path.join(ROOT, "scenes", config[key])
        config["target"]["scene"] = os.path.join(ROOT, "scenes", config["target"]["scene"])
        config["iterations"] = iterations
        config["checkpoint_every"] = iterations
        path = os.path.join(tmp, "config.json")
        json.dump(config, open(path, "w"))
        t0 = time.perf_counter()
        subprocess.run([tandem, "optimize", path, "--out", os.path.join(tmp, "out")], check=True,
                       capture_output=True)
        return time.perf_counter() - t0


def optimize_seconds(tandem, iterations):
    """Seconds per optimization iteration, everything in the loop included."""
    return (optimize_wall(tandem, iterations + 10) - optimize_wall(tandem, 10)) / iterations


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--sizes", default="64,128")
    ap.add_argument("--iterations", type=int, default=30)
    a = ap.parse_args()
    builds = {"before": a.before, "after": a.after}
    grad = {k: [] for k in builds}
    opt = {k: [] for k in builds}
    for r in range(a.rounds):
        order = ["before", "after"] if r % 2 == 0 else ["after", "before"]
        for k in order:
            grad[k].append(bench_grad(builds[k], a.sizes))
            opt[k].append(optimize_seconds(builds[k], a.iterations))
            print(f"round {r + 1}/{a.rounds}: {k} done", file=sys.stderr)
    sizes = [int(s) for s in a.sizes.split(",")]
    print("| measure | before (s) | after (s) | after / before |")
    print("|---|---|---|---|")
    for s in sizes:
        for field, label in (("iteration_seconds", "iteration"), ("other_seconds", "other")):
            b = statistics.median(run[s][field] for run in grad["before"])
            f = statistics.median(run[s][field] for run in grad["after"])
            print(f"| bench grad {s}², {label} | {b:.4f} | {f:.4f} | {f / b:.3f} |")
    b, f = statistics.median(opt["before"]), statistics.median(opt["after"])
    print(f"| optimize 128², CV-PS, per iteration (wall, metrics included) | {b:.4f} | {f:.4f} | {f / b:.3f} |")


if __name__ == "__main__":
    main()
