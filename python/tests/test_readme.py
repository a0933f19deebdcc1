"""The README's Python example runs as printed (with fewer iterations)."""

import os
import re

from conftest import ROOT


def test_readme_example_runs(monkeypatch):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Python module"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert "range(100)" in code
    monkeypatch.chdir(ROOT)
    namespace = {}
    exec(compile(code.replace("range(100)", "range(3)"), "README.md", "exec"), namespace)
    opt, wall = namespace["opt"], namespace["wall"]
    assert opt.steps == 3
    assert wall.value.std() > 0  # the grey start moved
    assert os.getcwd() == str(ROOT)
