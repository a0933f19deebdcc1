#!/usr/bin/env python3
"""The Python module's overhead per iteration: a loop written in Python (render, an L2 loss and
its delta in NumPy, backward, Optimizer.step) against `tandem optimize` doing the same work,
side by side in one run.

    PYTHONPATH=build/python .venv/bin/python bench/python_overhead.py [--build build]
        [--iterations 40] [--rounds 3] [--res 128] [--json OUT.json]

Workload: cbox-wall at res² (the wall's 256² texture, Adam lr 0.02 from flat grey), 4 + 4 spp,
L2 against a 256-spp target, for the plain loop (cv none) and the recursive control variate
(two-state render + ControlVariate in Python, cv ps in the CLI). The CLI's time is its
metrics.csv `seconds` (the iterations themselves, without measurements and output writes);
Python's is wall time around the loop. Each round runs both, alternating, after a warm-up
iteration; the medians over rounds are compared. Both loops are seeded alike, so they must end
on the same texture bit for bit: checked, and printed.
"""

import argparse
import csv
import json
import pathlib
import platform
import statistics
import subprocess
import tempfile
import time

import numpy as np

import tandem

ROOT = pathlib.Path(__file__).resolve().parents[1]
WALL = "wall.reflectance"


def l2_delta(image, ref):
    inv_n = np.float32(1.0) / np.float32(image.size)
    return np.float32(2.0) * (image - ref) * inv_n


def python_loop(scene, ref, cv_mode, iterations, seed):
    """Seconds of `iterations` iterations from flat grey; the final texture."""
    wall = scene.params[WALL]
    wall.value = 0.5
    opt = tandem.Optimizer(scene, {WALL: 0.02})
    cv = tandem.ControlVariate(scene) if cv_mode == "ps" else None
    t0 = time.perf_counter()
    for n in range(iterations):
        if cv is None:
            image = scene.render(spp=4, seed=tandem.primal_seed(seed, n))
        else:
            f, h = scene.render_two_state(spp=4, seed=tandem.primal_seed(seed, n))
            image = cv(f, h)
        scene.backward(l2_delta(image, ref), spp=4, seed=tandem.adjoint_seed(seed, n),
                       params=WALL)
        opt.step()
    return time.perf_counter() - t0, wall.value


def cli_run(cli, config, out):
    subprocess.run([cli, "optimize", str(config), "--out", str(out)], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(out / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    return float(rows[-1]["seconds"]), tandem.read_image(str(out / f"{WALL}.exr"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", type=pathlib.Path, default=ROOT / "build")
    ap.add_argument("--iterations", type=int, default=40)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--json", type=pathlib.Path)
    args = ap.parse_args()
    cli = str(args.build / "tandem")
    seed = 0

    work = pathlib.Path(tempfile.mkdtemp(prefix="tandem-python-overhead-"))
    scene = tandem.load(ROOT / "scenes" / "cbox-wall.xml", res=args.res)
    ref = scene.render(spp=256, seed=12345)
    tandem.write_image(work / "ref.exr", ref)
    results = {}
    for cv_mode in ("none", "ps"):
        config = work / f"config-{cv_mode}.json"
        config.write_text(json.dumps({
            "scene": str(ROOT / "scenes" / "cbox-wall.xml"), "defines": {"res": args.res},
            "target": {"image": str(work / "ref.exr")},
            "params": {WALL: {"lr": 0.02, "init": 0.5}}, "optimizer": "adam",
            "iterations": args.iterations, "spp": 4, "spp_grad": 4, "loss": "l2", "seed": seed,
            "cv": cv_mode, "checkpoint_every": args.iterations, "image_error_spp": 1}))
        python_loop(scene, ref, cv_mode, 1, seed)  # warm-up: every kernel built and launched
        py_times, cli_times = [], []
        for r in range(args.rounds):
            seconds, cli_texture = cli_run(cli, config, work / f"cli-{cv_mode}-{r}")
            cli_times.append(seconds)
            seconds, py_texture = python_loop(scene, ref, cv_mode, args.iterations, seed)
            py_times.append(seconds)
            same = bool(np.array_equal(py_texture, cli_texture))
            if not same:
                raise SystemExit(f"cv {cv_mode}: the Python loop's texture differs from the CLI's")
        py, cl = statistics.median(py_times), statistics.median(cli_times)
        results[cv_mode] = {
            "python_seconds_per_iteration": py / args.iterations,
            "cli_seconds_per_iteration": cl / args.iterations,
            "overhead": py / cl - 1.0,
            "python_seconds": py_times, "cli_seconds": cli_times, "same_texture": True}
        print(f"cv {cv_mode:4}: Python {1e3 * py / args.iterations:7.1f} ms/iteration, CLI "
              f"{1e3 * cl / args.iterations:7.1f} ms/iteration: overhead {100 * (py / cl - 1):+5.1f} % "
              f"(rounds: Python {', '.join(f'{t:.2f}' for t in py_times)} s; CLI "
              f"{', '.join(f'{t:.2f}' for t in cli_times)} s); same texture bit for bit",
              flush=True)
    out = {"machine": platform.processor() or platform.machine(), "device": scene.device["name"],
           "res": args.res, "iterations": args.iterations, "rounds": args.rounds, **results}
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
