#!/usr/bin/env python3
"""Is the mean of many gradients a reference's, tile by tile? A check of bias at a fixed θ.

    .venv/bin/python bench/restir_tile_bias.py REF.exr REF_SPP --test T1.exr T2.exr ...
                                               --base B1.exr B2.exr ... [--tile 16]

REF.exr is a texture gradient from `tandem grad ... --spp-grad REF_SPP --out-grad REF.exr`, the
T files gradients of the estimator under test (e.g. `--restir`), one seed each, the B files plain
PRB gradients at the test's spp with the same seeds. Sums each gradient over TILE x TILE texels
and its channels, then for each tile z = (mean of T - REF) / sqrt(se_T^2 + se_REF^2), with se_T
the standard error of the T mean and se_REF that of the reference, estimated from the spread of
the B gradients scaled by their spp over REF_SPP (the B spp read from --base-spp, default 4).
Prints the mean, RMS and largest |z| for the tests and, as a control, for the B mean, and the
per-tile variance of B over T. Unbiased: RMS z near 1 and no |z| far beyond 4.

Reads images through `oiiotool --dumpdata` (bench/texture_error_split.py); needs numpy.
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from texture_error_split import read  # noqa: E402


def tiles(img, t):
    h, w = img.shape[0] // t, img.shape[1] // t
    return img[:h * t, :w * t].sum(axis=-1).reshape(h, t, w, t).sum(axis=(1, 3))


def zsummary(name, z):
    print(f"{name:6s} tiles {z.size}: mean z {z.mean():+.2f}, rms z {np.sqrt(np.mean(z * z)):.2f}, "
          f"largest |z| {np.abs(z).max():.1f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ref")
    ap.add_argument("ref_spp", type=int)
    ap.add_argument("--test", nargs="+", required=True)
    ap.add_argument("--base", nargs="+", required=True)
    ap.add_argument("--base-spp", type=int, default=4)
    ap.add_argument("--tile", type=int, default=16)
    a = ap.parse_args()
    ref = tiles(read(a.ref), a.tile)
    test = np.array([tiles(read(p), a.tile) for p in a.test])
    base = np.array([tiles(read(p), a.tile) for p in a.base])
    var_ref = base.var(axis=0, ddof=1) * a.base_spp / a.ref_spp
    for name, g in (("test", test), ("base", base)):
        z = (g.mean(axis=0) - ref) / np.sqrt(g.var(axis=0, ddof=1) / len(g) + var_ref)
        zsummary(name, z)
    ratio = base.var(axis=0, ddof=1) / test.var(axis=0, ddof=1)
    print(f"variance of base over test per tile: median {np.median(ratio):.1f}, "
          f"10th-90th percentile {np.percentile(ratio, 10):.1f}-{np.percentile(ratio, 90):.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
