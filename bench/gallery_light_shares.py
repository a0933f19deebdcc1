#!/usr/bin/env python3
"""Where the direct light on gallery-lights' painting comes from: one render per emitter group
(the others set to zero radiance), each group's share of the painting's mean luminance.

    python3 bench/gallery_light_shares.py build/tandem [--res 128] [--spp 256] [-D fov=22]

Groups: the side-room light seen through the door gap, the three spots, the fill panel and the
64 ledge emitters (scenes/gen_gallery.py). The painting's pixels are the projection of its canvas,
inset by one pixel. Needs oiiotool (Debian's openimageio-tools) for the region statistics.
"""
import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "scenes", "gallery-lights.xml")
# The camera and the canvas as scenes/gen_gallery.py writes them.
EYE, TARGET = (0.0, 1.45, 1.7), (0.0, 1.4, -4.0)
CANVAS_X, CANVAS_Y, CANVAS_Z = (-1.0, 1.0), (0.75, 2.25), -3.955
LUMA = (0.2126, 0.7152, 0.0722)


def group_of(shape_id, emitter):
    if emitter.get("type") == "spot":
        return "spots"
    if shape_id == "door-light":
        return "door"
    if shape_id == "fill":
        return "fill"
    if shape_id.startswith("ledge-light"):
        return "ledge"
    raise SystemExit("gallery_light_shares.py: unknown emitter in shape '%s'" % shape_id)


def scene_with(src, keep):
    """The scene text with every emitter outside group `keep` (None: all kept) set to zero."""
    root = ET.fromstring(src)
    for child in root:  # the spots, and the shapes that carry an area emitter
        emitter = child if child.tag == "emitter" else child.find("emitter")
        if emitter is None:
            continue
        if keep is not None and group_of(child.get("id", ""), emitter) != keep:
            for rgb in emitter.iter("rgb"):
                rgb.set("value", "0, 0, 0")
    return ET.tostring(root, encoding="unicode")


def painting_box(res, fov):
    """Pixel rectangle (x0, y0, x1, y1), exclusive, inside the canvas' projection."""
    f = [t - e for t, e in zip(TARGET, EYE)]
    n = math.sqrt(sum(v * v for v in f))
    f = [v / n for v in f]
    r = [-f[2], 0.0, f[0]]  # f x up, up = +y
    n = math.sqrt(sum(v * v for v in r))
    r = [v / n for v in r]
    u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]]
    t = math.tan(math.radians(fov) / 2)
    xs, ys = [], []
    for X in CANVAS_X:
        for Y in CANVAS_Y:
            d = [X - EYE[0], Y - EYE[1], CANVAS_Z - EYE[2]]
            z = sum(a * b for a, b in zip(d, f))
            xs.append((sum(a * b for a, b in zip(d, r)) / z / t + 1) * res / 2)
            ys.append((1 - sum(a * b for a, b in zip(d, u)) / z / t) * res / 2)
    # corners: (x-, y-), (x-, y+), (x+, y-), (x+, y+); image rows grow downwards
    x0, x1 = math.ceil(max(xs[0], xs[1])), math.floor(min(xs[2], xs[3]))
    y0, y1 = math.ceil(max(ys[1], ys[3])), math.floor(min(ys[0], ys[2]))
    return max(0, x0 + 1), max(0, y0 + 1), min(res, x1 - 1), min(res, y1 - 1)


def stats(exr, box):
    x0, y0, x1, y1 = box
    out = subprocess.run(["oiiotool", exr, "--cut", "%dx%d+%d+%d" % (x1 - x0, y1 - y0, x0, y0),
                          "--printstats"], check=True, capture_output=True, text=True).stdout
    def row(name):
        return [float(v) for v in re.search(r"Stats %s:([^(\n]*)" % name, out).group(1).split()]
    luma = lambda c: sum(a * b for a, b in zip(c, LUMA))
    return luma(row("Avg")), luma(row("Max"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("tandem")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("-D", action="append", default=[], help="name=value, passed to tandem render")
    a = ap.parse_args()
    fov = 65.0
    for d in a.D:
        if d.startswith("fov="):
            fov = float(d[4:])
    src = open(SCENE).read()
    box = painting_box(a.res, fov)
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(os.path.join(os.path.dirname(SCENE), "textures"), os.path.join(tmp, "textures"))
        result = {}
        for keep in [None, "door", "spots", "fill", "ledge"]:
            name = keep or "all"
            path = os.path.join(tmp, name + ".xml")
            open(path, "w").write(scene_with(src, keep))
            exr = os.path.join(tmp, name + ".exr")
            cmd = [a.tandem, "render", path, "-D", "res=%d" % a.res, "--spp", str(a.spp), "--out", exr]
            for d in a.D:
                cmd += ["-D", d]
            subprocess.run(cmd, check=True, capture_output=True)
            result[name] = stats(exr, box)
    x0, y0, x1, y1 = box
    print("painting: pixels [%d, %d) x [%d, %d) of %d^2 (fov %g), %d spp" % (x0, x1, y0, y1, a.res, fov, a.spp))
    print("| group | share of the mean luminance | mean | max |")
    print("|---|---|---|---|")
    for g in ["door", "spots", "fill", "ledge"]:
        avg, mx = result[g]
        print("| %s | %.3f | %.4f | %.3f |" % (g, avg / result["all"][0], avg, mx))
    print("| all | 1 | %.4f | %.3f |" % result["all"])


if __name__ == "__main__":
    sys.exit(main())
