"""Gradients taken through Python: the CLI's bits, and finite differences."""

import json

import numpy as np
import pytest

import tandem
from conftest import ROOT, SCENES, run_cli

TEST_SCENES = ROOT / "tests" / "scenes"


def l2_delta(image, ref):
    """d/dimage of mean((image - ref)^2), in the device's float32 operation order
    (kernels/shared/loss.h: 2 e inv_n with inv_n = 1 / count)."""
    inv_n = np.float32(1.0) / np.float32(image.size)
    return np.float32(2.0) * (image - ref) * inv_n


@pytest.fixture
def reference(tmp):
    """A reference image of cbox-wall at 16x16 written by the CLI, and its path."""
    path = tmp / "ref.exr"
    run_cli("render", SCENES / "cbox-wall.xml", "-D", "res=16", "--spp", 16, "--seed", 99,
            "--out", path)
    return path


def cli_grad(reference, tmp, *params, seed=5):
    """tandem grad with an L2 loss: (JSON, the wall texture's gradient image or None)."""
    args = ["grad", SCENES / "cbox-wall.xml", "-D", "res=16", "--loss", "l2", "--ref", reference,
            "--spp", 4, "--spp-grad", 4, "--seed", seed, "--json"]
    for p in params:
        args += ["--param", p]
    out = tmp / "grad.exr"
    if params == ("wall.reflectance",):
        args += ["--out-grad", out]
    j = json.loads(run_cli(*args).stdout)
    return j, (tandem.read_image(str(out)) if params == ("wall.reflectance",) else None)


def test_backward_of_a_numpy_l2_delta_equals_tandem_grad(reference, tmp):
    ref = tandem.read_image(str(reference))
    s = tandem.load(str(SCENES / "cbox-wall.xml"), res=16)
    seed = 5
    image = s.render(spp=4, seed=tandem.primal_seed(seed, 0))
    delta = l2_delta(image, ref)

    params = ["red.reflectance", "light.emitter.radiance"]
    j, _ = cli_grad(reference, tmp, *params, seed=seed)
    grads = s.backward(delta, spp=4, seed=tandem.adjoint_seed(seed, 0), params=params)
    assert sorted(grads) == sorted(params)
    for entry in j["parameters"]:
        expected = np.float32(entry["gradient"])
        assert np.array_equal(grads[entry["name"]], expected), entry["name"]
        assert np.any(expected != 0)

    _, texture = cli_grad(reference, tmp, "wall.reflectance", seed=seed)
    g = s.backward(delta, spp=4, seed=tandem.adjoint_seed(seed, 0), params="wall.reflectance")
    assert g["wall.reflectance"].shape == (256, 256, 3)
    assert np.array_equal(g["wall.reflectance"], texture)
    assert np.count_nonzero(texture) > 1000


def test_builtin_grad_equals_tandem_grad(reference, tmp):
    ref = tandem.read_image(str(reference))
    s = tandem.load(str(SCENES / "cbox-wall.xml"), res=16)
    params = ["red.reflectance", "light.emitter.radiance"]
    j, _ = cli_grad(reference, tmp, *params, seed=7)
    loss, grads = s.grad("l2", ref, params, spp=4, spp_grad=4, seed=7)
    assert loss == np.float32(j["loss_value"])
    for entry in j["parameters"]:
        assert np.array_equal(grads[entry["name"]], np.float32(entry["gradient"])), entry["name"]


def test_backward_is_linear_in_delta_and_deterministic():
    s = tandem.load(str(SCENES / "cbox.xml"), res=16)
    delta = np.random.default_rng(3).standard_normal((16, 16, 3)).astype(np.float32) * 1e-3
    a = s.backward(delta, spp=2, seed=1)
    b = s.backward(delta, spp=2, seed=1)
    c = s.backward(delta * np.float32(4.0), spp=2, seed=1)
    for name in a:
        assert np.array_equal(a[name], b[name])
        # the fixed-point scale follows delta: 4 delta gives exactly 4 times the gradient
        assert np.array_equal(c[name], a[name] * np.float32(4.0)), name
    # params=None: every parameter but meshes' vertex positions
    assert sorted(a) == sorted(k for k in s.params if not k.endswith(".vertex_positions"))


def test_central_finite_differences_through_python():
    """d/dtheta of an L2 loss written in NumPy: PRB (mean of 4 adjoint seeds) against central
    differences with common random numbers, for the sky radiance and for every texel of a
    texture scaled together, on a plane lit by the sky (max_depth 2)."""
    s = tandem.load(str(TEST_SCENES / "grad-texture.xml"), res=16)
    sky, paint = s.params["sky.radiance"], s.params["paint.reflectance"]
    paint.value = paint.value * np.float32(0.9)  # room to move up within [0, 1]
    sky0, paint0 = sky.value, paint.value
    sky.value = sky0 * np.float32(0.7)
    ref = s.render(spp=64, seed=1000)
    sky.value = sky0

    spp, seed = 256, 17

    def loss():
        image = s.render(spp=spp, seed=seed).astype(np.float64)
        return np.mean((image - ref) ** 2)

    image = s.render(spp=spp, seed=seed)
    delta = l2_delta(image, ref)
    grads = [s.backward(delta, spp=64, seed=100 + k) for k in range(4)]
    prb_sky = np.mean([g["sky.radiance"] for g in grads], axis=0)
    # the texture moves along paint0 (every texel scaled by 1 + t): d/dt = sum(grad * paint0)
    prb_paint = np.mean([np.sum(g["paint.reflectance"].astype(np.float64) * paint0)
                         for g in grads])

    h = 1e-2
    for c in range(3):
        v = sky0.copy()
        v[c] += h
        sky.value = v
        up = loss()
        v[c] -= 2 * h
        sky.value = v
        down = loss()
        fd = (up - down) / (2 * h)
        assert prb_sky[c] == pytest.approx(fd, rel=0.01), (c, prb_sky[c], fd)
    sky.value = sky0

    h = 1e-2
    assert paint0.max() * (1 + h) <= 1, "the texture must stay in range"
    paint.value = paint0 * np.float32(1 + h)
    up = loss()
    paint.value = paint0 * np.float32(1 - h)
    down = loss()
    fd = (up - down) / (2 * h)
    assert prb_paint == pytest.approx(fd, rel=0.01), (prb_paint, fd)
