"""Tandem: a portable inverse path tracer (OpenCL), from Python.

The same core as the ``tandem`` command line: a render, a gradient or an optimization run here is
the CLI's bit for bit. Images are float32 NumPy arrays (height, width, 3), linear RGB, row-major
from the top left. Inputs may be NumPy arrays, PyTorch CPU tensors or anything else that speaks
DLPack or the buffer protocol (float32 C-contiguous ones are read without a copy).

    import tandem
    scene = tandem.load("scenes/cbox-wall.xml", res=64)
    ref = scene.render(spp=64, seed=1)
    wall = scene.params["wall.reflectance"]
    wall.value = 0.5                                  # a flat grey start
    opt = tandem.Optimizer(scene, {wall.name: 0.02})
    for it in range(50):
        img = scene.render(spp=4, seed=tandem.primal_seed(0, it))
        delta = 2 * (img - ref) / img.size            # d(mean squared error)/d(image)
        scene.backward(delta, spp=4, seed=tandem.adjoint_seed(0, it), params=wall.name)
        opt.step()

Errors in the input raise ValueError with the CLI's one-line message; failures of the device
(no OpenCL device, out of memory, a kernel build) raise RuntimeError.
"""

from collections.abc import Mapping as _Mapping

from ._tandem import (
    ControlVariate,
    LargeSteps,
    Optimizer,
    Parameter,
    Params,
    Scene,
    adjoint_seed,
    devices,
    load,
    optimize,
    primal_seed,
    read_image,
    surface_distance,
    write_image,
)

# scene.params behaves as a read-only mapping: keys(), items(), values(), get(), in, len.
_Mapping.register(Params)
for _name in ("keys", "items", "values", "get", "__eq__", "__ne__"):
    setattr(Params, _name, getattr(_Mapping, _name))
del _name

__version__ = "0.1.0"

__all__ = [
    "ControlVariate",
    "LargeSteps",
    "Optimizer",
    "Parameter",
    "Params",
    "Scene",
    "adjoint_seed",
    "devices",
    "load",
    "optimize",
    "primal_seed",
    "read_image",
    "surface_distance",
    "write_image",
]
