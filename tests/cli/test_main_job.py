#!/usr/bin/env python3
"""The README's main job, shortened, does what it is for: the parameter error and the image error
in its metrics.csv fall.

    python3 tests/cli/test_main_job.py TANDEM_BINARY CONFIG

CONFIG is scenes/cbox-wall-recover.json, run as it is but at 64² (its scene and its target),
for ITERATIONS iterations, with the image error measured after every one (checkpoint_every 1)
instead of every 20: about 20 s on 2 cores. Each series must fall from its first to its last
value by more than 4 s sqrt(n - 1), where s is the sample standard deviation of its n - 1
iteration-to-iteration changes about their mean: what a series with no trend, only steps of that
spread, would wander in n - 1 steps, four times over (one-sided, 3e-5). s also counts the trend's
own changes of pace, so it overstates the noise, and the margin errs toward failing. Measured on
PoCL: param_error 0.2641 -> 0.2163 (fell 0.048, margin 0.0094), image_error 0.03977 -> 0.03569
(fell 0.0041, margin 0.0014). Standard library only.
"""

import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

ITERATIONS = 30
RES = 64


def falls_beyond_noise(series):
    """(fall, margin) of a series: first minus last value, and 4 s sqrt(n - 1) (see above)."""
    steps = [b - a for a, b in zip(series, series[1:])]
    return series[0] - series[-1], 4.0 * statistics.stdev(steps) * math.sqrt(len(steps))


def main(binary, config_path):
    with open(config_path) as f:
        config = json.load(f)
    folder = os.path.dirname(os.path.abspath(config_path))
    config["scene"] = os.path.join(folder, config["scene"])
    config["target"]["scene"] = os.path.join(folder, config["target"]["scene"])
    config["defines"]["res"] = config["target"]["defines"]["res"] = RES
    config["iterations"] = ITERATIONS
    config["checkpoint_every"] = 1
    with tempfile.TemporaryDirectory() as tmp:
        short = os.path.join(tmp, "config.json")
        with open(short, "w") as f:
            json.dump(config, f)
        out = os.path.join(tmp, "out")
        run = subprocess.run([binary, "optimize", short, "--out", out], capture_output=True,
                             text=True, timeout=600)
        if run.returncode != 0:
            print(run.stdout + run.stderr)
            print(f"FAIL: tandem optimize exited {run.returncode}")
            return 1
        with open(os.path.join(out, "metrics.csv")) as f:
            rows = list(csv.DictReader(f))
    failures = []
    if [int(r["iteration"]) for r in rows] != list(range(1, ITERATIONS + 1)):
        failures.append(f"metrics.csv has iterations {[r['iteration'] for r in rows]}")
    for key in ("param_error", "image_error"):
        if any(r[key] == "" for r in rows):
            failures.append(f"{key} is missing at some iteration")
            continue
        series = [float(r[key]) for r in rows]
        fall, margin = falls_beyond_noise(series)
        print(f"{key}: {series[0]:.5f} -> {series[-1]:.5f}, fell {fall:.5f}, margin {margin:.5f}")
        if not fall > margin:
            failures.append(f"{key} fell by {fall:.5f}, not more than its noise margin "
                            f"{margin:.5f}: {series}")
    for f in failures:
        print("FAIL: " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
