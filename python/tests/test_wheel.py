"""`pip install .` builds a working wheel (scikit-build-core), with its type stubs."""

import os
import subprocess
import sys

from conftest import ROOT, SCENES


def test_pip_install_builds_an_importable_module(tmp):
    # no build isolation: scikit-build-core and nanobind come from the environment
    # (scripts/setup-python.sh), so the test needs no network
    target = tmp / "site"
    p = subprocess.run([sys.executable, "-m", "pip", "install", "--disable-pip-version-check",
                        "--no-build-isolation", "--no-deps", "-q", "--target", str(target),
                        str(ROOT)], capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr
    installed = sorted(os.listdir(target / "tandem"))
    assert "__init__.py" in installed and "_tandem.pyi" in installed and "py.typed" in installed
    assert any(f.startswith("_tandem.") and f.endswith(".so") for f in installed), installed
    script = ("import tandem; s = tandem.load(%r, res=8); "
              "print(tandem.__file__, s.render(spp=1).shape)" % str(SCENES / "cbox.xml"))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(target)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env,
                       cwd=tmp)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == f"{target / 'tandem' / '__init__.py'} (8, 8, 3)"
