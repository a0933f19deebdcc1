"""Shapes from Python: vertex positions as (V, 3) arrays read and written through, faces, the
per-vertex gradient against the CLI's .npy, and the Large Steps helper against its definition."""

import numpy as np
import pytest

import tandem
from conftest import ROOT, run_cli

TEST_SCENES = ROOT / "tests" / "scenes"


def test_vertex_positions_faces_and_gradients(tmp):
    path = str(TEST_SCENES / "shape-emitter-black.xml")
    s = tandem.load(path, res=16)
    name = "light.vertex_positions"
    x = s.params[name].value
    assert x.shape == (4, 3) and x.dtype == np.float32
    faces = s.faces(name)
    assert faces.shape == (2, 3) and faces.dtype == np.uint32 and faces.max() == 3
    # the gradient is the CLI's, bit for bit
    out = tmp / "g.npy"
    run_cli("grad", path, "-D", "res=16", "--param", name, "--spp", 4, "--seed", 3,
            "--out-grad", out)
    _, grads = s.grad(params=name, spp=4, seed=3)
    assert grads[name].shape == (4, 3)
    assert np.array_equal(grads[name], np.load(out))
    # written through: the scene moves (a shift left by 0.25 renders as the scene built there)
    s.params[name].value = x - np.float32([0.25, 0, 0])
    there = tandem.load(path, res=16, x=1.0)
    assert np.array_equal(s.render(spp=4, seed=1), there.render(spp=4, seed=1))


def test_large_steps_helper():
    s = tandem.load(str(TEST_SCENES / "shape-emitter-black.xml"), res=8)
    name = "light.vertex_positions"
    x, faces = s.params[name].value, s.faces(name)
    ls = tandem.LargeSteps(x, faces, lam=19.0)
    assert ls.points == 4 and ls.lam == 19.0
    # (I + lam L) for the square of two triangles, written out: degrees 3, 2, 3, 2 (a diagonal)
    lap = np.zeros((4, 4))
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            lap[a, b] = lap[b, a] = -1.0
    np.fill_diagonal(lap, -lap.sum(axis=1))
    m = np.eye(4) + 19.0 * lap
    u = ls.to_differential(x)
    np.testing.assert_allclose(u, m @ x, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(ls.from_differential(u), x, rtol=1e-5, atol=1e-5)
    g = np.arange(12, dtype=np.float32).reshape(4, 3)
    np.testing.assert_allclose(ls.gradient(g), np.linalg.solve(m, g), rtol=1e-5, atol=1e-6)


def test_large_steps_image():
    # (I + lam L) of a 2 x 3 texel grid, four neighbours each, written out
    h, w, lam = 2, 3, 4.0
    ls = tandem.LargeSteps.image(h, w, channels=3, lam=lam)
    assert ls.points == h * w and ls.channels == 3
    lap = np.zeros((h * w, h * w))
    for y in range(h):
        for x in range(w):
            for dy, dx in ((0, 1), (1, 0)):
                if y + dy < h and x + dx < w:
                    a, b = y * w + x, (y + dy) * w + x + dx
                    lap[a, b] = lap[b, a] = -1.0
    np.fill_diagonal(lap, -lap.sum(axis=1))
    m = np.eye(h * w) + lam * lap
    g = np.sin(np.arange(h * w * 3, dtype=np.float32)).reshape(h, w, 3)
    np.testing.assert_allclose(ls.gradient(g), np.linalg.solve(m, g.reshape(-1, 3)),
                               rtol=1e-5, atol=1e-6)
    u = ls.to_differential(g)
    np.testing.assert_allclose(u, m @ g.reshape(-1, 3), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(ls.from_differential(u), g.reshape(-1, 3), rtol=1e-5, atol=1e-5)


def test_boundary_reuse():
    """Scene.set_boundary_reuse: the secondary term's reservoirs carried from one grad() to the
    next, deterministic, dropped by False; bad settings refused naming the field. (Its mean is
    tests/core/inverse/test_boundary_reuse.cpp's.)"""
    path = str(TEST_SCENES / "shape-sphere-lights.xml")
    name = "occluder.vertex_positions"

    def grads(s, seeds):
        return [s.grad(params=name, spp=4, seed=k)[1][name] for k in seeds]

    plain = tandem.load(path, res=9)
    with pytest.raises(ValueError, match=r"restir=True"):
        plain.set_boundary_reuse()
    s = tandem.load(path, res=9, restir=True)
    for bad, field in (({"candidates": 0}, "candidates"), ({"neighbors": 2}, "neighbors"),
                       ({"cell": "small"}, "cell"), ({"m_cap": float("nan")}, "non-finite")):
        with pytest.raises(ValueError, match=f"^set_boundary_reuse: .*{field}"):
            s.set_boundary_reuse(bad)
    # without reuse a restir=True scene gives the plain scene's bits
    ref = grads(plain, [1, 2])
    assert all(np.array_equal(a, b) for a, b in zip(grads(s, [1, 2]), ref))
    s.set_boundary_reuse({"candidates": 4})
    chain = grads(s, [1, 2])
    assert not np.array_equal(chain[0], ref[0])  # the reuse is there
    # the second gradient reads the first's reservoirs: a fresh set at its seed gives other bits
    s.set_boundary_reuse({"candidates": 4})
    fresh = grads(s, [2])[0]
    assert not np.array_equal(fresh, chain[1])
    # deterministic: the same chain again, on another scene object, the same bits
    # (boundary samples set between the two keep the reservoirs)
    t = tandem.load(path, res=9, restir=True)
    t.set_boundary_reuse({"candidates": 4})
    assert np.array_equal(grads(t, [1])[0], chain[0])
    t.set_boundary_samples(secondary=-1)
    assert np.array_equal(grads(t, [2])[0], chain[1])
    # False drops them: the plain bits again
    t.set_boundary_reuse(False)
    assert np.array_equal(grads(t, [2])[0], ref[1])
