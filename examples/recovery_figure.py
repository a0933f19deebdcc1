#!/usr/bin/env python3
"""The README's picture (docs/recovery.png): the main job's target, its flat grey start and its
result, as renders and as the wall's texture.

    build/tandem optimize scenes/cbox-wall-recover.json --out cbox-wall-recovery
    PYTHONPATH=build/python .venv/bin/python examples/recovery_figure.py cbox-wall-recovery

The top row is the target (target.exr, the true scene at 256 spp), the start (the scene with the
wall at 0.5, rendered here at 64 spp, as the run's re-renders are) and the result
(iter_0100.exr); the bottom row is the true texture, the grey start and wall.reflectance.exr.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tandem  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]


def srgb(linear):
    """Linear radiance to displayable sRGB in [0, 1]."""
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=pathlib.Path, help="the main job's --out folder")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "recovery.png")
    args = ap.parse_args()

    scene = tandem.load(str(ROOT / "scenes" / "cbox-wall.xml"), res=128)
    wall = scene.params["wall.reflectance"]
    truth = wall.value
    wall.value = 0.5
    start = scene.render(spp=64, seed=1)
    iters = sorted(args.run.glob("iter_*.exr"))
    panels = [
        ("target", tandem.read_image(str(args.run / "target.exr"))),
        ("start", start),
        (f"after {int(iters[-1].stem[5:])} iterations", tandem.read_image(str(iters[-1]))),
        ("true texture", truth),
        ("start", np.full_like(truth, 0.5)),
        ("recovered", tandem.read_image(str(args.run / "wall.reflectance.exr"))),
    ]
    fig, axes = plt.subplots(2, 3, figsize=(6.0, 4.3), dpi=80)
    for ax, (title, image) in zip(axes.flat, panels):
        ax.imshow(srgb(image), interpolation="nearest")
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.94, wspace=0.04, hspace=0.1)
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
