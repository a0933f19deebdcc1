#!/usr/bin/env python3
"""The furnace of participating media, per pixel: a non-absorbing ball (albedo 1, chromatic
extinction, Henyey-Greenstein g) in a unit sky with unbounded depth must render 1 everywhere.
Renders --seeds independent images with `tandem render` and reports, per pixel and channel, the
deviation of their mean from 1 against its standard error over the seeds.

    bench/media_furnace.py [--tandem build/tandem] [--res 16] [--spp 16384] [--seeds 16]
                           [--sigma-t "0.5, 1, 2"] [--g 0.7]

Reads the EXR images with OpenImageIO's Python module if it is there, else with Mitsuba's
(bench/.venv-mitsuba: run this script with that venv's python).
"""
import argparse
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

SCENE = """<scene version="3.0.0">
  <integrator type="volpath"><integer name="max_depth" value="-1"/></integrator>
  <sensor type="perspective"><float name="fov" value="20"/>
    <transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="{res}"/><integer name="height" value="{res}"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
  <medium type="homogeneous" id="m"><rgb name="sigma_t" value="{sigma_t}"/>
    <float name="albedo" value="1"/><phase type="hg"><float name="g" value="{g}"/></phase></medium>
  <shape type="sphere"><point name="center" x="0" y="0" z="4"/><bsdf type="null"/>
    <ref name="interior" id="m"/></shape>
</scene>
"""


def read_exr(path):
    try:
        import OpenImageIO as oiio
        return np.asarray(oiio.ImageBuf(path).get_pixels(oiio.FLOAT))[..., :3]
    except ImportError:
        import mitsuba as mi
        mi.set_variant("scalar_rgb")
        return np.array(mi.Bitmap(path))[..., :3]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tandem", default=os.path.join(HERE, "..", "build", "tandem"))
    ap.add_argument("--res", type=int, default=16)
    ap.add_argument("--spp", type=int, default=16384)
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--sigma-t", default="0.5, 1, 2")
    ap.add_argument("--g", type=float, default=0.7)
    a = ap.parse_args()
    if a.seeds < 2:
        sys.exit("--seeds must be at least 2 (the standard error needs them)")
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "furnace.xml")
        open(scene, "w").write(SCENE.format(res=a.res, sigma_t=a.sigma_t, g=a.g))
        images = []
        for s in range(a.seeds):
            out = os.path.join(tmp, f"furnace-{s}.exr")
            subprocess.run([a.tandem, "render", scene, "--spp", str(a.spp), "--seed", str(s),
                            "--out", out], check=True, capture_output=True)
            images.append(read_exr(out))
    images = np.stack(images).astype(np.float64)
    mean = images.mean(0)
    se = images.std(0, ddof=1) / math.sqrt(a.seeds)
    dev = np.abs(mean - 1.0)
    z = dev / np.maximum(se, 1e-12)
    print(f"furnace: {a.res}x{a.res}, {a.seeds} seeds x {a.spp} spp = {a.seeds * a.spp} spp per "
          f"pixel; sigma_t ({a.sigma_t}), albedo 1, g {a.g}, unbounded depth")
    print(f"channel means: {' / '.join(f'{m:.5f}' for m in mean.mean(axis=(0, 1)))}")
    print(f"per pixel |mean - 1|: mean {100 * dev.mean():.3f} %, max {100 * dev.max():.3f} %")
    print(f"per pixel standard error: median {100 * np.median(se):.3f} %, max {100 * se.max():.3f} %")
    print(f"beyond 3 standard errors: {100 * (z > 3).mean():.2f} % of values (max z {z.max():.2f})")
    print(f"every pixel within 0.5 %: {'yes' if dev.max() <= 0.005 else 'no'}")


if __name__ == "__main__":
    main()
