#!/usr/bin/env python3
"""Recover the painted back wall of the Cornell box from one rendered image, with a loss Tandem
does not have built in: L1 on the image plus a total-variation prior on the texture, written in
NumPy. Tandem renders (through the recursive control variate), back-propagates the image part
(PRB), and steps Adam on the device; the prior's gradient is added in NumPy.

    PYTHONPATH=build/python .venv/bin/python examples/texture_recovery.py

writes texture_recovery/: plot.png (losses, texture error, the textures and renders),
wall.reflectance.exr (the recovered texture) and metrics.csv.
"""

import argparse
import csv
import pathlib
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tandem  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]


def total_variation(tex):
    """Anisotropic TV, mean over texel pairs of |difference|, and its gradient."""
    dx = tex[:, 1:] - tex[:, :-1]
    dy = tex[1:, :] - tex[:-1, :]
    n = dx.size + dy.size
    value = (np.abs(dx).sum() + np.abs(dy).sum()) / n
    sx, sy = np.sign(dx) / n, np.sign(dy) / n
    grad = np.zeros_like(tex)
    grad[:, 1:] += sx
    grad[:, :-1] -= sx
    grad[1:, :] += sy
    grad[:-1, :] -= sy
    return value, grad


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", type=int, default=200)
    ap.add_argument("--res", type=int, default=128, help="film width and height")
    ap.add_argument("--spp", type=int, default=4, help="samples per pixel, primal and adjoint")
    ap.add_argument("--lr", type=float, default=0.02, help="Adam's learning rate")
    ap.add_argument("--tv", type=float, default=0.03, help="weight of the total-variation prior")
    ap.add_argument("--no-cv", action="store_true", help="plain renders, no control variate")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default=None, help="OpenCL device: index or name substring")
    ap.add_argument("--out", type=pathlib.Path, default=pathlib.Path("texture_recovery"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    scene = tandem.load(ROOT / "scenes" / "cbox-wall.xml", device=args.device, res=args.res)
    wall = scene.params["wall.reflectance"]
    truth = wall.value
    target = scene.render(spp=256, seed=0xC0FFEE)  # the "photograph"
    wall.value = 0.5  # a flat grey start
    start = scene.render(spp=64, seed=1)
    opt = tandem.Optimizer(scene, {wall.name: args.lr})
    cv = None if args.no_cv else tandem.ControlVariate(scene)

    rows = []
    seen = None  # texels that receive gradient (seen directly or through a bounce)
    t0 = time.perf_counter()
    for it in range(args.iterations):
        seed = tandem.primal_seed(args.seed, it)
        if cv is None:
            image = scene.render(spp=args.spp, seed=seed)
        else:
            f, h = scene.render_two_state(spp=args.spp, seed=seed)
            image = cv(f, h)
        diff = image - target
        l1 = float(np.abs(diff).mean())
        delta = (np.sign(diff) / diff.size).astype(np.float32)
        grads = scene.backward(delta, spp=args.spp, seed=tandem.adjoint_seed(args.seed, it),
                               params=wall.name)
        if seen is None:
            seen = np.any(grads[wall.name] != 0, axis=2)
        tex = wall.value
        tv, tv_grad = total_variation(tex)
        opt.step({wall.name: grads[wall.name] + np.float32(args.tv) * tv_grad})
        rmse = float(np.sqrt(np.mean((wall.value[seen] - truth[seen]) ** 2)))
        rows.append({"iteration": it + 1, "seconds": time.perf_counter() - t0, "l1": l1,
                     "tv": float(tv), "texture_rmse": rmse})
        if (it + 1) % 20 == 0 or it + 1 == args.iterations:
            print(f"iteration {it + 1}/{args.iterations}: L1 {l1:.5f}, TV {tv:.5f}, "
                  f"texture RMSE {rmse:.4f} ({rows[-1]['seconds']:.1f} s)", flush=True)

    recovered = wall.value
    tandem.write_image(args.out / "wall.reflectance.exr", recovered)
    with open(args.out / "metrics.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    final = scene.render(spp=64, seed=1)

    def show(ax, img, title):
        ax.imshow(np.clip(img, 0, 1) ** (1 / 2.2))
        ax.set_title(title, fontsize=9)
        ax.axis("off")

    fig = plt.figure(figsize=(12, 6), constrained_layout=True)
    grid = fig.add_gridspec(2, 4)
    ax = fig.add_subplot(grid[:, :2])
    its = [r["iteration"] for r in rows]
    ax.semilogy(its, [r["l1"] for r in rows], label="image L1 (loss)")
    ax.semilogy(its, [args.tv * r["tv"] for r in rows], label=f"{args.tv:g} x texture TV (prior)")
    ax.semilogy(its, [r["texture_rmse"] for r in rows],
                label=f"texture RMSE vs truth, over the {100 * seen.mean():.0f} % of texels "
                      "with gradient")
    ax.set_xlabel("iteration")
    ax.set_title(f"cbox-wall {args.res}², {args.spp} spp, Adam lr {args.lr:g}, "
                 f"{'recursive CV' if cv else 'no CV'}: {rows[-1]['seconds']:.0f} s", fontsize=10)
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    show(fig.add_subplot(grid[0, 2]), truth, "true texture")
    show(fig.add_subplot(grid[0, 3]), recovered, "recovered texture")
    show(fig.add_subplot(grid[1, 2]), start, "start (grey wall)")
    show(fig.add_subplot(grid[1, 3]), final, "recovered, re-rendered")
    fig.savefig(args.out / "plot.png", dpi=80)
    print(f"{args.out}/plot.png, wall.reflectance.exr, metrics.csv")


if __name__ == "__main__":
    main()
