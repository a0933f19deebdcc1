#!/usr/bin/env python3
"""Deterministic generator of the bundled scenes' textures (PNG, 8-bit sRGB), standard library only.

Usage: python3 scenes/gen_textures.py OUTDIR   (the committed copies live in scenes/textures/;
ctest checks that this script reproduces them byte for byte).
"""
import math
import os
import struct
import sys
import zlib


def write_png(path, width, height, pixel):
    """pixel(x, y) -> (r, g, b) in 0..255. Written to a temporary file, then renamed."""
    rows = bytearray()
    for y in range(height):
        rows.append(0)  # filter type: none
        for x in range(width):
            rows.extend(bytes(pixel(x, y)))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    png = (b"\x89PNG\r\n\x1a\n"
           + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(bytes(rows), 9))
           + chunk(b"IEND", b""))
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(png)
    os.replace(tmp, path)


def clamp8(v):
    return max(0, min(255, int(round(v))))


def wall(x, y):
    """Tiles in four colours with dark grout, and a large soft ring: detail at several scales."""
    tile = 32
    tx, ty = x // tile, y // tile
    gx, gy = x % tile, y % tile
    if gx < 2 or gy < 2:
        return (40, 36, 34)
    palette = [(200, 170, 120), (120, 150, 190), (190, 110, 90), (150, 180, 120)]
    r, g, b = palette[(tx * 3 + ty * 5) % 4]
    d = math.hypot(x - 128.0, y - 128.0)
    ring = 0.35 * math.exp(-((d - 80.0) / 14.0) ** 2)
    return (clamp8(r * (1 - ring) + 250 * ring), clamp8(g * (1 - ring) + 240 * ring),
            clamp8(b * (1 - ring) + 200 * ring))


def painting(x, y):
    """A sunset over hills: a sky gradient, a sun disk, two hill silhouettes."""
    w, h = 256, 192
    u, v = x / (w - 1), y / (h - 1)
    sky = (255 * (0.95 - 0.3 * v), 255 * (0.55 + 0.2 * v), 255 * (0.35 + 0.5 * v))
    if math.hypot(x - 170, y - 70) < 26:
        sky = (255, 230, 150)
    hill1 = 120 + 25 * math.sin(6.0 * u + 0.5)
    hill2 = 150 + 18 * math.sin(11.0 * u + 2.0)
    if y > hill2:
        return (40, 70, 45)
    if y > hill1:
        return (70, 110, 70)
    return tuple(clamp8(c) for c in sky)


def floor(x, y):
    """Wooden planks: stripes with a per-plank tint and fine grain."""
    plank = y // 32
    tint = [(150, 105, 70), (170, 120, 80), (135, 95, 60), (160, 112, 76)][plank % 4]
    grain = 12 * math.sin(0.35 * x + 3.1 * plank + 2.0 * math.sin(0.05 * x))
    edge = 0.55 if y % 32 == 0 else 1.0
    return tuple(clamp8((c + grain) * edge) for c in tint)


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    write_png(os.path.join(out, "wall.png"), 256, 256, wall)
    write_png(os.path.join(out, "painting.png"), 256, 192, painting)
    write_png(os.path.join(out, "floor.png"), 256, 256, floor)
    return 0


if __name__ == "__main__":
    sys.exit(main())
