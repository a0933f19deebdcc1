"""Bad input raises ValueError and device failures RuntimeError, with the CLI's one-line
messages; nothing brings the interpreter down."""

import os
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import tandem
from conftest import ROOT, SCENES, cli_error

TEST_SCENES = ROOT / "tests" / "scenes"
CBOX = str(SCENES / "cbox.xml")


@pytest.fixture(scope="module")
def scene():
    return tandem.load(CBOX, res=16)


def test_missing_scene(tmp):
    with pytest.raises(ValueError, match=r"nope\.xml: scene file not found or unreadable"):
        tandem.load(str(tmp / "nope.xml"))


def test_malformed_scene_has_the_cli_message(tmp):
    bad = tmp / "bad.xml"
    bad.write_text('<scene version="3.0.0">\n  <shape type="obj">\n</scene>\n')
    with pytest.raises(ValueError) as e:
        tandem.load(str(bad))
    assert str(e.value) == cli_error("render", bad)
    assert str(bad) in str(e.value)


def test_bad_define_value_has_the_cli_message():
    with pytest.raises(ValueError) as e:
        tandem.load(CBOX, res="sixteen")
    assert str(e.value) == cli_error("render", CBOX, "-D", "res=sixteen")


def test_unknown_device_has_the_cli_message():
    with pytest.raises(ValueError) as e:
        tandem.load(CBOX, device="no-such-device")
    assert str(e.value) == cli_error("render", CBOX, "--device", "no-such-device")


def test_unknown_parameter_has_the_cli_message(scene):
    delta = np.zeros((16, 16, 3), np.float32)
    with pytest.raises(ValueError) as e:
        scene.backward(delta, params=["nope"])
    assert str(e.value) == cli_error("grad", CBOX, "-D", "res=16", "--param", "nope")
    with pytest.raises(KeyError):
        scene.params["nope"]


def test_unknown_loss_has_the_cli_message(scene):
    with pytest.raises(ValueError) as e:
        scene.grad("l3", params="red.reflectance")
    assert str(e.value) == cli_error("grad", CBOX, "-D", "res=16", "--param", "red.reflectance",
                                     "--loss", "l3")
    with pytest.raises(ValueError, match="loss 'l2' needs a reference image"):
        scene.grad("l2", params="red.reflectance")


def test_bad_values(scene):
    red = scene.params["red.reflectance"]
    before = red.value
    with pytest.raises(ValueError, match=r"red.reflectance: element 1 is 1.5, outside .*\[0, 1\]"):
        red.value = [0.5, 1.5, 0.5]
    with pytest.raises(ValueError, match=r"red.reflectance: element 0 is nan"):
        red.value = [np.nan, 0.5, 0.5]
    with pytest.raises(ValueError, match=r"red.reflectance: 4 values for a parameter of 3"):
        red.value = [0.1, 0.2, 0.3, 0.4]
    with pytest.raises(ValueError, match="expected an array of floats"):
        red.value = "grey"
    assert np.array_equal(red.value, before)  # unchanged by the failed assignments
    wall = tandem.load(str(SCENES / "cbox-wall.xml"), res=8).params["wall.reflectance"]
    with pytest.raises(ValueError, match=r"expected shape \(256, 256, 3\)"):
        wall.value = np.zeros((256, 128, 6), np.float32)


def test_bad_images(scene):
    with pytest.raises(ValueError, match=r"delta has shape \(16, 3, 16\); the film is \(16, 16, 3\)"):
        scene.backward(np.zeros((16, 3, 16), np.float32))
    delta = np.zeros((16, 16, 3), np.float32)
    delta[3, 4, 1] = np.inf
    with pytest.raises(ValueError, match="delta: element 157 is not finite"):
        scene.backward(delta)
    with pytest.raises(ValueError, match="ref has shape"):
        scene.grad("l2", ref=np.zeros((8, 8, 3)))
    with pytest.raises(ValueError, match="spp must be in"):
        scene.render(spp=-1)


def test_bad_control_variate_and_optimizer(scene):
    with pytest.raises(ValueError, match="consistent"):
        tandem.ControlVariate(scene, variance="approximate")
    with pytest.raises(ValueError, match=r"beta1 and beta2 must be in \(0, 1\)"):
        tandem.ControlVariate(scene, beta1=1.5)
    cv = tandem.ControlVariate(scene)
    with pytest.raises(ValueError, match="F has shape"):
        cv(np.zeros(5), np.zeros(5))
    with pytest.raises(ValueError, match="expected 'adam' or 'sgd'"):
        tandem.Optimizer(scene, {"red.reflectance": 0.1}, method="lbfgs")
    with pytest.raises(ValueError, match="nope"):
        tandem.Optimizer(scene, {"nope": 0.1})
    with pytest.raises(ValueError, match="learning rate -1 must be finite and >= 0"):
        tandem.Optimizer(scene, {"red.reflectance": -1.0})
    opt = tandem.Optimizer(scene, {"red.reflectance": 0.1})
    with pytest.raises(ValueError, match="a gradient of 2 elements for a parameter of 3"):
        opt.step({"red.reflectance": [1.0, 2.0]})


def test_bad_optimize_config_has_the_cli_message(tmp):
    config = TEST_SCENES / "malformed-config.json"
    with pytest.raises(ValueError) as e:
        tandem.optimize(str(config), out=str(tmp / "out"), progress=False)
    assert str(e.value) == cli_error("optimize", config, "--out", tmp / "out")
    assert "malformed-config.json" in str(e.value)


def test_image_errors(tmp):
    with pytest.raises(ValueError, match="nope.exr"):
        tandem.read_image(str(tmp / "nope.exr"))
    with pytest.raises(ValueError, match=r"expected an array \(height, width, 3\)"):
        tandem.write_image(str(tmp / "a.exr"), np.zeros((4, 4)))


def test_a_failed_device_allocation_leaves_the_interpreter_usable():
    """The N-th device allocation fails as on CL_MEM_OBJECT_ALLOCATION_FAILURE (the runtime's
    TANDEM_FAIL_ALLOCATION hook), at load and in the middle of a gradient: RuntimeError, then
    the same process renders again."""
    script = textwrap.dedent(f"""
        import numpy as np, os, tandem
        for n in (1, 3, 9):                   # counted from the process's first allocation
            os.environ["TANDEM_FAIL_ALLOCATION"] = str(n)
            try:
                s = tandem.load({CBOX!r}, res=8)
                img = s.render(spp=1)
                s.backward(np.ones_like(img), spp=1)
                s.backward(np.ones_like(img), spp=1)
                print("no failure", n)
            except RuntimeError as e:
                print("RuntimeError:", e)
        os.environ.pop("TANDEM_FAIL_ALLOCATION")
        s = tandem.load({CBOX!r}, res=8)
        print("survived", s.render(spp=1).shape)
    """)
    env = dict(os.environ)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    failures = [line for line in lines if line.startswith("RuntimeError: out of device memory")]
    assert len(failures) >= 2, p.stdout
    assert all("CL_MEM_OBJECT_ALLOCATION_FAILURE (injected" in line for line in failures)
    assert lines[-1] == "survived (8, 8, 3)"
