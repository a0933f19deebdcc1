#!/usr/bin/env python3
"""Writes the grids of grad-media-grid.xml (a finite-difference test of grid media,
tests/core/inverse/test_gradient.cpp): grad-media-density.vol, 6^3 densities in [0.25, 1.5], one
channel, and grad-media-albedo.vol, 4^3 rgb albedos in [0.3, 0.9], from a fixed seed, in Mitsuba's
.vol format (version 3, float32); and grad-media-density-empty.vol, the density grid with its
voxels of x index 0, 1 and 2 set to 0 (empty: `-D density=grad-media-density-empty.vol`).

    tests/scenes/gen_grad_media_grid.py [OUT_DIR]     (default: this folder)
"""
import os
import random
import struct
import sys


def write_vol(path, n, channels, values):
    with open(path, "wb") as f:
        f.write(b"VOL" + bytes([3]) + struct.pack("<iiiii", 1, n, n, n, channels))
        f.write(struct.pack("<6f", 0, 0, 0, 1, 1, 1))
        f.write(struct.pack(f"<{len(values)}f", *values))


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    rng = random.Random(11)
    density = [0.25 + 1.25 * rng.random() for _ in range(6 ** 3)]
    write_vol(os.path.join(out, "grad-media-density.vol"), 6, 1, density)
    write_vol(os.path.join(out, "grad-media-albedo.vol"), 4, 3,
              [0.3 + 0.6 * rng.random() for _ in range(4 ** 3 * 3)])
    write_vol(os.path.join(out, "grad-media-density-empty.vol"), 6, 1,
              [0.0 if i % 6 < 3 else v for i, v in enumerate(density)])


if __name__ == "__main__":
    main()
