"""The compiled engine's cache follows every engine source: a change anywhere compiles anew.

numba alone keys a cached function on its own file, so a change in the kernel would leave
the vector env's and the rollouts' cached code (which embed the kernel) stale.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from twin.fast import jit

ROOT = Path(__file__).resolve().parents[2]


def test_the_fingerprint_covers_every_engine_source(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    copy = tmp_path / "fast"
    shutil.copytree(jit.ENGINE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(jit, "ENGINE", copy)
    before = jit.fingerprint()
    assert before == jit.fingerprint()
    for name in ("mathlib.py", "kernel.py", "vector.py"):
        path = copy / name
        text = path.read_text()
        path.write_text(text + "\n# changed\n")
        assert jit.fingerprint() != before, name
        path.write_text(text)
    assert jit.fingerprint() == before


def test_compiled_code_is_cached_under_the_fingerprint(tmp_path: Path) -> None:
    stale = tmp_path / "pnp_twin" / "0123456789abcdef"
    stale.mkdir(parents=True)
    code = (
        "from twin import load_scenario, simulate; from policies import make_policy;"
        "sc = load_scenario('two_robot', {'duration': 5.0, 'warmup': 1.0});"
        "simulate(sc, make_policy('SPT', 2), engine='fast')"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, check=True)
    folders = [p.name for p in (tmp_path / "pnp_twin").iterdir()]
    assert folders == [jit.fingerprint()]  # another fingerprint's folder is gone
    assert list((tmp_path / "pnp_twin" / folders[0]).rglob("*.nbi"))
