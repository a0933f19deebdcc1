#!/usr/bin/env python3
"""The cost of checkpoints against the iterations they protect: the README's main job
(scenes/cbox-wall-recover.json: a 256x256 texture, so a 3.2 MB checkpoint) run with a checkpoint
every K iterations, for each K given. From the summary of `tandem optimize --json`: the wall time
of the iterations themselves (metrics.csv's last "seconds"), the checkpoints written and their
wall time (checkpoint_seconds: the state's download, the checksums of every section, the write,
its flush to the disk and the renames that keep the previous one), and their share of the
iterations' time.

    python3 bench/checkpoint_cost.py [--tandem build/tandem] [--iterations 40] [--every 20 1]
                                     [--res 128] [--out FILE.md]

Prints a Markdown table (and writes it to --out, for bench/update_performance.py checkpoint FILE).
Standard library only.
"""

import argparse
import csv
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]


def run(tandem, work, every, iterations, res):
    config = json.loads((ROOT / "scenes" / "cbox-wall-recover.json").read_text())
    scene = str(ROOT / "scenes" / config["scene"])
    config.update(scene=scene, iterations=iterations, checkpoint_every=every,
                  image_error_spp=1, defines={"res": res})
    config["target"].update(scene=scene, defines={"res": res})
    path = work / f"config-{every}.json"
    path.write_text(json.dumps(config))
    out = work / f"out-{every}"
    r = subprocess.run([tandem, "optimize", str(path), "--out", str(out), "--json"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"tandem optimize failed: {r.stderr.strip()}")
    summary = json.loads(r.stdout)
    with open(out / "metrics.csv") as f:
        iterations_seconds = float(list(csv.DictReader(f))[-1]["seconds"])
    return {"every": every, "iterations": summary["iterations"],
            "iteration_ms": 1e3 * iterations_seconds / summary["iterations"],
            "checkpoints": summary["checkpoints"],
            "checkpoint_ms": 1e3 * summary["checkpoint_seconds"] / summary["checkpoints"],
            "bytes": (out / "checkpoint.bin").stat().st_size,
            "share": summary["checkpoint_seconds"] / iterations_seconds}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tandem", default=str(ROOT / "build" / "tandem"))
    ap.add_argument("--iterations", type=int, default=40)
    ap.add_argument("--every", type=int, nargs="+", default=[20, 1])
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--out")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="tandem-checkpoint-cost-") as work:
        rows = [run(a.tandem, pathlib.Path(work), k, a.iterations, a.res) for k in a.every]
    lines = ["| checkpoint every | iterations | ms per iteration | checkpoints | MB each | "
             "ms per checkpoint | share of the iterations' time |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['every']} | {r['iterations']} | {r['iteration_ms']:.1f} | "
                     f"{r['checkpoints']} | {r['bytes'] / 1e6:.2f} | {r['checkpoint_ms']:.1f} | "
                     f"{100 * r['share']:.2f} % |")
    table = "\n".join(lines) + "\n"
    print(table, end="")
    if a.out:
        pathlib.Path(a.out).write_text(table)


if __name__ == "__main__":
    main()
