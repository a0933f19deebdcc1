#!/usr/bin/env python3
"""Where a recovered texture's error lives: at the scale of a few texels or above it.

    .venv/bin/python scripts/texture_error_split.py TRUTH RECOVERED.exr [RECOVERED.exr ...]
                                                  [--block 4] [--rows 12]

TRUTH is the texture the scene was rendered with (an 8-bit PNG is sRGB-decoded, as `tandem`
reads it; an EXR is linear), RECOVERED a texture `tandem optimize` wrote. For each, prints the
RMSE over texels and channels (what metrics.csv calls param_error), then splits the error
e = recovered - truth into its low-pass part (e averaged over BLOCK x BLOCK texel tiles) and the
rest, RMSE of each (their squares add up to the first's), and the same two for the top ROWS
rows of tiles. A film with about a pixel per texel sees the high-pass part only through the
pixel and bilinear filters, so noise in δ can put error there that the image barely shows.

Reads images through `oiiotool --dumpdata` (Debian's openimageio-tools, installed by
scripts/setup-debian.sh); needs numpy.
"""
import argparse
import subprocess
import sys

import numpy as np


def read(path):
    out = subprocess.run(["oiiotool", "--dumpdata", path], check=True, capture_output=True,
                         text=True).stdout.splitlines()
    header = out[0].split(":")[1].split(",")
    w, h = (int(v) for v in header[0].split("x"))
    integer = "uint8" in out[0]
    rows = []
    for line in out[1:]:
        if "Pixel" not in line:
            continue
        values = line.split(":", 1)[1]
        if integer:  # "242 140 89 (0.949 0.549 0.349)": the normalised values
            values = values[values.index("(") + 1:values.index(")")]
        rows.append([float(v) for v in values.split()[:3]])
    img = np.array(rows, dtype=np.float64).reshape(h, w, 3)
    if integer:  # sRGB, decoded as core/io/image_io.cpp does
        img = np.where(img <= 0.04045, img / 12.92, ((img + 0.055) / 1.055) ** 2.4)
    return img


def split(e, block):
    h, w, c = e.shape
    hb, wb = h // block, w // block
    e = e[:hb * block, :wb * block]
    low = e.reshape(hb, block, wb, block, c).mean(axis=(1, 3))
    low = np.repeat(np.repeat(low, block, axis=0), block, axis=1)
    return e, low, e - low


def rms(a):
    return float(np.sqrt(np.mean(a * a)))


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("truth")
    ap.add_argument("recovered", nargs="+")
    ap.add_argument("--block", type=int, default=4)
    ap.add_argument("--rows", type=int, default=12, help="tile rows of the top region (0: none)")
    a = ap.parse_args()
    truth = read(a.truth)
    print(f"{'texture':60s} {'rmse':>7s} {'low':>7s} {'high':>7s} {'top low':>8s} {'top high':>8s}")
    for path in a.recovered:
        rec = read(path)
        if rec.shape != truth.shape:
            print(f"{path}: {rec.shape[1]}x{rec.shape[0]}, "
                  f"the truth is {truth.shape[1]}x{truth.shape[0]}", file=sys.stderr)
            return 1
        e, low, high = split(rec - truth, a.block)
        top = a.rows * a.block
        print(f"{path[-60:]:60s} {rms(e):7.4f} {rms(low):7.4f} {rms(high):7.4f} "
              f"{rms(low[:top]) if top else 0:8.4f} {rms(high[:top]) if top else 0:8.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
