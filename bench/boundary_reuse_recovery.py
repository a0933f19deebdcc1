#!/usr/bin/env python3
"""End to end: a multi-view shape recovery with and without the boundary term's reuse, at equal
time, several seeds.

    PYTHONPATH=build/python .venv/bin/python bench/boundary_reuse_recovery.py BUILD_DIR OUT_DIR
        [--config FILE] [--seeds 0 1 2] [--iterations N] [--plain-secondary N] [--samples N]

Runs the config (default scenes/shadow-lights-recover.json: the blob from a sphere, four 64²
views of it and its shadows under twelve small lights, Adam on Large Steps, L1, CV-PSS, 4 + 4
spp, "restir": {"adjoint": false, "boundary": true}) once per seed with "boundary" set to
--reuse (JSON; default true: the defaults) and once with "boundary": false and
--plain-secondary secondary edge samples per pixel (default 28, which costs about what the reuse
costs per iteration on a 2-core Xeon: choose it so that the two runs' seconds per iteration match
on your machine; the table shows both). Each checkpoint's mesh is measured against the true blob
with tandem.surface_distance (Chamfer: the mean of the two one-sided mean distances, over
--samples points of each surface), and the two runs' Chamfer distances are read at the same wall
time, the end of the shorter run (log-linear between checkpoints). Near the end the distance
wanders from checkpoint to checkpoint, so the ratio's geometric mean over the second half of
that time is given too. Prints both per seed and their geometric means over the seeds; writes
OUT_DIR/boundary_reuse_recovery.json (every checkpoint of every run).
"""
import argparse
import bisect
import csv
import json
import math
import pathlib
import subprocess
import sys

import tandem

ROOT = pathlib.Path(__file__).resolve().parents[1]
PARAM = "blob.vertex_positions"


def run(tandem_bin, config, out):
    r = subprocess.run([str(tandem_bin), "optimize", str(config), "--out", str(out)],
                       capture_output=True, text=True)
    if r.returncode:
        sys.exit(f"tandem optimize {config} failed:\n{r.stderr}")


def chamfer_curve(out, start_mesh, truth, samples):
    """(seconds, Chamfer) at iteration 0 and at each checkpoint of the run in `out`."""
    seconds = {int(r["iteration"]): float(r["seconds"])
               for r in csv.DictReader(open(out / "metrics.csv"))}
    rows = [(0.0, tandem.surface_distance(str(start_mesh), truth, samples)[0])]
    for path in sorted((out / "meshes").glob(f"{PARAM}_iter_*.ply")):
        it = int(path.stem.rsplit("_", 1)[1])
        rows.append((seconds[it], tandem.surface_distance(str(path), truth, samples)[0]))
    return rows


def at_time(curve, t):
    """The curve's Chamfer at time t (log-linear between its points; t within them)."""
    times = [s for s, _ in curve]
    k = min(max(bisect.bisect_left(times, t), 1), len(curve) - 1)
    (t0, c0), (t1, c1) = curve[k - 1], curve[k]
    f = 0.0 if t1 == t0 else min(max((t - t0) / (t1 - t0), 0.0), 1.0)
    return math.exp(math.log(c0) + f * (math.log(c1) - math.log(c0)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build", type=pathlib.Path)
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--config", type=pathlib.Path, default=ROOT / "scenes" / "shadow-lights-recover.json")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--iterations", type=int, default=0, help="0: the config's")
    ap.add_argument("--plain-secondary", type=int, default=28)
    ap.add_argument("--samples", type=int, default=100000)
    ap.add_argument("--reuse", default="true",
                    help='restir.boundary of the reuse runs, as JSON (e.g. \'{"neighbours": 0}\')')
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    base = json.load(open(args.config))
    scenes = args.config.resolve().parent
    base["scene"] = str(scenes / base["scene"])
    base["target"]["scene"] = str(scenes / base["target"]["scene"])
    if args.iterations:
        base["iterations"] = args.iterations
    defines = base["target"].get("defines", {})
    truth = str(scenes / defines.get("mesh", "blob.obj"))
    start_mesh = scenes / "blob-sphere.obj"

    report = {"config": str(args.config), "plain_secondary": args.plain_secondary,
              "reuse": json.loads(args.reuse), "runs": []}
    ratios, late_ratios = [], []
    print("seed  s/it reuse  s/it plain  t_equal  Chamfer reuse  Chamfer plain  plain/reuse  late half")
    for seed in args.seeds:
        curves = {}
        for name in ("reuse", "plain"):
            c = json.loads(json.dumps(base))
            c["seed"] = seed
            if name == "reuse":
                c["restir"] = dict(c.get("restir", {}), boundary=json.loads(args.reuse))
            if name == "plain":
                c["restir"] = dict(c.get("restir", {}), boundary=False)
                c["spp_secondary"] = args.plain_secondary
            path = args.out / f"{name}-{seed}.json"
            path.write_text(json.dumps(c))
            run(args.build / "tandem", path, args.out / f"{name}-{seed}")
            curves[name] = chamfer_curve(args.out / f"{name}-{seed}", start_mesh, truth, args.samples)
        t = min(curves["reuse"][-1][0], curves["plain"][-1][0])
        reuse, plain = at_time(curves["reuse"], t), at_time(curves["plain"], t)
        # the Chamfer distance wanders from checkpoint to checkpoint once near the end: the
        # geometric mean over the second half of the time as well
        late = [t * k / 10 for k in range(5, 11)]
        late_ratio = math.exp(sum(math.log(at_time(curves["plain"], u) / at_time(curves["reuse"], u))
                                  for u in late) / len(late))
        late_ratios.append(late_ratio)
        per_it = {n: curves[n][-1][0] / base["iterations"] for n in curves}
        ratios.append(plain / reuse)
        print(f"{seed:4d} {per_it['reuse']:11.3f} {per_it['plain']:11.3f} {t:8.1f} "
              f"{reuse:14.5f} {plain:14.5f} {plain / reuse:12.3f} {late_ratio:11.3f}")
        report["runs"].append({"seed": seed, "t_equal": t, "chamfer_reuse": reuse,
                               "chamfer_plain": plain, "late_ratio": late_ratio, "curves": curves})
    geo = math.exp(sum(math.log(r) for r in ratios) / len(ratios))
    late = math.exp(sum(math.log(r) for r in late_ratios) / len(late_ratios))
    report["plain_over_reuse_geomean"] = geo
    report["plain_over_reuse_late_geomean"] = late
    print(f"plain / reuse Chamfer at equal time, geometric mean over {len(ratios)} seeds: {geo:.3f} "
          f"at the end, {late:.3f} over the second half of the time")
    (args.out / "boundary_reuse_recovery.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
