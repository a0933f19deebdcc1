#!/usr/bin/env python3
"""The cost of checkpoints against the iterations they protect, on the README's main job
(scenes/cbox-wall-recover.json: a 256x256 texture with Adam's moments and the control variate's
state, so a 5 MB checkpoint).

For each K of --every, one `tandem optimize --json` with a checkpoint every K iterations: the wall
time of the iterations themselves (metrics.csv's last "seconds"), the checkpoints written and
their wall time (checkpoint_seconds: the state's download, the checksums of every section, the
write, its flush to the disk and the renames that keep the previous one), and their share of the
iterations' time.

With --baseline OTHER_TANDEM (a build of another commit, e.g. one before the checksums), rounds of
both binaries alternate at a checkpoint every iteration, and the time outside the iterations
(the run's wall time less its iterations': start-up, the target, the re-renders and images, the
checkpoints) is compared per iteration: mean difference and its standard error over the rounds.

    python3 bench/checkpoint_cost.py [--tandem build/tandem] [--iterations 40] [--every 20 1]
                                     [--res 128] [--baseline OTHER [--baseline-name NAME]
                                     --rounds 5] [--out FILE.md]

Prints Markdown (and writes it to --out, for bench/update_performance.py checkpoint FILE).
Standard library only.
"""

import argparse
import csv
import json
import math
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def config_file(work, every, iterations, res):
    config = json.loads((ROOT / "scenes" / "cbox-wall-recover.json").read_text())
    scene = str(ROOT / "scenes" / config["scene"])
    config.update(scene=scene, iterations=iterations, checkpoint_every=every,
                  image_error_spp=1, defines={"res": res})
    config["target"].update(scene=scene, defines={"res": res})
    path = work / f"config-{every}.json"
    path.write_text(json.dumps(config))
    return path


def run(tandem, config, out):
    """(summary or None, wall seconds, the iterations' seconds) of one run."""
    t0 = time.monotonic()
    r = subprocess.run([tandem, "optimize", str(config), "--out", str(out), "--json"],
                       capture_output=True, text=True)
    wall = time.monotonic() - t0
    if r.returncode != 0:
        sys.exit(f"{tandem} optimize failed: {r.stderr.strip()}")
    with open(out / "metrics.csv") as f:
        iterations_seconds = float(list(csv.DictReader(f))[-1]["seconds"])
    try:
        summary = json.loads(r.stdout)
    except json.JSONDecodeError:
        summary = None
    return summary, wall, iterations_seconds


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tandem", default=str(ROOT / "build" / "tandem"))
    ap.add_argument("--iterations", type=int, default=40)
    ap.add_argument("--every", type=int, nargs="+", default=[20, 1])
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--baseline")
    ap.add_argument("--baseline-name", help="how the table names the baseline (default: its path)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out")
    a = ap.parse_args()
    lines = ["| checkpoint every | iterations | ms per iteration | checkpoints | MB each | "
             "ms per checkpoint | share of the iterations' time |",
             "|---|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory(prefix="tandem-checkpoint-cost-") as tmp:
        work = pathlib.Path(tmp)
        for k in a.every:
            out = work / f"out-{k}"
            s, _, it = run(a.tandem, config_file(work, k, a.iterations, a.res), out)
            n = s["iterations"]
            lines.append(f"| {k} | {n} | {1e3 * it / n:.1f} | {s['checkpoints']} | "
                         f"{(out / 'checkpoint.bin').stat().st_size / 1e6:.2f} | "
                         f"{1e3 * s['checkpoint_seconds'] / s['checkpoints']:.1f} | "
                         f"{100 * s['checkpoint_seconds'] / it:.2f} % |")
        if a.baseline:
            config = config_file(work, 1, a.iterations, a.res)
            outside = {"this": [], "baseline": []}
            for _ in range(a.rounds):
                for side, tandem in (("this", a.tandem), ("baseline", a.baseline)):
                    _, wall, it = run(tandem, config, work / f"ab-{side}")
                    outside[side].append(1e3 * (wall - it) / a.iterations)
            d = [x - y for x, y in zip(outside["this"], outside["baseline"])]
            mean = sum(d) / len(d)
            se = math.sqrt(sum((x - mean) ** 2 for x in d) / (len(d) - 1) / len(d))
            lines += ["", f"Against {a.baseline_name or a.baseline}, a checkpoint every iteration, {a.rounds} "
                      "alternating rounds: time outside the iterations per iteration "
                      f"{sum(outside['this']) / a.rounds:.1f} ms against "
                      f"{sum(outside['baseline']) / a.rounds:.1f} ms, difference "
                      f"{mean:+.1f} ± {se:.1f} ms (standard error)."]
    table = "\n".join(lines) + "\n"
    print(table, end="")
    if a.out:
        pathlib.Path(a.out).write_text(table)


if __name__ == "__main__":
    main()
