#!/usr/bin/env python3
# Deterministic generator of scenes/gallery-lights.xml (standard library only).
# Usage: python3 scenes/gen_gallery.py OUTDIR   -- same output bytes on every run and platform.
#
# A gallery where light sampling is hard: the painting on the back wall is lit mostly by a dim
# fill, while nearly all the emitted power goes elsewhere -- three narrow spots aimed beside and
# below the painting, a bright area light in a side room seen only through a narrow door gap, and
# 64 small emitters on a ledge whose lip hides them from the painting. A sampler that picks lights
# by power spends most of its shadow rays on lights that do not reach the shading point.
import os
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from gen_meshes import write_atomic  # noqa: E402 (the same atomic replace as the meshes)

# Gallery room [-3,3] x [0,3] x [-4,2]; the camera looks down -z at the back wall (z = -4).
X0, X1, Y1, Z0, Z1 = -3.0, 3.0, 3.0, -4.0, 2.0
# Painting: 2 x 1.5 (the texture is 256 x 192), centred at (0, 1.5) on the back wall.
PAINT_C, PAINT_H = (0.0, 1.5), (1.0, 0.75)
# Door gap in the right wall (x = 3): 0.08 wide, 2.2 high, centred at z = DOOR_Z. The side room
# behind it is [3,5.2] x [0,3] x [-1.8,2].
DOOR_Z, DOOR_HW, DOOR_TOP = -1.0, 0.04, 2.2
SIDE_X1, SIDE_Z0 = 5.2, -1.8
# Spots: 8 degree cutoff, on a ceiling track; each aimed so that only the soft edge of its cone
# reaches the painting (about 3% of its power, the rest lands on the wall or floor beside it).
SPOT_CUTOFF, SPOT_INTENSITY = 8.0, 1500.0
SPOTS = [((-2.0, 2.9, -2.6), (-1.28, 1.5, -4.0)),   # left of the painting
         ((2.0, 2.9, -2.6), (1.26, 1.7, -4.0)),     # right of it
         ((0.0, 2.9, -2.2), (0.3, 0.2, -4.0))]     # below it, near the floor
# Side-room light: a 0.3 x 0.3 square in the side room's far corner, facing the door gap.
DOOR_LIGHT_C, DOOR_LIGHT_HS, DOOR_LIGHT_L = (5.0, 1.4, 1.6), 0.15, 1500.0
# Fill: a large dim panel on the near wall behind the camera, facing the painting.
FILL_C, FILL_H, FILL_L = (0.0, 1.5, 1.98), (2.6, 1.2), 4.0
# Ledge on the left wall near the ceiling: a shelf at y = 2.68 with a lip up to y = 2.76 at
# x = -2.82; 64 emitters (0.05 x 0.08, facing +x) stand on the shelf at x = -2.95. Their tops peek
# 2 cm over the lip: only points high up (the ceiling, the upper walls, the painting's top right
# corner) see a sliver of them.
SHELF_Y, LIP_X, LIP_TOP, LEDGE_X = 2.68, -2.82, 2.76, -2.95
LEDGE_N, LEDGE_Z0, LEDGE_Z1, LEDGE_HS, LEDGE_L = 64, -3.8, 1.8, (0.025, 0.04), 60.0
# The ledge emitters' radiance is the scene's default "ledge_radiance". Raising it with
# -D ledge_radiance="R, G, B" brightens a light that the lip hides from the painting: picking
# lights by their unshadowed contribution (RIS) gets harder there, and the painting's direct
# light stays the same.
LEDGE_RADIANCE = (LEDGE_L, LEDGE_L * 0.85, LEDGE_L * 0.6)


def num(x):
    """A coordinate as written in the XML: rounded to 1e-6, no trailing zeros, no '-0'."""
    s = ("%.6f" % x).rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def vec(v):
    return ", ".join(num(c) for c in v)


# Rotation taking the rectangle's +z normal to each facing, and which world half-extents
# (of the two in-plane axes) become the rectangle's local x and y half-sizes.
FACING = {
    "+z": ("", lambda hx, hy, hz: (hx, hy)),
    "-z": ('<rotate y="1" angle="180"/>', lambda hx, hy, hz: (hx, hy)),
    "+x": ('<rotate y="1" angle="90"/>', lambda hx, hy, hz: (hz, hy)),
    "-x": ('<rotate y="1" angle="-90"/>', lambda hx, hy, hz: (hz, hy)),
    "+y": ('<rotate x="1" angle="-90"/>', lambda hx, hy, hz: (hx, hz)),
    "-y": ('<rotate x="1" angle="90"/>', lambda hx, hy, hz: (hx, hz)),
}


class Xml:
    def __init__(self):
        self.lines = []

    def add(self, text, indent=1):
        for line in text.strip("\n").split("\n"):
            self.lines.append("    " * indent + line if line else "")

    def comment(self, text):
        self.add("")
        self.add("<!-- %s -->" % text)

    def rect(self, sid, lo, hi, facing, bsdf=None, radiance=None):
        """An axis-aligned rectangle spanning the box lo..hi (flat along its normal's axis)."""
        c = [(a + b) / 2 for a, b in zip(lo, hi)]
        h = [(b - a) / 2 for a, b in zip(lo, hi)]
        rot, pick = FACING[facing]
        sx, sy = pick(*h)
        body = ['<transform name="to_world">',
                '    <scale x="%s" y="%s" z="1"/>' % (num(sx), num(sy))]
        if rot:
            body.append("    " + rot)
        body.append('    <translate x="%s" y="%s" z="%s"/>' % tuple(num(v) for v in c))
        body.append("</transform>")
        self.shape("rectangle", sid, body, bsdf, radiance)

    def cube(self, sid, lo, hi, bsdf):
        c = [(a + b) / 2 for a, b in zip(lo, hi)]
        h = [(b - a) / 2 for a, b in zip(lo, hi)]
        body = ['<transform name="to_world">',
                '    <scale x="%s" y="%s" z="%s"/>' % tuple(num(v) for v in h),
                '    <translate x="%s" y="%s" z="%s"/>' % tuple(num(v) for v in c),
                "</transform>"]
        self.shape("cube", sid, body, bsdf, None)

    def shape(self, kind, sid, body, bsdf, radiance):
        self.add('<shape type="%s" id="%s">' % (kind, sid))
        self.add("\n".join(body), 2)
        if bsdf:
            self.add('<ref id="%s"/>' % bsdf, 2)
        if radiance is not None:
            value = radiance if isinstance(radiance, str) else vec(radiance)
            self.add('<emitter type="area">\n    <rgb name="radiance" value="%s"/>\n</emitter>'
                     % value, 2)
        self.add("</shape>")


def scene():
    x = Xml()
    x.add(HEADER % vec(LEDGE_RADIANCE), 0)
    x.comment("gallery: floor, ceiling, back wall, left wall and near wall, normals inward")
    x.rect("room-floor", (X0, 0, Z0), (X1, 0, Z1), "+y", "floor")
    x.rect("room-ceiling", (X0, Y1, Z0), (X1, Y1, Z1), "-y", "plaster")
    x.rect("room-back", (X0, 0, Z0), (X1, Y1, Z0), "+z", "plaster")
    x.rect("room-left", (X0, 0, Z0), (X0, Y1, Z1), "+x", "plaster")
    x.rect("room-near", (X0, 0, Z1), (X1, Y1, Z1), "-z", "plaster")
    x.comment("right wall (x = 3, two-sided: the side room sees its back) with the door gap "
              "z in [%s, %s], y < %s" % (num(DOOR_Z - DOOR_HW), num(DOOR_Z + DOOR_HW), num(DOOR_TOP)))
    x.rect("right-back", (X1, 0, Z0), (X1, Y1, DOOR_Z - DOOR_HW), "-x", "plaster-2s")
    x.rect("right-front", (X1, 0, DOOR_Z + DOOR_HW), (X1, Y1, Z1), "-x", "plaster-2s")
    x.rect("right-lintel", (X1, DOOR_TOP, DOOR_Z - DOOR_HW), (X1, Y1, DOOR_Z + DOOR_HW), "-x",
           "plaster-2s")
    x.comment("side room [3,%s] x [0,3] x [%s,2] behind the door gap" % (num(SIDE_X1), num(SIDE_Z0)))
    x.rect("side-floor", (X1, 0, SIDE_Z0), (SIDE_X1, 0, Z1), "+y", "floor")
    x.rect("side-ceiling", (X1, Y1, SIDE_Z0), (SIDE_X1, Y1, Z1), "-y", "plaster")
    x.rect("side-far", (SIDE_X1, 0, SIDE_Z0), (SIDE_X1, Y1, Z1), "-x", "plaster")
    x.rect("side-back", (X1, 0, SIDE_Z0), (SIDE_X1, Y1, SIDE_Z0), "+z", "plaster")
    x.rect("side-near", (X1, 0, Z1), (SIDE_X1, Y1, Z1), "-z", "plaster")
    c, hs = DOOR_LIGHT_C, DOOR_LIGHT_HS
    x.comment("side-room light: %s x %s at (%s), facing the door gap" % (num(2 * hs), num(2 * hs), vec(c)))
    x.shape("rectangle", "door-light",
            ['<transform name="to_world">',
             '    <scale x="%s" y="%s" z="1"/>' % (num(hs), num(hs)),
             '    <lookat origin="%s" target="%s" up="0, 1, 0"/>' % (vec(c), vec((X1, 1.1, DOOR_Z))),
             "</transform>"], None, (DOOR_LIGHT_L, DOOR_LIGHT_L * 0.93, DOOR_LIGHT_L * 0.8))

    x.comment("the painting in a dark frame on the back wall")
    (pcx, pcy), (phx, phy) = PAINT_C, PAINT_H
    x.cube("painting-frame", (pcx - phx - 0.06, pcy - phy - 0.06, Z0), (pcx + phx + 0.06, pcy + phy + 0.06, Z0 + 0.04),
           "frame")
    x.rect("painting-canvas", (pcx - phx, pcy - phy, Z0 + 0.045), (pcx + phx, pcy + phy, Z0 + 0.045), "+z",
           "painting")

    x.comment("three narrow spots (cutoff %s degrees) aimed beside and below the painting"
              % num(SPOT_CUTOFF))
    for i, (o, t) in enumerate(SPOTS):
        x.add('<emitter type="spot" id="spot-%d">' % i)
        x.add('<rgb name="intensity" value="%s"/>\n'
              '<float name="cutoff_angle" value="%s"/>\n'
              '<transform name="to_world">\n'
              '    <lookat origin="%s" target="%s" up="0, 1, 0"/>\n'
              "</transform>" % (vec((SPOT_INTENSITY,) * 3), num(SPOT_CUTOFF), vec(o), vec(t)), 2)
        x.add("</emitter>")

    (fx, fy, fz), (fhx, fhy) = FILL_C, FILL_H
    x.comment("dim fill: a %s x %s panel on the near wall, behind the camera" % (num(2 * fhx), num(2 * fhy)))
    x.rect("fill", (fx - fhx, fy - fhy, fz), (fx + fhx, fy + fhy, fz), "-z", None, (FILL_L,) * 3)

    x.comment("ledge on the left wall: shelf, lip, and %d small emitters behind the lip" % LEDGE_N)
    x.rect("ledge-shelf", (X0, SHELF_Y, LEDGE_Z0 - 0.1), (LIP_X, SHELF_Y, LEDGE_Z1 + 0.1), "-y", "ledge")
    x.rect("ledge-lip", (LIP_X, 2.6, LEDGE_Z0 - 0.1), (LIP_X, LIP_TOP, LEDGE_Z1 + 0.1), "+x", "ledge")
    hz, hy = LEDGE_HS
    for i in range(LEDGE_N):
        z = LEDGE_Z0 + (LEDGE_Z1 - LEDGE_Z0) * i / (LEDGE_N - 1)
        y = SHELF_Y + 0.02 + hy
        x.rect("ledge-light-%02d" % i, (LEDGE_X, y - hy, z - hz), (LEDGE_X, y + hy, z + hz), "+x", None,
               "$ledge_radiance")
    x.add("</scene>", 0)
    return ("\n".join(x.lines) + "\n").encode("utf-8")


HEADER = """<?xml version="1.0" encoding="utf-8"?>
<!-- Generated by scenes/gen_gallery.py; edit that script, not this file.
     A gallery where light sampling is hard, for benchmarking light-sample reuse (ReSTIR) in the
     adjoint pass. The painting (textures/painting.png, bsdf "painting") on the back wall is lit
     mostly by a dim fill panel behind the camera; the bright lights put little of their power on
     it: three narrow spots touch it with the soft edge of their cones only, a bright light in a
     side room reaches it through a narrow door gap as a thin stripe, and 64 small emitters on a
     ledge are hidden from it by the ledge's lip. Room [-3,3] x [0,3] x [-4,2]; max_depth 2
     (direct light only) is the benchmark's headline depth, -D max_depth=5 adds interreflection.
     -D fov=22 frames the painting alone, so that every texel is seen by some pixels even at a
     low resolution (at the default 65 degrees it spans 36 x 27 pixels of a 128^2 film).
     -D ledge_radiance="R, G, B" sets the 64 ledge emitters' radiance: the lip hides them from the
     painting, so brighter ones leave its direct light as it is and make light sampling by
     unshadowed contribution harder there. -->
<scene version="3.0.0">
    <default name="spp" value="64"/>
    <default name="res" value="256"/>
    <default name="max_depth" value="2"/>
    <default name="fov" value="65"/>
    <default name="ledge_radiance" value="%s"/>

    <integrator type="path">
        <integer name="max_depth" value="$max_depth"/>
    </integrator>

    <sensor type="perspective">
        <float name="fov" value="$fov"/>
        <transform name="to_world">
            <lookat origin="0, 1.45, 1.7" target="0, 1.4, -4" up="0, 1, 0"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/>
            <integer name="height" value="$res"/>
        </film>
    </sensor>

    <bsdf type="diffuse" id="plaster">
        <rgb name="reflectance" value="0.75, 0.73, 0.7"/>
    </bsdf>
    <bsdf type="twosided" id="plaster-2s">
        <ref id="plaster"/>
    </bsdf>
    <bsdf type="diffuse" id="floor">
        <rgb name="reflectance" value="0.4, 0.3, 0.22"/>
    </bsdf>
    <bsdf type="twosided" id="ledge">
        <bsdf type="diffuse">
            <rgb name="reflectance" value="0.6, 0.6, 0.62"/>
        </bsdf>
    </bsdf>
    <bsdf type="twosided" id="frame">
        <bsdf type="diffuse">
            <rgb name="reflectance" value="0.12, 0.09, 0.06"/>
        </bsdf>
    </bsdf>
    <bsdf type="diffuse" id="painting">
        <texture type="bitmap" name="reflectance">
            <string name="filename" value="textures/painting.png"/>
            <!-- v = 0 is the file's first row; flip so the image stands upright on the wall -->
            <transform name="to_uv">
                <scale x="1" y="-1"/>
            </transform>
        </texture>
    </bsdf>"""


def main(argv):
    if len(argv) != 2:
        sys.stderr.write("usage: python3 %s OUTDIR\n" % argv[0])
        return 2
    out = argv[1]
    os.makedirs(out, exist_ok=True)
    write_atomic(out, "gallery-lights.xml", scene())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
