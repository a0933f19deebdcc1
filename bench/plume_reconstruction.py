#!/usr/bin/env python3
"""The plume reconstruction of scenes/media-plume-recover.json (a 32^3 density grid from a flat
start, 8 views, a resolution schedule), the control variate against plain path replay at more
samples: CV-PS at s spp against plain PRB at s, 4 s and 8 s spp ("Recursive Control Variates for
Inverse Rendering", section 6: plain needs 4-8x the samples for the same quality). Each setting
runs the job for each seed, the settings alternating within a seed; the table gives each
setting's final parameter RMSE (the grid against the true one) and image RMSE (every view at
image_error_spp), and its optimization seconds (metrics.csv's `seconds`: the iterations proper).

    bench/plume_reconstruction.py [--tandem build/tandem] [--spp 4] [--iterations 400]
                                  [--seeds 0,1] [--res 96] [--out DIR] [--json]
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def run(tandem, job, out, cv, spp, iterations, seed, res):
    """Runs the job with these settings into `out`; returns its last metrics row."""
    scene = os.path.join(ROOT, "scenes", job["scene"])
    c = dict(job, scene=scene, cv=cv, spp=spp, spp_grad=spp, iterations=iterations, seed=seed,
             defines={"res": res}, checkpoint_every=iterations)
    c["target"] = dict(job["target"], scene=scene, defines={"res": res})
    p = c["params"]["plume.sigma_t"] = dict(job["params"]["plume.sigma_t"])
    # the schedule at the same fractions of the run as the job's
    p["upsample"] = [max(1, round(i * iterations / job["iterations"])) for i in p["upsample"]]
    config = out + ".json"
    with open(config, "w") as f:
        json.dump(c, f)
    r = subprocess.run([tandem, "optimize", config, "--out", out], capture_output=True, text=True)
    if r.returncode:
        sys.exit(f"tandem optimize failed ({cv}, {spp} spp, seed {seed}):\n{r.stderr}")
    with open(os.path.join(out, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    return rows[-1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tandem", default=os.path.join(ROOT, "build", "tandem"))
    ap.add_argument("--spp", type=int, default=4, help="s: CV-PS's samples per pixel")
    ap.add_argument("--iterations", type=int, default=400)
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--out", help="keep the runs' folders here (default: a temporary folder)")
    ap.add_argument("--json", action="store_true", help="print the table as JSON")
    a = ap.parse_args()
    with open(os.path.join(ROOT, "scenes", "media-plume-recover.json")) as f:
        job = json.load(f)
    settings = [("ps", a.spp), ("none", a.spp), ("none", 4 * a.spp), ("none", 8 * a.spp)]
    results = {s: [] for s in settings}
    with tempfile.TemporaryDirectory() as tmp:
        base = a.out or tmp
        os.makedirs(base, exist_ok=True)
        for seed in (int(s) for s in a.seeds.split(",")):
            for cv, spp in settings:
                out = os.path.join(base, f"{cv}-{spp}spp-seed{seed}")
                row = run(a.tandem, job, out, cv, spp, a.iterations, seed, a.res)
                results[(cv, spp)].append({k: float(row[k]) for k in
                                           ("seconds", "param_error", "image_error")})
                print(f"{cv} {spp} spp seed {seed}: {results[(cv, spp)][-1]}", file=sys.stderr)
    table = []
    for (cv, spp), runs in results.items():
        mean = {k: sum(r[k] for r in runs) / len(runs) for k in runs[0]}
        table.append(dict(cv=cv, spp=spp, runs=len(runs), **mean))
    if a.json:
        print(json.dumps(table, indent=1))
        return
    print(f"plume reconstruction, {a.iterations} iterations at {a.res}^2, seeds {a.seeds}")
    print("| estimator | spp | seconds | final parameter RMSE | final image RMSE |")
    print("|---|---|---|---|---|")
    for t in table:
        name = "CV-PS" if t["cv"] == "ps" else "plain PRB"
        print(f"| {name} | {t['spp']} | {t['seconds']:.1f} | {t['param_error']:.4f} | "
              f"{t['image_error']:.4f} |")


if __name__ == "__main__":
    main()
