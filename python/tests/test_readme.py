"""The README's Python example runs as printed (with fewer iterations) and does what it says: the
wall's texture moves from the grey start toward the true one, and the image toward the target."""

import os
import re

import numpy as np

import tandem
from conftest import ROOT

# Measured on PoCL: parameter error 0.2658 -> 0.2217 (fell 0.044, margin 0.009), image error
# 0.01973 -> 0.01619 (fell 0.0035, margin 0.0004), in 3 s. Past about 33 iterations the texture's
# RMSE over all its texels turns up again under this L1 loss at 64² (the image error goes on
# falling), so the run stops well before.
ITERATIONS = 20


def falls_beyond_noise(series):
    """(fall, margin): how much the series fell from its first to its last value, and the fall
    that noise alone could make. Noise: each step's change about the mean change (the sample
    standard deviation s of the differences, which also counts the trend's own curvature, so it
    overstates the noise); a series that only wanders with steps of that spread moves by
    s sqrt(n - 1) over n - 1 steps, and 4 times that is the margin (one-sided, 3e-5)."""
    steps = np.diff(np.asarray(series, dtype=np.float64))
    return series[0] - series[-1], 4.0 * steps.std(ddof=1) * np.sqrt(len(steps))


def test_readme_example_runs_and_recovers_the_wall(monkeypatch):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python module"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert code.count("for it in range(100):") == 1 and code.count("    opt.step()") == 1
    monkeypatch.chdir(ROOT)
    truth = tandem.load("scenes/cbox-wall.xml", res=64).params["wall.reflectance"].value
    # At the grey start and after each step: the texture's RMSE against the scene file's, and the
    # mean absolute error of a fixed-seed 16-spp render against the example's target (the same
    # seed every time, so that the change is the parameters', not the samples').
    param_error, image_error = [], []
    namespace = {}

    def measure():
        scene, wall = namespace["scene"], namespace["wall"]
        param_error.append(float(np.sqrt(np.mean((wall.value - truth) ** 2))))
        image = scene.render(spp=16, seed=987654321)
        image_error.append(float(np.mean(np.abs(image - namespace["target"]))))

    namespace["measure"] = measure
    code = code.replace("for it in range(100):", f"measure()\nfor it in range({ITERATIONS}):")
    code = code.replace("    opt.step()", "    opt.step(); measure()")
    exec(compile(code, "README.md", "exec"), namespace)
    opt = namespace["opt"]
    assert opt.steps == ITERATIONS
    assert os.getcwd() == str(ROOT)
    for name, series in (("parameter error", param_error), ("image error", image_error)):
        fall, margin = falls_beyond_noise(series)
        print(f"{name}: {series[0]:.5f} -> {series[-1]:.5f}, fell {fall:.5f}, margin {margin:.5f}")
        assert fall > margin, (name, series)
