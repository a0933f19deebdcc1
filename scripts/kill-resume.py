#!/usr/bin/env python3
"""Kills `tandem optimize` with SIGKILL at random moments and checks that `--resume` always
succeeds and ends bit-identical to an uninterrupted run.

    scripts/kill-resume.py [--tandem build/tandem] [--imgcmp TOOL] [--kills 20] [--seed 1]
                           [--work DIR]

The run: cbox-wall at 32x32, the wall's 256x256 texture from flat grey, CV-PS, Adam, 60
iterations, a checkpoint and re-render images every 3 iterations (the script writes the
config). First an uninterrupted run (after one that builds the kernels), timed; then for each kill a fresh run killed after a
uniformly random fraction of that time (so kills land in iterations, checkpoint writes and image
writes in proportion to the time each takes), then `--resume` to the end. Each resumed run must
give the uninterrupted run's metrics (all but the wall-time column) and params.json byte for
byte, and its final texture's stored words bit for bit (tandem-imgcmp, built beside tandem, unless
--imgcmp names it). A kill that lands in a write leaves its temporary behind: counted, and the
resumed run must remove it. Exits 1 on the first difference. Needs no Python module outside the
standard library. (tests/cli/test_kills.py places kills deterministically; this script samples
the moments at random.)
"""

import argparse
import csv
import io
import json
import os
import pathlib
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
TEMPORARY = re.compile(r"\.(.+)\.tmp[0-9]+(\.[A-Za-z0-9]+)?$")  # .NAME.tmpPID[.ext]


def write_config(work, res=32, spp=2, target_spp=16):
    """A CV-PS run on cbox-wall (res x res, spp samples, a checkpoint every 3 iterations)."""
    config = {
        "scene": str(ROOT / "scenes" / "cbox-wall.xml"),
        "defines": {"res": res},
        "target": {"scene": str(ROOT / "scenes" / "cbox-wall.xml"), "defines": {"res": res},
                   "spp": target_spp},
        "params": {"wall.reflectance": {"lr": 0.02, "init": 0.5}},
        "iterations": 60, "spp": spp, "spp_grad": spp, "loss": "l2", "seed": 7, "cv": "ps",
        "checkpoint_every": 3, "image_error_spp": spp,
    }
    path = pathlib.Path(work) / "config.json"
    path.write_text(json.dumps(config))
    return path


class StoppedRun:
    """A unittest.TestCase mixin (tests/cli): in a fresh folder cls.work, a config (write_config
    with `config_args`), an uninterrupted run "whole" to iteration `until` and a run "part"
    stopped after its first checkpoint (iteration 3); fresh_copy(name) copies "part" for a case
    to resume. Call set_up_runs from setUpClass."""

    @classmethod
    def set_up_runs(cls, tandem, prefix, until, **config_args):
        cls.work = pathlib.Path(tempfile.mkdtemp(prefix=prefix))
        cls.config = write_config(cls.work, **config_args)
        for name, last in (("whole", until), ("part", 3)):
            r = run(tandem, cls.config, cls.work / name, "--until", str(last))
            assert r.returncode == 0, r.stderr

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.work, ignore_errors=True)

    def fresh_copy(self, name):
        out = self.work / name
        shutil.rmtree(out, ignore_errors=True)
        shutil.copytree(self.work / "part", out)
        return out


def error_lines(stderr):
    """The CLI's error lines ("tandem: error: ...") of a run's stderr."""
    return [line for line in stderr.splitlines() if line.startswith("tandem: error: ")]


def outcome(out):
    """What must be identical: metrics without the wall-time column, params.json, the texture."""
    with open(out / "metrics.csv") as f:
        rows = list(csv.reader(f))
    seconds = rows[0].index("seconds")
    metrics = [[v for i, v in enumerate(r) if i != seconds] for r in rows]
    return {"metrics": metrics, "params.json": (out / "params.json").read_bytes()}


def imgcmp_beside(tandem):
    """tandem-imgcmp, which the build puts beside tandem."""
    return str(pathlib.Path(tandem).with_name("tandem-imgcmp"))


def same_pixels(a, b, imgcmp):
    """Whether two images store the same words bit for bit (tandem-imgcmp: NaN payloads and the
    sign of zero count). Raises SystemExit when one cannot be read."""
    r = subprocess.run([imgcmp, str(a), str(b)], capture_output=True, text=True)
    if r.returncode not in (0, 1):
        raise SystemExit(f"{imgcmp}: {r.stderr.strip() or r.returncode}")
    return r.returncode == 0


def run(tandem, config, out, *extra, env=None):
    return subprocess.run([tandem, "optimize", str(config), "--out", str(out), *extra],
                          capture_output=True, text=True, env=env)


def kill_and_resume(tandem, config, out, delay):
    """Starts a run, kills it after `delay` s, resumes it to the end. Returns (finished before
    the kill, temporaries the kill left, the resumed run's stderr)."""
    p = subprocess.Popen([tandem, "optimize", str(config), "--out", str(out)],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(delay)
    p.kill()
    code = p.wait()
    left = sorted(f.name for f in out.iterdir() if TEMPORARY.match(f.name)) if out.exists() else []
    r = run(tandem, config, out, "--resume")
    if r.returncode != 0:
        raise SystemExit(f"--resume after a kill at {delay:.2f} s failed: {r.stderr.strip()}")
    remaining = [f.name for f in out.iterdir() if TEMPORARY.match(f.name)]
    if remaining:
        raise SystemExit(f"the resumed run left temporaries: {remaining}")
    return code == 0, left, r.stderr


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tandem", default=str(ROOT / "build" / "tandem"))
    ap.add_argument("--imgcmp", help="tandem-imgcmp (default: beside --tandem)")
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--work", help="folder for the runs (default: a new temporary folder)")
    args = ap.parse_args(argv)
    imgcmp = args.imgcmp or imgcmp_beside(args.tandem)
    work = pathlib.Path(args.work or tempfile.mkdtemp(prefix="tandem-kill-resume-"))
    work.mkdir(parents=True, exist_ok=True)
    config = write_config(work)

    for attempt in ("warm-up", "timed"):  # the first builds (and caches) the kernels
        shutil.rmtree(work / "whole", ignore_errors=True)
        t0 = time.perf_counter()
        r = run(args.tandem, config, work / "whole")
        duration = time.perf_counter() - t0
        if r.returncode != 0:
            raise SystemExit(f"the uninterrupted run failed: {r.stderr.strip()}")
    expected = outcome(work / "whole")
    rng = random.Random(args.seed)
    in_write = finished = 0
    for k in range(args.kills):
        out = work / f"kill{k}"
        shutil.rmtree(out, ignore_errors=True)
        delay = rng.uniform(0.0, duration)
        done, left, _ = kill_and_resume(args.tandem, config, out, delay)
        finished += done
        in_write += bool(left)
        got = outcome(out)
        for key in expected:
            if got[key] != expected[key]:
                raise SystemExit(f"kill {k} at {delay:.2f} s: {key} differs after --resume")
        if not same_pixels(work / "whole" / "wall.reflectance.exr", out / "wall.reflectance.exr",
                           imgcmp):
            raise SystemExit(f"kill {k} at {delay:.2f} s: the texture differs after --resume")
        print(f"kill {k + 1}/{args.kills} at {delay:5.2f} s of {duration:.2f} s: resumed, "
              f"identical{'; it left ' + ', '.join(left) if left else ''}"
              f"{' (the run had finished)' if done else ''}", flush=True)
    print(f"{args.kills} kills: every --resume succeeded and ended bit-identical; "
          f"{in_write} landed in a file write, {finished} after the run had finished")
    return 0


if __name__ == "__main__":
    sys.exit(main())
