"""Optimization from Python: tandem.optimize is `tandem optimize`, and a loop written in Python
with the module's pieces retraces the CLI's run bit for bit."""

import csv
import json

import numpy as np
import pytest

import tandem
from conftest import SCENES, cli_json, run_cli
from test_gradients import l2_delta

WALL = "wall.reflectance"


def write_config(tmp, cv, iterations=10, **extra):
    """A cbox-wall texture recovery at 16x16 against a target image the test renders."""
    ref_path = tmp / "ref.exr"
    if not ref_path.exists():
        s = tandem.load(str(SCENES / "cbox-wall.xml"), res=16)
        tandem.write_image(str(ref_path), s.render(spp=32, seed=123))
    config = {
        "scene": str(SCENES / "cbox-wall.xml"),
        "defines": {"res": 16},
        "target": {"image": str(ref_path)},
        "params": {WALL: {"lr": 0.02, "init": 0.5}},
        "optimizer": "adam",
        "iterations": iterations,
        "spp": 4,
        "spp_grad": 4,
        "loss": "l2",
        "seed": 3,
        "cv": cv,
        "checkpoint_every": 5,
        "image_error_spp": 4,
        **extra,
    }
    path = tmp / f"config-{cv}.json"
    path.write_text(json.dumps(config))
    return path, tandem.read_image(str(ref_path))


def metrics(out_dir):
    """metrics.csv without the wall-time column."""
    with open(out_dir / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r.pop("seconds")
    return rows


def test_optimize_equals_the_cli(tmp):
    config, _ = write_config(tmp, "ps", iterations=20)
    run_cli("optimize", config, "--out", tmp / "cli")
    summary = tandem.optimize(str(config), out=str(tmp / "py"), progress=False)
    assert summary["iterations"] == 20 and summary["out"] == str(tmp / "py")
    assert summary["cv_variance"] == "consistent" and "fused" in summary["cv_plan"]
    assert len(metrics(tmp / "cli")) == 20
    assert metrics(tmp / "py") == metrics(tmp / "cli")
    assert (tmp / "py" / "params.json").read_text() == (tmp / "cli" / "params.json").read_text()
    a = tandem.read_image(str(tmp / "py" / "wall.reflectance.exr"))
    b = tandem.read_image(str(tmp / "cli" / "wall.reflectance.exr"))
    assert np.array_equal(a, b)
    assert (tmp / "py" / "checkpoint.bin").exists()


def test_optimize_resumes_bit_identically(tmp):
    config, _ = write_config(tmp, "ps", iterations=10)
    tandem.optimize(str(config), out=str(tmp / "whole"), progress=False)
    first = tandem.optimize(str(config), out=str(tmp / "split"), until=5, progress=False)
    assert first["iterations"] == 5
    second = tandem.optimize(str(config), out=str(tmp / "split"), resume=True, progress=False)
    assert second["iterations"] == 10
    assert metrics(tmp / "split") == metrics(tmp / "whole")
    a = tandem.read_image(str(tmp / "split" / "wall.reflectance.exr"))
    b = tandem.read_image(str(tmp / "whole" / "wall.reflectance.exr"))
    assert np.array_equal(a, b)


def test_optimize_guards_its_folder_and_its_inputs(tmp):
    """The CLI's integrity checks (docs/cli.md, "What keeps a run whole") hold for
    tandem.optimize: a changed input refuses resume=True naming the file, force=True goes on and
    says so, a damaged newest checkpoint falls back to the previous one, a locked folder is
    refused."""
    config, _ = write_config(tmp, "ps", iterations=15)
    whole = tandem.optimize(str(config), out=str(tmp / "whole"), progress=False)
    assert set(whole) == set(cli_json("optimize", config, "--out", tmp / "cli"))
    assert whole["inputs_changed"] is False
    tandem.optimize(str(config), out=str(tmp / "split"), until=10, progress=False)
    # the newest checkpoint (10) damaged: the previous one (5) resumes, to the same end
    newest = tmp / "split" / "checkpoint.bin"
    data = bytearray(newest.read_bytes())
    data[len(data) // 2] ^= 0x40
    newest.write_bytes(bytes(data))
    tandem.optimize(str(config), out=str(tmp / "split"), resume=True, progress=False)
    assert metrics(tmp / "split") == metrics(tmp / "whole")
    assert (tmp / "split" / "checkpoint.bin.damaged").read_bytes() == bytes(data)
    # another holder of the folder's lock (flock, as a second tandem would take it)
    import fcntl
    with open(tmp / "split" / ".tandem.lock", "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        with pytest.raises(ValueError, match="in use by another tandem optimize"):
            tandem.optimize(str(config), out=str(tmp / "split"), resume=True, progress=False)
    # the target image changed after iteration 10
    tandem.optimize(str(config), out=str(tmp / "changed"), until=10, progress=False)
    ref = tmp / "ref.exr"
    image = tandem.read_image(str(ref))
    tandem.write_image(str(ref), image * 0.5)
    with pytest.raises(ValueError, match=f"{ref}: changed since the checkpoint"):
        tandem.optimize(str(config), out=str(tmp / "changed"), resume=True, progress=False)
    with pytest.raises(ValueError, match="force=True needs resume=True"):
        tandem.optimize(str(config), out=str(tmp / "changed"), force=True, progress=False)
    forced = tandem.optimize(str(config), out=str(tmp / "changed"), resume=True, force=True,
                             progress=False)
    assert forced["inputs_changed"] is True and forced["iterations"] == 15
    assert [r["inputs_changed"] for r in metrics(tmp / "changed")] == [""] * 10 + ["1"] * 5


@pytest.mark.parametrize("cv", ["none", "ps"])
def test_a_python_loop_retraces_tandem_optimize(tmp, cv):
    """render (or the two-state render and the control variate) + an L2 delta in NumPy +
    backward + Optimizer.step, seeded as the CLI seeds its iterations: the recovered texture is
    the CLI's, bit for bit."""
    iterations, seed = 8, 3
    config, ref = write_config(tmp, cv, iterations=iterations)
    run_cli("optimize", config, "--out", tmp / "cli")
    expected = tandem.read_image(str(tmp / "cli" / "wall.reflectance.exr"))

    s = tandem.load(str(SCENES / "cbox-wall.xml"), res=16)
    wall = s.params[WALL]
    wall.value = 0.5
    opt = tandem.Optimizer(s, {WALL: 0.02})
    control = tandem.ControlVariate(s) if cv == "ps" else None
    for n in range(iterations):
        if control is None:
            image = s.render(spp=4, seed=tandem.primal_seed(seed, n))
        else:
            f, h = s.render_two_state(spp=4, seed=tandem.primal_seed(seed, n))
            image = control(f, h)
        s.backward(l2_delta(image, ref), spp=4, seed=tandem.adjoint_seed(seed, n), params=WALL)
        opt.step()
    assert opt.steps == iterations
    assert not np.array_equal(wall.value, np.full_like(expected, 0.5))
    assert np.array_equal(wall.value, expected)
    if control is not None:
        assert control.iteration == iterations
        alpha = control.alpha
        assert alpha.shape == (16, 16, 3) and np.all((alpha >= 0) & (alpha <= 1))


def test_optimizer_with_explicit_gradients_and_sgd():
    s = tandem.load(str(SCENES / "cbox.xml"), res=16)
    red, green = s.params["red.reflectance"], s.params["green.reflectance"]
    r0, g0 = red.value, green.value
    opt = tandem.Optimizer(s, {"red.reflectance": 0.1}, method="sgd")
    opt.step({"red.reflectance": [1.0, -1.0, 0.0], "green.reflectance": [5.0, 5.0, 5.0]})
    expected = np.clip(r0 - np.float32(0.1) * np.float32([1.0, -1.0, 0.0]), 0, 1)
    assert np.array_equal(red.value, expected.astype(np.float32))
    assert np.array_equal(green.value, g0)  # no learning rate: unchanged
    # the previous state of the two-state render is the value before the step ...
    f, h = s.render_two_state(spp=2, seed=0)
    assert not np.array_equal(f, h)
    # ... unless `previous` says otherwise: the current value, so both states are one, and both
    # images the plain render's (F itself depends on the old state through Russian roulette)
    f2, h2 = s.render_two_state(spp=2, seed=0, previous={"red.reflectance": red.value})
    plain = s.render(spp=2, seed=0)
    assert np.array_equal(f2, plain) and np.array_equal(h2, plain)
    # an assignment starts a new trajectory: no previous state apart from it
    red.value = r0
    f3, h3 = s.render_two_state(spp=2, seed=0)
    assert np.array_equal(f3, h3) and np.array_equal(f3, s.render(spp=2, seed=0))


def test_optimize_under_an_mpi_launcher_refuses_to_run_the_job_per_rank(tmp, monkeypatch):
    # the module runs one process; under mpirun each rank would run the whole job (docs/cli.md)
    config, _ = write_config(tmp, "none", iterations=1)
    monkeypatch.setenv("OMPI_COMM_WORLD_SIZE", "2")
    with pytest.raises(ValueError, match=r"runs as one process.*mpirun -np N tandem optimize"):
        tandem.optimize(str(config), str(tmp / "out"))
    assert not (tmp / "out").exists()  # nothing written
