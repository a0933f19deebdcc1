"""Several views: scenes with several sensors (or Mitsuba's batch sensor), the sensor each call
renders, and tandem.optimize over some of them."""

import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import tandem
from conftest import SCENES, cli_error, run_cli

GLOBE = SCENES / "globe.xml"
GLOBE_IDS = [f"view{k}" for k in range(8)]
EPS = np.finfo(np.float32).eps


def globe(**defines):
    return tandem.load(str(GLOBE), **{"res": 16, "spp": 2, **defines})


def numbers(text):
    return [float(x) for x in re.split(r"[,\s]+", text.strip())]


def look_at(origin, target, up):
    """Mitsuba's Transform4f::look_at in float64: columns (left, new_up, dir, origin)."""
    origin, target, up = (np.asarray(v, np.float64) for v in (origin, target, up))
    d = target - origin
    d /= np.linalg.norm(d)
    left = np.cross(up, d)
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, origin
    return m


def test_globe_sensors_are_the_files_cameras():
    cameras = []
    for sensor in ET.parse(GLOBE).getroot().iter("sensor"):
        la = sensor.find("transform/lookat")
        cameras.append((sensor.get("id"), numbers(la.get("origin")), numbers(la.get("target")),
                        numbers(la.get("up"))))
    assert [c[0] for c in cameras] == GLOBE_IDS  # the file is what the test assumes

    s = globe(res=24, spp=3, fov=50)
    sensors = s.sensors
    assert [d["index"] for d in sensors] == list(range(8))
    assert [d["id"] for d in sensors] == GLOBE_IDS
    for d, (_, origin, target, up) in zip(sensors, cameras):
        assert (d["width"], d["height"], d["spp"], d["fov"]) == (24, 24, 3, 50.0), d
        m = np.asarray(d["to_world"])
        assert m.shape == (4, 4)
        # the translation is the origin as written, rounded to float32
        assert np.array_equal(m[:3, 3], np.float32(origin)), (d["id"], m[:3, 3], origin)
        assert np.array_equal(m[3], [0, 0, 0, 1])
        # +z looks at the target (the origin of the world): along -origin
        to_target = -np.float64(origin) / np.linalg.norm(origin)
        assert target == [0, 0, 0]
        # a unit vector from a few float32 operations: a few ulps of 1 per element; 16 ulps of
        # the largest magnitude (3.2, the distance) for the whole matrix
        assert np.allclose(m[:3, 2], to_target, rtol=0, atol=16 * EPS), (d["id"], m[:3, 2])
        assert np.allclose(m, look_at(origin, target, up), rtol=0, atol=16 * EPS * 3.2), d["id"]
    # the resolution is a define: the default one is 64
    assert {(d["width"], d["height"]) for d in tandem.load(str(GLOBE)).sensors} == {(64, 64)}


def test_render_of_a_sensor_equals_the_cli(tmp):
    s = globe()
    for key in (3, "view3", 0, "view6"):
        out = tmp / f"cli-{key}.exr"
        run_cli("render", GLOBE, "-D", "res=16", "-D", "spp=2", "--sensor", key, "--spp", 2,
                "--seed", 7, "--out", out)
        expected = tandem.read_image(str(out))
        image = s.render(spp=2, seed=7, sensor=key)
        assert image.shape == (16, 16, 3)
        assert np.array_equal(image, expected), f"sensor {key}: {np.sum(image != expected)} differ"
    assert np.array_equal(s.render(2, 7, sensor="view3"), s.render(2, 7, sensor=3))
    assert np.array_equal(s.render(2, 7), s.render(2, 7, sensor=0))
    a, b = s.render(2, 7, sensor=0), s.render(2, 7, sensor=3)
    assert not np.array_equal(a, b)
    # both see the globe: neither is the constant sky (1, 1, 1) everywhere
    assert np.any(np.abs(a - 1) > 0.05) and np.any(np.abs(b - 1) > 0.05)


def test_cli_renders_every_sensor_into_numbered_files(tmp):
    s = globe()
    run_cli("render", GLOBE, "-D", "res=16", "--sensor", "all", "--spp", 2, "--seed", 4, "--out",
            tmp / "all.exr")
    assert sorted(p.name for p in tmp.iterdir()) == sorted(f"all_{k}.exr" for k in range(8))
    images = [tandem.read_image(str(tmp / f"all_{k}.exr")) for k in range(8)]
    for k, image in enumerate(images):
        assert np.array_equal(image, s.render(2, 4, sensor=k)), k
    assert len({im.tobytes() for im in images}) == 8  # eight different views


def test_an_unknown_sensor_names_the_sensors(tmp):
    s = globe()
    known = ", ".join(f"{k} ('view{k}')" for k in range(8))
    for key in ("nope", 8):
        with pytest.raises(ValueError, match=re.escape(known)):
            s.render(2, 0, sensor=key)
        with pytest.raises(ValueError, match=re.escape(known)):
            s.backward(np.zeros((16, 16, 3), np.float32), 2, 0, sensor=key)
        with pytest.raises(ValueError, match=re.escape(known)):
            tandem.ControlVariate(s, sensor=key)
        message = cli_error("render", GLOBE, "-D", "res=16", "--sensor", key, "--spp", 1,
                            "--out", tmp / "x.exr")
        assert "view7" in message and str(key) in message, message
    assert not (tmp / "x.exr").exists()


def perspective(origin, target, fov, film=None, spp=None, sensor_id=None):
    inner = [f'<float name="fov" value="{fov}"/>',
             f'<transform name="to_world"><lookat origin="{origin}" target="{target}" '
             'up="0, 1, 0"/></transform>']
    if spp is not None:
        inner.append(f'<sampler type="independent"><integer name="sample_count" value="{spp}"/>'
                     '</sampler>')
    if film is not None:
        inner.append(f'<film type="hdrfilm"><integer name="width" value="{film[0]}"/>'
                     f'<integer name="height" value="{film[1]}"/><rfilter type="box"/></film>')
    sid = f' id="{sensor_id}"' if sensor_id else ""
    return f'<sensor type="perspective"{sid}>' + "".join(inner) + "</sensor>"


CAM_A = dict(origin="0, 1.2, 4", target="0, 0.4, 0", fov=40)
CAM_B = dict(origin="3, 2, -1.5", target="0.2, 0.3, 0", fov=55)


def write_scene(path, *sensors):
    """A diffuse ball on a diffuse floor under a constant sky, seen by `sensors`."""
    path.write_text(f"""<?xml version="1.0" encoding="utf-8"?>
<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="3"/></integrator>
    {"".join(sensors)}
    <bsdf type="diffuse" id="ball"><rgb name="reflectance" value="0.7, 0.3, 0.2"/></bsdf>
    <bsdf type="diffuse" id="floor"><rgb name="reflectance" value="0.4, 0.5, 0.6"/></bsdf>
    <shape type="sphere" id="ball-shape">
        <point name="center" x="0" y="0.5" z="0"/><float name="radius" value="0.5"/>
        <ref id="ball"/>
    </shape>
    <shape type="rectangle" id="floor-shape">
        <transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
        <ref id="floor"/>
    </shape>
    <emitter type="constant" id="sky"><rgb name="radiance" value="1, 0.9, 0.8"/></emitter>
</scene>
""")
    return path


@pytest.fixture
def two_and_one(tmp, request):
    """(a scene whose second sensor, 'cam1', has a 20x12 film, the one-sensor copy of that
    sensor); the first sensor is 16x16. `request.param`: two <sensor>s, or a batch sensor of two
    (a 40x12 film split in two: then both sensors are 20x12 and share the batch's 5 spp)."""
    if request.param == "sensors":
        sensors = [perspective(**CAM_A, film=(16, 16), spp=3, sensor_id="cam0"),
                   perspective(**CAM_B, film=(20, 12), spp=5, sensor_id="cam1")]
    else:
        sensors = ['<sensor type="batch">'
                   '<sampler type="independent"><integer name="sample_count" value="5"/></sampler>'
                   '<film type="hdrfilm"><integer name="width" value="40"/>'
                   '<integer name="height" value="12"/><rfilter type="box"/></film>'
                   + perspective(**CAM_A, sensor_id="cam0")
                   + perspective(**CAM_B, sensor_id="cam1") + "</sensor>"]
    two = write_scene(tmp / f"two-{request.param}.xml", *sensors)
    one = write_scene(tmp / "one.xml", perspective(**CAM_B, film=(20, 12), spp=5))
    return tandem.load(str(two)), tandem.load(str(one)), request.param


LAYOUTS = pytest.mark.parametrize("two_and_one", ["sensors", "batch"], indirect=True)


@LAYOUTS
def test_a_second_sensor_is_a_scene_of_its_own(two_and_one):
    two, one, layout = two_and_one
    first = (16, 16, 3) if layout == "sensors" else (20, 12, 3)
    assert [(d["index"], d["id"], d["width"], d["height"], d["spp"]) for d in two.sensors] == [
        (0, "cam0", first[0], first[1], 3 if layout == "sensors" else 5),
        (1, "cam1", 20, 12, 5)]
    assert np.array_equal(two.sensors[1]["to_world"], one.sensors[0]["to_world"])
    assert two.sensors[1]["fov"] == one.sensors[0]["fov"] == 55.0
    for spp, seed in ((2, 9), (0, 1)):  # spp 0: the sensor's own sampler (5)
        image = two.render(spp, seed, sensor=1)
        assert image.shape == (12, 20, 3)
        assert np.array_equal(image, one.render(spp, seed))
        assert np.array_equal(two.render(spp, seed, sensor="cam1"), image)
    assert two.render(2, 9, sensor=0).shape == (first[1], first[0], 3)

    delta = (np.random.default_rng(5).standard_normal((12, 20, 3)) * 1e-2).astype(np.float32)
    params = ["ball.reflectance", "floor.reflectance", "sky.radiance"]
    g2 = two.backward(delta, spp=2, seed=3, params=params, sensor=1)
    g1 = one.backward(delta, spp=2, seed=3, params=params)
    for name in params:
        assert np.array_equal(g2[name], g1[name]), name
        assert np.any(g1[name] != 0), name

    # the two-state render with another previous state, in both scenes
    previous = {"ball.reflectance": [0.2, 0.6, 0.3]}
    f2, h2 = two.render_two_state(spp=2, seed=4, previous=previous, sensor=1)
    f1, h1 = one.render_two_state(spp=2, seed=4, previous=previous)
    assert np.array_equal(f2, f1) and np.array_equal(h2, h1)
    assert not np.array_equal(f1, h1)


@pytest.mark.parametrize("two_and_one", ["sensors"], indirect=True)  # two film sizes
def test_control_variate_takes_its_sensors_film(two_and_one):
    two, _, _ = two_and_one
    f0, h0 = two.render_two_state(spp=2, seed=1, sensor=0)
    f1, h1 = two.render_two_state(spp=2, seed=1, sensor="cam1")
    assert f0.shape == (16, 16, 3) and f1.shape == (12, 20, 3)
    for key in (1, "cam1"):
        cv = tandem.ControlVariate(two, sensor=key)
        with pytest.raises(ValueError, match=r"F has shape \(16, 16, 3\); the film is \(12, 20"):
            cv(f0, h0)
        with pytest.raises(ValueError, match=r"H has shape \(16, 16, 3\); the film is \(12, 20"):
            cv(f1, h0)
        c = cv(f1, h1)  # warmup 1: the first estimate is F itself
        assert c.shape == (12, 20, 3) and np.array_equal(c, f1)
        assert cv.alpha.shape == (12, 20, 3)
        assert cv.iteration == 1
    cv0 = tandem.ControlVariate(two)
    with pytest.raises(ValueError, match=r"F has shape \(12, 20, 3\); the film is \(16, 16"):
        cv0(f1, h1)
    assert cv0(f0.reshape(-1), h0.reshape(-1)).shape == (16, 16, 3)  # flat: the film's size
    # backward checks the delta against the sensor it replays
    with pytest.raises(ValueError, match=r"\(12, 20, 3\)"):
        two.backward(np.zeros((16, 16, 3), np.float32), 1, 0, sensor=1)


def test_params_item_assignment_checks_like_value_assignment():
    s = globe()
    sky = "sky.radiance"
    s.params[sky] = [0.5, 0.25, 2.0]
    assert np.array_equal(s.params[sky].value, np.float32([0.5, 0.25, 2.0]))
    s.params["globe.reflectance"] = 0.125
    assert np.all(s.params["globe.reflectance"].value == np.float32(0.125))
    texels = np.random.default_rng(0).random((64, 128, 3)).astype(np.float32)
    s.params["globe.reflectance"] = texels
    assert np.array_equal(s.params["globe.reflectance"].value, texels)
    rendered = s.render(2, 0)
    s.params["globe.reflectance"] = 0.5
    assert not np.array_equal(s.render(2, 0), rendered)  # writes through to the render

    bad = [(sky, [1.0, 2.0], "2 values for a parameter of 3"),
           (sky, [np.nan, 1.0, 1.0], "element 0 is nan"),
           (sky, [1.0, -1.0, 1.0], r"element 1 is -1, outside .*\[0, inf\]"),
           ("globe.reflectance", 1.5, r"outside .*\[0, 1\]"),
           ("globe.reflectance", np.zeros((64, 128, 2)), r"expected shape \(64, 128, 3\)")]
    for name, value, message in bad:
        before = s.params[name].value
        with pytest.raises(ValueError, match=message) as by_value:
            s.params[name].value = value
        with pytest.raises(ValueError, match=message) as by_item:
            s.params[name] = value
        assert str(by_item.value) == str(by_value.value)
        assert np.array_equal(s.params[name].value, before), name  # unchanged
    with pytest.raises(KeyError, match="nope.*known: globe.reflectance, sky.radiance"):
        s.params["nope"] = [1.0, 1.0, 1.0]
    assert "nope" not in s.params


def test_optimize_a_batch_of_some_views(tmp):
    s = globe()
    images = []
    for k in range(8):  # one target per sensor, each its view at a higher spp
        images.append(tmp / f"target{k}.exr")
        tandem.write_image(str(images[-1]), s.render(8, 100 + k, sensor=k))
    config = {
        "scene": str(GLOBE),
        "defines": {"res": 16},
        "target": {"images": [str(p) for p in images]},
        "params": {"globe.reflectance": {"lr": 0.05, "init": 0.5}},
        "views": [0, "view2"],
        "batch": 1,
        "iterations": 4,
        "spp": 2,
        "spp_grad": 2,
        "loss": "l2",
        "seed": 1,
        "checkpoint_every": 2,
        "image_error_spp": 2,
    }
    path = tmp / "config.json"
    path.write_text(json.dumps(config))
    out = tmp / "out"
    summary = tandem.optimize(str(path), out=str(out), progress=False)
    assert summary["iterations"] == 4
    assert sorted(p.name for p in (out / "views").iterdir()) == ["0", "2"]
    for k in (0, 2):
        written = tandem.read_image(str(out / "views" / str(k) / "target.exr"))
        assert np.array_equal(written, tandem.read_image(str(images[k]))), k
    texture = tandem.read_image(str(out / "globe.reflectance.exr"))
    assert texture.shape == (64, 128, 3) and np.any(texture != np.float32(0.5))

    # a batch larger than the views, and an unknown view: errors naming the config
    for change, message in (({"batch": 3}, "'batch' is 3, more than the 2 views"),
                            ({"views": [0, "view9"]}, "views: .*view9.*7 \\('view7'\\)")):
        bad = tmp / "bad.json"
        bad.write_text(json.dumps({**config, **change}))
        with pytest.raises(ValueError, match=re.escape(str(bad)) + ": " + message):
            tandem.optimize(str(bad), out=str(tmp / "bad-out"), progress=False)
        assert re.search(message, cli_error("optimize", bad, "--out", tmp / "bad-cli"))


def test_grad_of_a_sensor_and_of_all(tmp):
    """tandem grad --sensor K differentiates sensor K's loss (against a reference of its film),
    --sensor all the sum of every sensor's; sensor 0 keeps the seeds of a one-sensor scene."""
    sensors = [perspective(**CAM_A, film=(16, 16), spp=3, sensor_id="cam0"),
               perspective(**CAM_B, film=(20, 12), spp=5, sensor_id="cam1")]
    scene = write_scene(tmp / "two.xml", *sensors)
    s = tandem.load(str(scene))
    refs = []
    for k in range(2):
        s.params["ball.reflectance"] = [0.2, 0.6, 0.3]  # the reference's ball
        refs.append(s.render(8, 50 + k, sensor=k))
        tandem.write_image(str(tmp / f"ref_{k}.exr"), refs[-1])
    s.params["ball.reflectance"] = [0.7, 0.3, 0.2]
    params = ["ball.reflectance", "sky.radiance"]

    def grad(sensor, ref):
        args = ["grad", scene, "--loss", "l2", "--ref", ref, "--spp", 2, "--spp-grad", 2,
                "--seed", 6, "--sensor", sensor, "--json"]
        for p in params:
            args += ["--param", p]
        j = json.loads(run_cli(*args).stdout)
        return j, {e["name"]: np.float32(e["gradient"]) for e in j["parameters"]}

    j0, g0 = grad(0, tmp / "ref_0.exr")
    j1, g1 = grad(1, tmp / "ref_1.exr")
    j1_by_id, g1_by_id = grad("cam1", tmp / "ref_1.exr")
    assert (j0["sensors"], j1["sensors"], j1_by_id["sensors"]) == ([0], [1], [1])
    assert j1["loss_value"] == j1_by_id["loss_value"]
    for name in params:
        assert np.array_equal(g1[name], g1_by_id[name]), name
        assert np.any(g0[name] != 0) and np.any(g1[name] != 0), name
        assert not np.array_equal(g0[name], g1[name]), name
    # sensor 0: the seeds of tandem grad on a one-sensor scene, which scene.grad reproduces
    loss, expected = s.grad("l2", refs[0], params, spp=2, spp_grad=2, seed=6)
    assert np.float32(j0["loss_value"]) == np.float32(loss)
    for name in params:
        assert np.array_equal(g0[name], expected[name]), name

    # a reference of the other sensor's film is refused, naming the film
    message = cli_error("grad", scene, "--loss", "l2", "--ref", tmp / "ref_0.exr", "--sensor", 1,
                        "--param", params[0], "--spp", 1)
    assert "20" in message and "12" in message, message

    # all: NAME_K.EXT per sensor; the loss is the sum of the two sensors' (each view keeps its
    # seeds); the two float32 losses add with one rounding: half an ulp of the sum
    j_all, _ = grad("all", tmp / "ref.exr")
    assert j_all["sensors"] == [0, 1]
    both = np.float64(np.float32(j0["loss_value"])) + np.float64(np.float32(j1["loss_value"]))
    assert abs(np.float32(j_all["loss_value"]) - both) <= 0.5 * EPS * both, (j_all, both)
