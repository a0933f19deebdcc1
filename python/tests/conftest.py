"""Shared fixtures of the Python module's tests: the repository, the CLI next to the module; and,
under ctest, a skipped test reported as skipped."""

import json
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"


def cli_path() -> str:
    """The tandem executable of the same build (ctest sets TANDEM_CLI)."""
    path = os.environ.get("TANDEM_CLI") or str(ROOT / "build" / "tandem")
    if not os.path.exists(path):
        raise RuntimeError(f"the tandem CLI is not at {path}: build it, or set TANDEM_CLI")
    return path


def run_cli(*args, check=True):
    """Runs the CLI; returns the CompletedProcess (text). Fails the test on a nonzero exit when
    `check`, with the CLI's stderr."""
    p = subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        pytest.fail(f"tandem {' '.join(map(str, args))} failed: {p.stderr.strip()}")
    return p


def cli_json(*args):
    return json.loads(run_cli(*args, "--json").stdout)


def cli_error(*args) -> str:
    """The one-line message of a CLI run that must fail ("tandem: error: MESSAGE")."""
    p = run_cli(*args, check=False)
    assert p.returncode != 0, f"tandem {' '.join(map(str, args))} succeeded"
    lines = [line for line in p.stderr.splitlines() if line.startswith("tandem: error: ")]
    assert len(lines) == 1, p.stderr
    return lines[0][len("tandem: error: "):]


@pytest.fixture
def tmp(tmp_path):
    return tmp_path


def pytest_sessionfinish(session, exitstatus):
    """Under ctest, which sets TANDEM_PYTEST_SKIP_EXIT (python/CMakeLists.txt), a run that skipped a
    test and failed none exits with that code, which ctest reports as skipped (SKIP_RETURN_CODE)
    rather than passed. A failure keeps its own exit code."""
    code = os.environ.get("TANDEM_PYTEST_SKIP_EXIT")
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if code and exitstatus == 0 and reporter is not None and reporter.stats.get("skipped"):
        session.exitstatus = int(code)
