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


def write_pfm(path, width, height, pixel):
    """Portable float map, linear RGB, little-endian; rows stored bottom to top (the format's rule)."""
    data = bytearray(b"PF\n%d %d\n-1.0\n" % (width, height))
    for y in reversed(range(height)):
        for x in range(width):
            data.extend(struct.pack("<3f", *pixel(x, y)))
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(bytes(data))
    os.replace(tmp, path)


def sky(x, y):
    """Latitude-longitude sky (v = 0 is straight up): a blue gradient, a small bright sun 35 degrees
    above the horizon, and a dim brown ground below the horizon. Linear radiance."""
    w, h = 128, 64
    theta = (y + 0.5) / h * math.pi
    phi = (x + 0.5) / w * 2 * math.pi
    if theta > math.pi / 2:
        return (0.12, 0.09, 0.06)
    up = math.cos(theta)
    sky_rgb = (0.35 + 0.25 * (1 - up), 0.55 + 0.2 * (1 - up), 1.0)
    sun_theta, sun_phi = math.radians(55), math.radians(120)
    cos_sun = (math.sin(theta) * math.sin(sun_theta) * math.cos(phi - sun_phi)
               + math.cos(theta) * math.cos(sun_theta))
    if cos_sun > math.cos(math.radians(3.0)):
        return (400.0, 360.0, 300.0)
    return sky_rgb


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    write_png(os.path.join(out, "wall.png"), 256, 256, wall)
    write_png(os.path.join(out, "painting.png"), 256, 192, painting)
    write_png(os.path.join(out, "floor.png"), 256, 256, floor)
    write_pfm(os.path.join(out, "sky.pfm"), 128, 64, sky)
    return 0


if __name__ == "__main__":
    sys.exit(main())
