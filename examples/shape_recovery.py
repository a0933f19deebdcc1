#!/usr/bin/env python3
"""Multi-view shape recovery (scenes/shape-recover.json): the blob's distance to the true shape at
each checkpoint of the run, against iterations and time, and a picture of three views.

    build/tandem optimize scenes/shape-recover.json --out shape-recovery
    PYTHONPATH=build/python .venv/bin/python examples/shape_recovery.py shape-recovery

The run starts from a sphere (scenes/blob-sphere.obj) and writes the mesh it has reached at each
checkpoint (meshes/blob.vertex_positions_iter_NNNN.ply). Each is measured against the true blob
(scenes/blob.obj) with tandem.surface_distance: the Chamfer distance (the mean of the two
one-sided mean distances between the surfaces) and the Hausdorff distance (the largest), over
100,000 points of each surface. Written: RUN/shape_metrics.csv (iteration, seconds, chamfer,
hausdorff; iteration 0 is the sphere) and --out (default docs/shape_recovery.png): the two
distances against iterations and seconds, and for three views (rows) the target, the start and
the last re-render.
"""

import argparse
import csv
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tandem  # noqa: E402

sys.dont_write_bytecode = True  # no __pycache__ in examples/
from recovery_figure import srgb  # noqa: E402 (the same display transform)

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
PARAM = "blob.vertex_positions"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=pathlib.Path, help="the job's --out folder")
    ap.add_argument("--samples", type=int, default=100000, help="points on each surface")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "shape_recovery.png")
    args = ap.parse_args()

    seconds = {int(r["iteration"]): float(r["seconds"])
               for r in csv.DictReader(open(args.run / "metrics.csv"))}
    meshes = sorted((args.run / "meshes").glob(f"{PARAM}_iter_*.ply"))
    if not meshes:
        raise SystemExit(f"{args.run}/meshes: no {PARAM}_iter_*.ply (run scenes/shape-recover.json)")
    truth = str(SCENES / "blob.obj")
    rows = [(0, 0.0, *tandem.surface_distance(str(SCENES / "blob-sphere.obj"), truth, args.samples))]
    for path in meshes:
        it = int(path.stem.rsplit("_", 1)[1])
        rows.append((it, seconds[it], *tandem.surface_distance(str(path), truth, args.samples)))
    with open(args.run / "shape_metrics.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["iteration", "seconds", "chamfer", "hausdorff"])
        w.writerows(rows)
    print("iteration  seconds   chamfer  hausdorff")
    for it, s, c, h in rows:
        print(f"{it:9d} {s:8.1f} {c:9.5f} {h:10.5f}")
    print(f"Chamfer {rows[0][2]:.5f} -> {rows[-1][2]:.5f} ({rows[-1][2] / rows[0][2]:.3f} of the "
          f"start), Hausdorff {rows[0][3]:.5f} -> {rows[-1][3]:.5f}")

    fig = plt.figure(figsize=(10.0, 6.6), dpi=80)
    grid = fig.add_gridspec(6, 5, width_ratios=[1.0, 1.0, 0.62, 0.62, 0.62])
    its, secs = [r[0] for r in rows], [r[1] for r in rows]
    for cell, x, label in ((grid[0:3, 0:2], its, "iteration"),
                           (grid[3:6, 0:2], secs, "seconds (metrics.csv)")):
        ax = fig.add_subplot(cell)
        ax.semilogy(x, [r[2] for r in rows], "o-", label="Chamfer")
        ax.semilogy(x, [r[3] for r in rows], "s-", label="Hausdorff")
        ax.set_xlabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    scene = tandem.load(str(SCENES / "blob.xml"))
    last = meshes[-1].stem.rsplit("_", 1)[1]
    for j, k in enumerate((0, 2, 5)):
        folder = args.run / "views" / str(k)
        panels = (("target", tandem.read_image(str(folder / "target.exr"))),
                  ("start", scene.render(spp=64, seed=1, sensor=k)),
                  (f"iter. {int(last)}", tandem.read_image(str(folder / f"iter_{last}.exr"))))
        for i, (title, image) in enumerate(panels):
            ax = fig.add_subplot(grid[2 * j:2 * j + 2, 2 + i])
            ax.imshow(srgb(image), interpolation="nearest")
            ax.set_title(f"view {k}: {title}", fontsize=7)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out} and {args.run / 'shape_metrics.csv'}")


if __name__ == "__main__":
    main()
