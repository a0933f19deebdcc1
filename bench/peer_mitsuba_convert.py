#!/usr/bin/env python3
"""Tandem scene XML -> Mitsuba 3 XML, with the same images: part of bench/peer_mitsuba.py.

    bench/peer_mitsuba_convert.py SCENE.xml [-D name=value]... [--integrator path|prb|prb_projective]
                                  [--square-obj FILE] [> OUT.xml]

Tandem reads a subset of Mitsuba 3's format (core/scene/scene.cpp). The same file means the same
scene in both, except where the two renderers' defaults differ; this makes those explicit:

- `<default>` variables and `$name` are resolved here, with the same -D overrides Tandem takes,
  and the `<default>` tags dropped: both renderers see the same numbers.
- The film gets `<rfilter type="box"/>` (Tandem always filters with a box, one pixel per sample;
  Mitsuba's default is a Gaussian). A sensor without a film gets Mitsuba's default 768x576
  `hdrfilm`, which is also Tandem's.
- `roughconductor` and `roughplastic` get `distribution="ggx"` (Tandem has GGX only; Mitsuba's
  default is Beckmann).
- Files (`filename`) become absolute paths, so the output can live anywhere.
- `--integrator prb` turns the `path` integrator into Mitsuba's `prb` (path replay
  backpropagation, the method Tandem's gradients use), with the same max_depth and rr_depth.
  Scenes with media keep `volpath` (`prbvolpath` with `--integrator prb`).
- `--integrator prb_projective` gives Mitsuba's PRB with projective sampling of visibility
  boundaries, for shape gradients (bench/peer_shape.py); with `--square-obj FILE` (FILE: a square
  written by write_square_obj) each `rectangle` becomes that mesh under the same transform, so
  that Mitsuba has its `vertex_positions` (its rectangle is not a mesh), with Mitsuba's texture
  coordinates.

- Bitmap textures get `format="variant"`: 32-bit float texels, as Tandem stores them (decoded
  from sRGB to linear at load unless `raw`). Mitsuba 3.9's default (`auto`) keeps an 8-bit file
  in 8-bit texels, which cannot be optimized.

Any tag or plugin type outside the subset both renderers share is refused with its line number,
rather than converted into something that might differ.
"""
import argparse
import os
import re
import sys
import xml.etree.ElementTree as ET
from xml.parsers import expat

# The plugin types Tandem reads (core/scene/scene.cpp), by tag. All of them exist in Mitsuba 3
# under the same name with the same parameters.
SUPPORTED = {
    "integrator": {"path", "volpath", "prbvolpath"},
    "sensor": {"perspective"},
    "film": {"hdrfilm"},
    "rfilter": {"box"},
    "sampler": {"independent"},
    "shape": {"obj", "ply", "rectangle", "cube", "sphere", "disk"},
    "bsdf": {"diffuse", "conductor", "roughconductor", "dielectric", "roughplastic", "twosided",
             "null"},
    "texture": {"bitmap", "checkerboard"},
    "emitter": {"area", "point", "spot", "constant", "envmap"},
    "medium": {"homogeneous", "heterogeneous"},
    "phase": {"isotropic", "hg"},
    "volume": {"constvolume", "gridvolume"},
}
PROPERTY_TAGS = {"float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector",
                 "transform", "ref"}
TRANSFORM_TAGS = {"translate", "scale", "rotate", "matrix", "lookat"}


INTEGRATORS = ("path", "prb", "prb_projective")


def write_square_obj(path):
    """Mitsuba's rectangle as an OBJ: [-1, 1]^2 at z = 0, normal +z, two triangles; uv (0, 0) at
    (-1, -1), written as vt with v flipped, since Mitsuba's OBJ reader flips it back."""
    with open(path, "w") as f:
        f.write("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                "vt 0 1\nvt 1 1\nvt 1 0\nvt 0 0\n"
                "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")


class ConvertError(Exception):
    """A construct the converter cannot carry over; the message names the file and line."""


def parse_with_lines(path):
    """ElementTree of `path`, and a map from each element to its line number."""
    builder = ET.TreeBuilder()
    parser = expat.ParserCreate()
    lines = {}

    def start(tag, attrs):
        lines[builder.start(tag, attrs)] = parser.CurrentLineNumber

    parser.StartElementHandler = start
    parser.EndElementHandler = builder.end
    parser.CharacterDataHandler = builder.data
    try:
        with open(path, "rb") as f:
            parser.ParseFile(f)
    except expat.ExpatError as e:
        raise ConvertError(f"{path}:{e.lineno}: malformed XML: {expat.ErrorString(e.code)}")
    return builder.close(), lines


class Converter:
    def __init__(self, path, defines, integrator="path", square_obj=None):
        self.path = path
        self.dir = os.path.dirname(os.path.abspath(path))
        self.defines = dict(defines)
        self.integrator = integrator
        self.square_obj = square_obj

    def fail(self, element, what):
        raise ConvertError(f"{self.path}:{self.lines.get(element, '?')}: {what}")

    def describe(self, e):
        attrs = "".join(f' {k}="{e.get(k)}"' for k in ("type", "name", "id") if e.get(k))
        return f"<{e.tag}{attrs}>"

    def convert(self):
        root, self.lines = parse_with_lines(self.path)
        if root.tag != "scene":
            self.fail(root, f"the root tag must be <scene>, not <{root.tag}>")
        # Step 1: <default> variables (a -D define wins), then $name everywhere.
        variables = {}
        for d in root.findall("default"):
            variables.setdefault(d.get("name"), d.get("value"))
            root.remove(d)
        variables.update(self.defines)
        for e in root.iter():
            if e.tag == "default":
                self.fail(e, "<default> is only allowed directly inside <scene>")
            for key, value in e.attrib.items():
                e.set(key, self.substitute(e, key, value, variables))
        # Step 2: check every tag against the shared subset, then make the defaults explicit.
        self.check(root, inside_transform=False)
        for e in root.iter():
            if e.tag == "sensor":
                self.film_with_box_filter(e)
            elif e.tag == "bsdf" and e.get("type") in ("roughconductor", "roughplastic"):
                if not any(p.get("name") == "distribution" for p in e.findall("string")):
                    ET.SubElement(e, "string", name="distribution", value="ggx")
            elif e.tag == "texture" and e.get("type") == "bitmap":
                if not any(p.get("name") == "format" for p in e.findall("string")):
                    ET.SubElement(e, "string", name="format", value="variant")
            elif e.tag == "integrator":
                # a volumetric scene keeps its volpath (prbvolpath for gradients)
                volumetric = e.get("type") in ("volpath", "prbvolpath")
                e.set("type", ("prbvolpath" if self.integrator == "prb" else "volpath")
                      if volumetric else self.integrator)
            elif e.tag == "shape" and e.get("type") == "rectangle" and self.square_obj:
                e.set("type", "obj")
                ET.SubElement(e, "string", name="filename", value=os.path.abspath(self.square_obj))
            elif e.tag == "string" and e.get("name") == "filename":
                e.set("value", os.path.normpath(os.path.join(self.dir, e.get("value"))))
        ET.indent(root, space="    ")
        return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, "unicode") + "\n"

    def substitute(self, e, key, value, variables):
        def one(m):
            name = m.group(1)
            if name not in variables:
                self.fail(e, f"{self.describe(e)}: attribute '{key}' uses undefined ${name}")
            return variables[name]

        return re.sub(r"\$([A-Za-z0-9_]*)", one, value)

    def check(self, parent, inside_transform):
        for e in parent:
            if inside_transform:
                if e.tag not in TRANSFORM_TAGS:
                    self.fail(e, f"unknown tag <{e.tag}> inside <transform>")
                continue
            if e.tag in SUPPORTED:
                if e.get("type") not in SUPPORTED[e.tag]:
                    self.fail(e, f"{self.describe(e)}: cannot convert {e.tag} type "
                                 f"'{e.get('type')}' (the shared subset has: "
                                 f"{', '.join(sorted(SUPPORTED[e.tag]))})")
                if e.tag == "integrator" and self.integrator not in INTEGRATORS:
                    self.fail(e, f"unknown integrator '{self.integrator}' "
                                 f"({', '.join(INTEGRATORS)})")
            elif e.tag not in PROPERTY_TAGS:
                self.fail(e, f"cannot convert <{e.tag}> inside <{parent.tag}>")
            self.check(e, inside_transform=e.tag == "transform")

    def film_with_box_filter(self, sensor):
        films = sensor.findall("film")
        if not films:
            films = [ET.SubElement(sensor, "film", type="hdrfilm")]
        for film in films:
            if film.find("rfilter") is None:
                ET.SubElement(film, "rfilter", type="box")


def convert_file(path, defines=(), integrator="path", square_obj=None):
    """The Mitsuba 3 XML text of the Tandem scene `path` with -D `defines` (name, value) pairs."""
    return Converter(path, defines, integrator, square_obj).convert()


def parse_define(text):
    name, eq, value = text.partition("=")
    if not eq or not name:
        raise argparse.ArgumentTypeError(f"-D {text}: expected name=value")
    return name, value


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("-D", dest="defines", action="append", type=parse_define, default=[],
                    metavar="NAME=VALUE", help="override a <default> (repeatable)")
    ap.add_argument("--integrator", choices=INTEGRATORS, default="path")
    ap.add_argument("--square-obj", help="rectangles become this mesh (write_square_obj)")
    args = ap.parse_args()
    try:
        sys.stdout.write(convert_file(args.scene, args.defines, args.integrator, args.square_obj))
    except ConvertError as e:
        sys.exit(f"peer_mitsuba_convert: {e}")


if __name__ == "__main__":
    main()
