"""CI cannot turn green on a broken install: in strict mode (``CI=1``, ``PNP_TWIN_STRICT=1`` or
``--strict-deps``; ``.ci/run`` sets ``CI=1``) every skip is a failure, and a test that leaves a
signal handler behind fails. Each case runs pytest in a subprocess, with the suite's own
conftest, on a small test file or on a real test module with torch hidden."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SKIPPING = """
import pytest

needed = pytest.importorskip("pnp_twin_no_such_module")


def test_uses_it():
    assert needed
"""

SKIPS_AT_RUN_TIME = """
import shutil

import pytest


@pytest.mark.skipif(True, reason="no such tool on PATH")
def test_marked():
    pass


def test_skips_inside():
    pytest.skip("the shipped model is missing")


@pytest.mark.xfail(reason="a known bug", strict=True)
def test_expected_failure():
    assert False


def test_passes():
    assert shutil.which("sh")
"""

LEAKS_A_HANDLER = """
import signal


def test_leaves_sigterm_handled():
    signal.signal(signal.SIGTERM, lambda signum, frame: None)


def test_restores_sigterm():
    old = signal.signal(signal.SIGTERM, lambda signum, frame: None)
    signal.signal(signal.SIGTERM, old)
"""


def clean_env(**extra: str) -> dict[str, str]:
    """The environment without anything that turns strict mode on, plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k not in ("CI", "PNP_TWIN_STRICT")}
    env.pop("PYTEST_ADDOPTS", None)
    env.update(extra)
    return env


def pytest_in(folder: Path, *args: str, env: dict[str, str]) -> tuple[int, str]:
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rA", *args],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    return proc.returncode, proc.stdout + proc.stderr


@pytest.fixture
def suite(tmp_path: Path) -> Path:
    """A folder holding the suite's conftest and three small test files."""
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "conftest.py").write_text((ROOT / "tests" / "conftest.py").read_text())
    (tmp_path / "test_skipping.py").write_text(SKIPPING)
    (tmp_path / "test_run_time.py").write_text(SKIPS_AT_RUN_TIME)
    return tmp_path


def test_skips_are_skips_outside_ci(suite: Path) -> None:
    rc, out = pytest_in(suite, env=clean_env())
    assert rc == 0, out
    assert re.search(r"\b1 passed, 3 skipped, 1 xfailed\b", out), out


@pytest.mark.parametrize(
    ("args", "env"),
    [
        ((), {"CI": "true"}),
        ((), {"PNP_TWIN_STRICT": "1"}),
        (("--strict-deps",), {}),
    ],
)
def test_in_strict_mode_every_skip_fails(suite: Path, args: tuple[str, ...], env: dict) -> None:
    rc, out = pytest_in(suite, "--continue-on-collection-errors", *args, env=clean_env(**env))
    assert rc != 0, out
    # the module-level importorskip is a collection error, the marker a setup error, the
    # run-time skip a failure; the expected failure and the passing test are what they were
    assert re.search(r"\b1 failed, 1 passed, 1 xfailed, 2 errors\b", out), out
    strict = "strict mode (--strict-deps, CI or PNP_TWIN_STRICT): a skip is a failure"
    for reason in (
        "No module named 'pnp_twin_no_such_module'",
        "Skipped: no such tool on PATH",
        "Skipped: the shipped model is missing",
    ):
        assert re.search(re.escape(strict) + r".*" + re.escape(reason), out), (reason, out)
    assert "ERROR collecting test_skipping.py" in out, out
    assert "ERROR at setup of test_marked" in out, out
    assert "PASSED test_run_time.py::test_passes" in out, out


def test_ci_0_is_not_strict(suite: Path) -> None:
    rc, out = pytest_in(suite, env=clean_env(CI="0", PNP_TWIN_STRICT="false"))
    assert rc == 0, out


def test_a_test_that_leaves_a_signal_handler_behind_fails(tmp_path: Path) -> None:
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    (tmp_path / "conftest.py").write_text((ROOT / "tests" / "conftest.py").read_text())
    (tmp_path / "test_leak.py").write_text(LEAKS_A_HANDLER)
    rc, out = pytest_in(tmp_path, env=clean_env())
    assert rc != 0, out
    assert "ERROR test_leak.py::test_leaves_sigterm_handled" in out, out
    assert "left signal handlers changed: SIGTERM" in out, out
    assert "PASSED test_leak.py::test_restores_sigterm" in out, out


def test_a_broken_install_without_torch_fails_in_ci(tmp_path: Path) -> None:
    # a real module of the suite, on an install where `import torch` fails
    hidden = tmp_path / "hide"
    (hidden / "torch").mkdir(parents=True)
    shim = 'raise ModuleNotFoundError("torch is hidden", name="torch")\n'
    (hidden / "torch" / "__init__.py").write_text(shim)
    target = "tests/learning/test_checkpoint_errors.py"
    pythonpath = os.pathsep.join([str(hidden), os.environ.get("PYTHONPATH", "")])

    rc, out = pytest_in(ROOT, target, env=clean_env(PYTHONPATH=pythonpath))
    assert rc in (0, 5), out  # skipped: no test ran
    assert "torch is hidden" in out and "skipped" in out, out

    rc, out = pytest_in(ROOT, target, env=clean_env(PYTHONPATH=pythonpath, CI="1"))
    assert rc != 0, out
    assert "strict mode" in out and "torch is hidden" in out, out


def test_ci_run_is_strict_checks_the_wheel_and_times_tests_out() -> None:
    import tomllib

    lines = [ln.split("#")[0].strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()]
    steps = [ln for ln in lines if ln]
    order = [
        "export CI=1",
        ".venv/bin/ruff check .",
        ".venv/bin/python .ci/stage_tree.py",
        ".venv/bin/mypy",
        "(cd build/stage && ../../.venv/bin/lint-imports --config ../../pyproject.toml --no-cache)",
        "bash .ci/wheel_check",
        ".venv/bin/pytest",
    ]
    assert [s for s in steps if s in order] == order
    assert (ROOT / ".ci" / "wheel_check").is_file()
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    test_extra = project["project"]["optional-dependencies"]["test"]
    assert any(d.startswith("pytest-timeout") for d in test_extra)
    assert project["tool"]["pytest"]["ini_options"]["timeout"] > 0
