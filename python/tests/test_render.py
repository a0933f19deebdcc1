"""Rendering from Python is the CLI's rendering, bit for bit."""

import numpy as np
import pytest

import tandem
from conftest import SCENES, run_cli


def test_devices_lists_what_the_cli_lists():
    from conftest import cli_json

    assert tandem.devices() == cli_json("devices")


@pytest.mark.parametrize("scene", ["cbox.xml", "cbox-wall.xml", "three-spheres.xml",
                                   "indirect-room.xml", "env-probe.xml", "gallery-lights.xml",
                                   "media-cube.xml", "media-plume.xml"])
def test_render_equals_cli_bit_for_bit(scene, tmp):
    out = tmp / "cli.exr"
    run_cli("render", SCENES / scene, "-D", "res=16", "--spp", 8, "--seed", 11, "--out", out)
    expected = tandem.read_image(str(out))

    s = tandem.load(str(SCENES / scene), res=16)
    image = s.render(spp=8, seed=11)
    assert image.shape == (16, 16, 3) and image.dtype == np.float32
    assert image.flags.c_contiguous and image.flags.owndata is False  # wraps the host vector
    assert np.array_equal(image, expected), f"{scene}: {np.sum(image != expected)} elements differ"


def test_media_gradients_and_grids_as_arrays(tmp):
    """Media are differentiated (backward equals tandem grad bit for bit), a grid is a (D, H, W)
    array that reads and writes through, and the fused two-state render runs on media (equal states:
    both images are the primal render's bits)."""
    s = tandem.load(str(SCENES / "media-plume.xml"), res=8)
    image = s.render(spp=2, seed=3)
    f, h = s.render_two_state(spp=2, seed=3)
    assert np.array_equal(f, image) and np.array_equal(h, image)
    density = s.params["plume.sigma_t"]
    assert "volume" in repr(density) and density.shape == (32, 32, 32)
    grid = density.value
    assert grid.shape == (32, 32, 32) and grid.dtype == np.float32 and grid.max() > 0
    density.value = grid * np.float32(0.5)
    assert np.array_equal(density.value, grid * np.float32(0.5))
    assert not np.array_equal(s.render(spp=2, seed=3), image)  # the majorants follow the voxels
    density.value = grid
    assert np.array_equal(s.render(spp=2, seed=3), image)
    with pytest.raises(ValueError, match="expected shape"):
        density.value = np.zeros((32, 32, 31), np.float32)

    loss, grads = s.grad("mean", None, ["plume.sigma_t", "plume.scale"], spp=2, spp_grad=2, seed=5)
    assert grads["plume.sigma_t"].shape == (32, 32, 32)
    assert np.count_nonzero(grads["plume.sigma_t"]) > 100
    out = tmp / "grad.vol"
    run_cli("grad", SCENES / "media-plume.xml", "-D", "res=8", "--param", "plume.sigma_t",
            "--spp", 2, "--spp-grad", 2, "--seed", 5, "--out-grad", out)
    from_cli = np.fromfile(out, dtype=np.float32, offset=48).reshape(32, 32, 32)
    assert np.array_equal(from_cli, grads["plume.sigma_t"])


def test_render_is_deterministic_and_seeded():
    s = tandem.load(str(SCENES / "cbox.xml"), res=16)
    a, b, c = s.render(4, 1), s.render(4, 1), s.render(4, 2)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_scene_properties_and_defines():
    s = tandem.load(SCENES / "cbox.xml", res=24, spp=3, max_depth=2)  # a pathlib.Path too
    assert (s.width, s.height, s.spp) == (24, 24, 3)
    assert s.render().shape == (24, 24, 3)  # spp 0: the scene's
    assert s.device["name"] == tandem.devices()[0]["name"]
    assert "cbox.xml" in repr(s)


def test_params_mapping_matches_tandem_params():
    from conftest import cli_json

    s = tandem.load(str(SCENES / "cbox-wall.xml"), res=16)
    listed = cli_json("params", SCENES / "cbox-wall.xml", "-D", "res=16")
    names = [p["name"] for p in listed]
    assert list(s.params) == names
    assert len(s.params) == len(names)
    assert dict(s.params.items()).keys() == set(names)
    assert "wall.reflectance" in s.params and "nope" not in s.params and 3 not in s.params
    wall = s.params["wall.reflectance"]
    assert (wall.kind, wall.shape, wall.range) == ("texture", (256, 256, 3), (0.0, 1.0))
    assert wall.value.shape == (256, 256, 3) and wall.value.dtype == np.float32
    light = s.params["light.emitter.radiance"]
    assert light.kind == "rgb" and light.shape == (3,) and light.value.shape == (3,)
    with pytest.raises(KeyError, match="nope.*known: white.reflectance"):
        s.params["nope"]


def test_assignment_writes_through_to_the_render():
    s = tandem.load(str(SCENES / "cbox.xml"), res=16)
    red = s.params["red.reflectance"]
    before = s.render(4, 0)
    old = red.value
    red.value = [0.1, 0.9, 0.1]
    assert np.array_equal(red.value, np.float32([0.1, 0.9, 0.1]))
    changed = s.render(4, 0)
    assert not np.array_equal(before, changed)
    red.value = old
    assert np.array_equal(s.render(4, 0), before)  # the same bits again


def test_texture_assignment_forms():
    s = tandem.load(str(SCENES / "cbox-wall.xml"), res=16)
    wall = s.params["wall.reflectance"]
    wall.value = 0.25  # every element
    assert np.all(wall.value == np.float32(0.25))
    wall.value = [0.1, 0.2, 0.3]  # one rgb for every texel
    assert np.array_equal(wall.value[7, 9], np.float32([0.1, 0.2, 0.3]))
    texels = np.random.default_rng(1).random((256, 256, 3))  # float64: converted
    wall.value = texels
    assert np.array_equal(wall.value, texels.astype(np.float32))
    wall.value = np.asfortranarray(texels.astype(np.float32))  # another layout: converted
    assert np.array_equal(wall.value, texels.astype(np.float32))


def test_images_round_trip_through_files(tmp):
    rng = np.random.default_rng(2)
    image = rng.random((5, 7, 3), dtype=np.float32)
    tandem.write_image(str(tmp / "a.exr"), image)
    assert np.array_equal(tandem.read_image(str(tmp / "a.exr")), image)
    tandem.write_image(str(tmp / "a.png"), image)
    assert np.abs(tandem.read_image(str(tmp / "a.png")) - image).max() < 0.01


class DLPackOnly:
    """An array that offers nothing but DLPack, as a PyTorch CPU tensor does."""

    def __init__(self, array):
        self._array = array

    def __dlpack__(self, **kwargs):
        return self._array.__dlpack__(**kwargs)

    def __dlpack_device__(self):
        return self._array.__dlpack_device__()


def test_dlpack_arrays_are_accepted():
    s = tandem.load(str(SCENES / "cbox.xml"), res=16)
    image = s.render(4, 0)
    delta = np.full_like(image, 1.0 / image.size)
    via_numpy = s.backward(delta, spp=2, seed=5, params="red.reflectance")
    via_dlpack = s.backward(DLPackOnly(delta), spp=2, seed=5, params="red.reflectance")
    assert np.array_equal(via_numpy["red.reflectance"], via_dlpack["red.reflectance"])
    s.params["red.reflectance"].value = DLPackOnly(np.float32([0.2, 0.3, 0.4]))
    assert np.array_equal(s.params["red.reflectance"].value, np.float32([0.2, 0.3, 0.4]))


def test_device_work_releases_the_gil():
    import threading
    import time

    s = tandem.load(str(SCENES / "cbox.xml"), res=64)
    s.render(1, 0)  # kernels built
    done = threading.Event()
    ticks = 0

    def work():
        s.render(256, 0)
        done.set()

    t = threading.Thread(target=work)
    t.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    t.join()
    # With the GIL held for the whole render this loop could not run at all.
    assert ticks > 20, ticks


def test_type_stubs_are_generated():
    import pathlib

    stub = pathlib.Path(tandem.__file__).with_name("_tandem.pyi")
    text = stub.read_text()
    for name in ("def load(", "class Scene", "def backward(", "class ControlVariate",
                 "class Optimizer", "def optimize("):
        assert name in text, name
