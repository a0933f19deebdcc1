#!/usr/bin/env python3
"""The README's picture of the multi-view job (docs/views.png): the painted globe recovered from one
view and from all eight, as textures and as renders of the side that view 0 does not see.

    build/tandem optimize scenes/globe-recover-one-view.json --out globe-one-view
    build/tandem optimize scenes/globe-recover.json --out globe-all-views
    PYTHONPATH=build/python .venv/bin/python examples/views_figure.py globe-one-view globe-all-views

The top row is the true texture and the two recovered ones (globe.reflectance.exr), with each
one's whole-texture RMSE; the bottom row renders each (64 spp) from sensor 6 ('view6', the far
side from view 0).
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tandem  # noqa: E402
from recovery_figure import ROOT, srgb  # noqa: E402 (the main job's figure, beside this one)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("one", type=pathlib.Path, help="the --out folder of globe-recover-one-view.json")
    ap.add_argument("all", type=pathlib.Path, help="the --out folder of globe-recover.json")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "views.png")
    args = ap.parse_args()

    scene = tandem.load(str(ROOT / "scenes" / "globe.xml"), res=96)
    globe = scene.params["globe.reflectance"]
    truth = globe.value
    textures = [("true texture", truth)]
    for title, run in (("one view", args.one), ("all 8 views", args.all)):
        t = tandem.read_image(str(run / "globe.reflectance.exr"))
        rmse = float(np.sqrt(np.mean((t.astype(np.float64) - truth) ** 2)))
        textures.append((f"{title}: RMSE {rmse:.3f}", t))
    renders = []
    for title, t in textures:
        scene.params["globe.reflectance"] = t
        renders.append((title.split(":")[0] + ", seen by view6", scene.render(spp=64, seed=1, sensor="view6")))
    fig, axes = plt.subplots(2, 3, figsize=(7.5, 4.6), dpi=80)
    for ax, (title, image) in zip(axes.flat, textures + renders):
        ax.imshow(srgb(image), interpolation="nearest")
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.94, wspace=0.04, hspace=0.12)
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
