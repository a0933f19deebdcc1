#!/usr/bin/env python3
"""End to end: `tandem optimize` with and without ReSTIR in the adjoint, several seeds.

    .venv/bin/python bench/restir_optimize.py BUILD_DIR OUT_DIR [--config FILE] [--seeds 0 1 2]
                                              [--iterations N] [--lr LR] [--spp N] [--controls]
                                              [--primal [--primal-spp N] [--primal-lr LR]]

Runs the config (default scenes/gallery-lights-recover.json: PRB + CV-PS, Adam, L2, 128², 4 + 4
spp) once per seed with its own "restir" removed and once with the default reservoirs
({"restir": {}}), everything else equal. Each run's metrics.csv gives the parameter RMSE (every
iteration) and the RMSE of a re-render (every K iterations) against wall time of the iterations
(burn-in included for ReSTIR). Writes OUT_DIR/restir_optimize.png (both errors against time,
per seed, and the parameter error against iterations), OUT_DIR/restir_optimize.json (every row)
and prints the headline: for each seed, the time ReSTIR needs to reach the final parameter error
of the run without it, over that run's time (and the time from which it stays below to the end:
a run that crosses the baseline's final error and comes back above does not count until it
stays).

--lr sets the learning rate of every optimized parameter, --spp the primal's samples per pixel
(the config's otherwise).

--primal adds two runs per seed without a control variate: plain PRB, and ReSTIR in both the
primal image and the adjoint (independent chains, "restir": {"primal": true}); the headline then
also gives the time the latter needs to reach the baseline's (PRB + CV's) final error.
--primal-spp and --primal-lr give the two-chain run its own samples per pixel (primal and
adjoint alike) and learning rate, and add PRB + CV at the same as a control: does the baseline
gain as much from them?

--controls adds two runs per seed without ReSTIR that locate the noise that limits the final
error, compared per iteration (their time is not the point): "adjoint x16" takes 16 times the
config's adjoint samples (spp_grad), a stand-in for any adjoint estimator far quieter than ReSTIR;
"primal x16" 16 times its primal samples (spp), so a quieter δ. Where the first follows ReSTIR's
curve and the second ends far lower, the error is the primal's, and no estimator of the adjoint
can reach the baseline's final error much sooner.

Needs matplotlib (plotting only; the runs are the C++ `tandem`).
"""
import argparse
import csv
import json
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def run(tandem, config, out):
    subprocess.run([tandem, "optimize", config, "--out", out], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "metrics.csv")) as f:
        return [{k: (float(v) if v else None) for k, v in row.items()} for row in csv.DictReader(f)]


def time_to_reach(rows, error):
    for r in rows:
        if r["param_error"] is not None and r["param_error"] <= error:
            return r["seconds"]
    return None


def time_to_stay(rows, error):
    """The time from which the error stays at or below `error` to the end: a run that crosses it
    and comes back above does not count until its last crossing."""
    t = None
    for r in rows:
        if r["param_error"] is None:
            continue
        if r["param_error"] <= error:
            t = r["seconds"] if t is None else t
        else:
            t = None
    return t


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("build")
    ap.add_argument("out")
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--config", default=os.path.join(here, "..", "scenes", "gallery-lights-recover.json"))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--iterations", type=int, default=0, help="override the config's (0: keep)")
    ap.add_argument("--lr", type=float, default=0.0, help="every parameter's learning rate (0: keep)")
    ap.add_argument("--spp", type=int, default=0, help="the primal's samples per pixel (0: keep)")
    ap.add_argument("--controls", action="store_true",
                    help="also run PRB + CV with 16x the adjoint's samples and with 16x the primal's")
    ap.add_argument("--primal", action="store_true",
                    help="also run without a control variate: plain PRB, and ReSTIR in the primal "
                         "and the adjoint (independent chains)")
    ap.add_argument("--primal-spp", type=int, default=0,
                    help="with --primal: the two-chain run's primal and adjoint samples per pixel, "
                         "and a PRB + CV run at the same (0: the config's)")
    ap.add_argument("--primal-lr", type=float, default=0.0,
                    help="with --primal: the two-chain run's learning rate, and that of the PRB + "
                         "CV run of --primal-spp (0: as the others)")
    a = ap.parse_args()
    tandem = os.path.join(a.build, "tandem")
    os.makedirs(a.out, exist_ok=True)
    with open(a.config) as f:
        base = json.load(f)
    cfg_dir = os.path.dirname(os.path.abspath(a.config))
    for key in ("scene",):
        base[key] = os.path.join(cfg_dir, base[key])
    if "scene" in base.get("target", {}):
        base["target"]["scene"] = os.path.join(cfg_dir, base["target"]["scene"])
    if a.iterations:
        base["iterations"] = a.iterations
    if a.lr:
        for p in base["params"].values():
            p["lr"] = a.lr
    spp_grad = base.get("spp_grad", base.get("spp", 4))  # before --spp: it sets the primal's only
    if a.spp:
        base["spp"] = a.spp
    base["spp_grad"] = spp_grad
    spp = base.get("spp", 4)
    # name: (restir, overrides)
    arms = {"prb+cv": (None, {}), "prb+cv+restir": ({}, {})}
    if a.controls:
        arms["adjoint x16"] = (None, {"spp_grad": 16 * spp_grad})
        arms["primal x16"] = (None, {"spp": 16 * spp, "spp_grad": spp_grad})
    if a.primal:
        arms["prb"] = (None, {"cv": "none"})
        own = {}
        if a.primal_spp:
            own.update({"spp": a.primal_spp, "spp_grad": a.primal_spp})
        if a.primal_lr:
            own["lr"] = a.primal_lr
        arms["prb+restir primal+adjoint"] = ({"primal": True}, dict(own, cv="none"))
        if own:
            arms["prb+cv (the same spp and lr)"] = (None, own)
    results = {}
    for seed in a.seeds:
        for name, (restir, overrides) in arms.items():
            c = json.loads(json.dumps(base))
            c.pop("restir", None)
            c["seed"] = seed
            overrides = dict(overrides)
            lr = overrides.pop("lr", None)
            if lr:
                for p in c["params"].values():
                    p["lr"] = lr
            c.update(overrides)
            if restir is not None:
                c["restir"] = restir
            path = os.path.join(a.out, f"{name.replace(' ', '_')}-{seed}.json")
            with open(path, "w") as f:
                json.dump(c, f, indent=2)
            rows = run(tandem, path, os.path.join(a.out, f"{name.replace(' ', '_')}-{seed}"))
            results[f"{name}/{seed}"] = rows
            last = rows[-1]
            print(f"{name:15s} seed {seed}: {last['seconds']:.1f} s, param_error {last['param_error']:.5f}, "
                  f"image_error {last['image_error']:.5f}", flush=True)
    headline = {}
    restir_arms = [n for n in arms if "restir" in n]
    for seed in a.seeds:
        base_rows = results[f"prb+cv/{seed}"]
        target = base_rows[-1]["param_error"]
        for name in restir_arms:
            re_rows = results[f"{name}/{seed}"]
            t = time_to_reach(re_rows, target)
            t_stay = time_to_stay(re_rows, target)
            # the default arm keeps its key of earlier JSON files: the seed alone
            key = seed if name == "prb+cv+restir" else f"{name}/{seed}"
            headline[key] = {"baseline_seconds": base_rows[-1]["seconds"],
                             "baseline_param_error": target,
                             "restir_seconds_to_reach": t,
                             "speedup": (base_rows[-1]["seconds"] / t) if t else None,
                             "restir_seconds_to_stay": t_stay,
                             "speedup_stay": (base_rows[-1]["seconds"] / t_stay) if t_stay else None,
                             "restir_final_param_error": re_rows[-1]["param_error"],
                             "restir_seconds": re_rows[-1]["seconds"]}
            print(f"seed {seed}: {name} reaches the baseline's final param_error {target:.5f} at "
                  + (f"{t:.1f} s (baseline {base_rows[-1]['seconds']:.1f} s: "
                     f"{base_rows[-1]['seconds'] / t:.2f}x)" if t else "never")
                  + (f", stays below from {t_stay:.1f} s ({base_rows[-1]['seconds'] / t_stay:.2f}x)"
                     if t_stay else ", does not stay below"))
    with open(os.path.join(a.out, "restir_optimize.json"), "w") as f:
        json.dump({"config": base, "runs": results, "headline": headline}, f, indent=1)
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.2))
    colors = {"prb+cv": "tab:blue", "prb+cv+restir": "tab:red", "adjoint x16": "tab:green",
              "primal x16": "tab:purple", "prb": "tab:gray",
              "prb+restir primal+adjoint": "tab:orange",
              "prb+cv (the same spp and lr)": "tab:cyan"}
    for key, rows in results.items():
        name, seed = key.split("/")
        label = name if seed == str(a.seeds[0]) else None
        control = name in ("adjoint x16", "primal x16")
        if not control:  # the controls' time is not the point: iterations only
            ax[0].plot([r["seconds"] for r in rows], [r["param_error"] for r in rows],
                       color=colors[name], alpha=0.8, label=label)
            img = [r for r in rows if r["image_error"] is not None]
            ax[1].plot([r["seconds"] for r in img], [r["image_error"] for r in img], "o-",
                       color=colors[name], alpha=0.8, label=label)
        ax[2].plot([r["iteration"] for r in rows], [r["param_error"] for r in rows],
                   "--" if control else "-",
                   color=colors[name], alpha=0.8, label=label)
    for x, title in zip(ax, ("parameter RMSE", "image RMSE (re-render)", "parameter RMSE")):
        x.set_xlabel("iteration" if x is ax[2] else "wall time of the iterations (s)")
        x.set_title(title)
        x.set_yscale("log")
        x.grid(alpha=0.3)
        x.legend()
    fig.suptitle(os.path.basename(a.config) + f": seeds {a.seeds}")
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "restir_optimize.png"), dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
