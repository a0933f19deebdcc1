#!/usr/bin/env python3
"""Shape gradients against Mitsuba 3's `prb_projective`, on the same scenes, seeds side by side.

    PYTHONPATH=build/python .venv/bin/python bench/peer_shape.py --python MITSUBA_PYTHON
        [--seeds 16] [--threads 2] [--boundary-reuse] [--json] [--cases NAME...]

For each case (the finite-difference cases of tests/core/inverse/test_shape_gradient.cpp, after
Mitsuba's own discontinuity tests, and the bundled many-lights shadow scene), the derivative of the mean image with respect to a rigid shift
of the listed meshes along one axis, at the same spp (primal) and spp_grad (Tandem's interior and
both boundary terms; Mitsuba's sppc, sppp and sppi, which its render() call sets from spp_grad):

- Tandem: Scene.grad("mean", spp, spp_grad, seed), the per-vertex gradient summed along the axis
  (the Python module, in this process);
- Mitsuba: the scene converted by bench/peer_mitsuba_convert.py (`prb_projective`; rectangles as
  a two-triangle OBJ, since Mitsuba's rectangle has no vertex positions), the shift t applied to
  the vertex positions and the mean image's dr.backward to t (bench/peer_mitsuba_worker.py, in
  MITSUBA_PYTHON's environment, `llvm_ad_rgb`);
- with --boundary-reuse, Tandem again with the secondary boundary term's reuse of light vertices
  across iterations (Scene.set_boundary_reuse; docs/restir.md, "Reuse for the boundary"): each
  estimate the last of a short chain along a moving theta (tandem_case), its var x t against
  Mitsuba's and against Tandem's without reuse.

Printed per case: each estimate's mean over the seeds with its standard error, the difference in
combined standard errors (z), and the median wall time of one gradient step of each (render, loss,
backward, the result read back; one untimed step first compiles), with their ratio, and the ratio
of variance times time (each estimate's variance over the seeds times its step's time: the ratio
of the two relative MSEs at equal time; below 1, Tandem is ahead). The steps of
the two renderers alternate case by case, not seed by seed (each runs its seeds in one go).
Both run on --threads threads (PoCL's pthread device; Dr.Jit's thread pool).
"""
import argparse
import json
import os
import statistics
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from peer_mitsuba import Mitsuba, tandem_env  # noqa: E402
from peer_mitsuba_convert import convert_file, write_square_obj  # noqa: E402

SCENES = os.path.join(ROOT, "tests", "scenes")
# name, scene, defines, meshes, axis, spp, spp_grad
CASES = [
    ("emitter-on-black-x", "shape-emitter-black.xml", {}, ["light"], 0, 4, 64),
    ("plane-along-normal", "shape-plane.xml", {}, ["plane"], 2, 4, 64),
    ("occluder", "shape-shadow.xml", {"ox": "0.3"}, ["occluder"], 0, 4, 256),
    ("receiver-under-sky", "shape-shadow.xml", {"sky": "1", "radiance": "0"}, ["wall"], 2, 4, 64),
    ("right-angle-point-light", "shape-selfshadow.xml", {}, ["floor", "wall"], 0, 4, 32),
    ("textured-plane-x", "shape-textured.xml", {}, ["plane"], 0, 4, 512),
    ("textured-plane-y", "shape-textured.xml", {}, ["plane"], 1, 4, 64),
    ("glossy-floor-x", "shape-glossy.xml", {}, ["object"], 0, 4, 64),
    # the bundled many-lights scene (scenes/shadow-lights.xml): twelve small sphere lights' shadows
    ("many-lights-shadows-x", "../../scenes/shadow-lights.xml", {"res": "64"}, ["blob"], 0, 4, 16),
]


def stats(values):
    m = statistics.fmean(values)
    return m, statistics.stdev(values) / len(values) ** 0.5


# With --boundary-reuse: each estimate the last of a chain of this many gradients, the meshes
# moving toward their place by REUSE_STEP times their bounding box's diagonal per gradient.
REUSE_CHAIN = 4
REUSE_STEP = 0.003


def tandem_case(tandem, case, seeds, reuse=False):
    """Tandem's estimates and step times. With `reuse`, the secondary boundary term reuses its
    light vertices (Scene.set_boundary_reuse, default settings): fresh reservoirs per seed, then
    REUSE_CHAIN - 1 untimed gradients along a moving theta (as an optimizer's steps), and the
    timed one at the case's theta with the seed."""
    _, scene, defines, meshes, axis, spp, spp_grad = case
    s = tandem.load(os.path.join(SCENES, scene), restir=reuse, **defines)
    names = [m + ".vertex_positions" for m in meshes]
    home = {n: s.params[n].value.copy() for n in names}
    diagonal = max(float(((x.max(0) - x.min(0)) ** 2).sum() ** 0.5) for x in home.values())

    def move(offset):
        for n in names:
            x = home[n].copy()
            x[:, axis] += offset
            s.params[n].value = x

    def grad(seed):
        _, g = s.grad("mean", params=names, spp=spp, spp_grad=spp_grad, seed=seed)
        return sum(float(g[n].reshape(-1, 3)[:, axis].sum()) for n in names)

    grads, times = [], []
    for i, seed in enumerate([0xFFFF] + list(seeds)):  # the first: untimed, builds the kernels
        if reuse:
            s.set_boundary_reuse(True)
            for k in range(REUSE_CHAIN - 1):
                move(REUSE_STEP * diagonal * (REUSE_CHAIN - 1 - k))
                grad(0x10000 + REUSE_CHAIN * seed + k)
            move(0.0)  # the case's theta, and a render that refits the BVH to it, untimed:
            s.render(spp=1, seed=0)  # the plain estimate's step moves nothing
        t0 = time.perf_counter()
        total = grad(seed)
        if i:
            grads.append(total)
            times.append(time.perf_counter() - t0)
    return grads, times


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python", required=True, help="a Python with Mitsuba 3 (>= 3.7) and numpy")
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--cases", nargs="*", help="names of the cases to run (default: all)")
    ap.add_argument("--boundary-reuse", action="store_true",
                    help="also Tandem with the secondary boundary term's reuse "
                         "(Scene.set_boundary_reuse), against both")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    os.environ.update(tandem_env(args.threads))  # before the module opens its device
    import tandem

    mitsuba = Mitsuba(None, args.threads, "llvm_ad_rgb", python=args.python)
    versions = mitsuba("hello")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        square = os.path.join(tmp, "square.obj")
        write_square_obj(square)
        for case in CASES:
            name, scene, defines, meshes, axis, spp, spp_grad = case
            if args.cases and name not in args.cases:
                continue
            print(f"[{name}] Tandem, then Mitsuba prb_projective", file=sys.stderr)
            xml = os.path.join(tmp, name + ".xml")
            open(xml, "w").write(convert_file(os.path.join(SCENES, scene), list(defines.items()),
                                              "prb_projective", square))
            seeds = range(args.seeds)
            tg, tt = tandem_case(tandem, case, seeds)
            m = mitsuba("shape_grad", xml=xml, params=meshes, axis=axis, spp=spp,
                        spp_grad=spp_grad, seeds=list(seeds))
            (ta, tse), (ma, mse) = stats(tg), stats(m["grads"])
            row = {"case": name, "spp": spp, "spp_grad": spp_grad, "seeds": args.seeds,
                   "tandem": ta, "tandem_se": tse, "mitsuba": ma, "mitsuba_se": mse,
                   "z": (ta - ma) / (tse ** 2 + mse ** 2) ** 0.5,
                   "tandem_seconds": statistics.median(tt),
                   "mitsuba_seconds": statistics.median(m["seconds"])}
            row["time_ratio"] = row["tandem_seconds"] / row["mitsuba_seconds"]
            print(f"[{name}] Tandem {ta:.5g} +- {tse:.2g}, Mitsuba {ma:.5g} +- {mse:.2g}; "
                  f"{row['tandem_seconds']:.4f} s against {row['mitsuba_seconds']:.4f} s",
                  file=sys.stderr)
            # error x time: the variance of one step's estimate times its time (the relative MSE
            # at equal time, Tandem's over Mitsuba's; below 1, Tandem is ahead)
            row["variance_time_ratio"] = (tse ** 2 * row["tandem_seconds"]) / (
                mse ** 2 * row["mitsuba_seconds"])
            if args.boundary_reuse:
                rg, rt = tandem_case(tandem, case, seeds, reuse=True)
                ra, rse = stats(rg)
                row.update({"reuse": ra, "reuse_se": rse,
                            "reuse_z": (ra - ma) / (rse ** 2 + mse ** 2) ** 0.5,
                            "reuse_seconds": statistics.median(rt)})
                # var x t of the reuse over Mitsuba's and over Tandem's without it
                row["reuse_variance_time_ratio"] = (rse ** 2 * row["reuse_seconds"]) / (
                    mse ** 2 * row["mitsuba_seconds"])
                row["reuse_vs_plain"] = (rse ** 2 * row["reuse_seconds"]) / (
                    tse ** 2 * row["tandem_seconds"])
                print(f"[{name}] Tandem with boundary reuse {ra:.5g} +- {rse:.2g} in "
                      f"{row['reuse_seconds']:.4f} s", file=sys.stderr)
            rows.append(row)
    mitsuba.close()
    if args.json:
        print(json.dumps({"mitsuba": versions, "threads": args.threads, "rows": rows}, indent=2))
        return
    print(f"Mitsuba {versions['mitsuba']} (llvm_ad_rgb, prb_projective), {args.threads} threads, "
          f"{args.seeds} seeds")
    print(f"{'case':26s} {'spp/grad':>9s} {'Tandem':>22s} {'Mitsuba':>22s} {'z':>6s} "
          f"{'Tandem s':>9s} {'Mitsuba s':>9s} {'ratio':>6s} {'var x t':>8s}")
    for r in rows:
        print(f"{r['case']:26s} {r['spp']:>4d}/{r['spp_grad']:<4d} "
              f"{r['tandem']:>11.5g} ± {r['tandem_se']:<8.2g} {r['mitsuba']:>11.5g} ± "
              f"{r['mitsuba_se']:<8.2g} {r['z']:>6.2f} {r['tandem_seconds']:>9.4f} "
              f"{r['mitsuba_seconds']:>9.4f} {r['time_ratio']:>6.2f} "
              f"{r['variance_time_ratio']:>8.3g}")
        if "reuse" in r:
            print(f"{'  with boundary reuse':26s} {'':>9s} {r['reuse']:>11.5g} ± "
                  f"{r['reuse_se']:<8.2g} {'':>22s} {r['reuse_z']:>6.2f} "
                  f"{r['reuse_seconds']:>9.4f} {'':>9s} {'':>6s} "
                  f"{r['reuse_variance_time_ratio']:>8.3g} (against Tandem without: "
                  f"{r['reuse_vs_plain']:.3g})")


if __name__ == "__main__":
    main()
