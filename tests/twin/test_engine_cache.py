"""The compiled engine's cache follows every engine source: a change anywhere compiles anew.

numba alone keys a cached function on its own file, so a change in the kernel would leave
the vector env's and the rollouts' cached code (which embed the kernel) stale.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pnp_twin.twin.fast import jit

ROOT = Path(__file__).resolve().parents[2]


def test_the_fingerprint_covers_every_engine_source(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    copy = tmp_path / "fast"
    shutil.copytree(jit.ENGINE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(jit, "ENGINE", copy)
    before = jit.fingerprint()
    assert before == jit.fingerprint()
    for name in ("mathlib.py", "kernel.py", "gateway.py", "robot.py"):
        path = copy / name
        text = path.read_text()
        path.write_text(text + "\n# changed\n")
        assert jit.fingerprint() != before, name
        path.write_text(text)
    assert jit.fingerprint() == before


RUN = (
    "from pnp_twin.twin import load_scenario, simulate;"
    "from pnp_twin.policies import make_policy;"
    "sc = load_scenario('two_robot', {'duration': 5.0, 'warmup': 1.0});"
    "simulate(sc, make_policy('SPT', 2), engine='fast')"
)


def test_compiled_code_is_cached_under_the_fingerprint(tmp_path: Path) -> None:
    root = tmp_path / "pnp_twin"
    ours = root / "0123456789abcdef"  # an older fingerprint this engine folder wrote
    ours.mkdir(parents=True)
    (ours / jit.OWNER).write_text(f"{jit.ENGINE}\n")
    (ours / "folders.txt").write_text("")
    recent = root / "00000000000000aa"  # ours too, but written to a minute ago: kept
    recent.mkdir()
    (recent / jit.OWNER).write_text(f"{jit.ENGINE}\n")
    (recent / "folders.txt").write_text("")
    hour_ago = time.time() - 3600
    os.utime(ours, (hour_ago, hour_ago))
    os.utime(recent, (time.time() - 60, time.time() - 60))
    theirs = root / "fedcba9876543210"  # another checkout's, sharing the cache folder
    theirs.mkdir()
    (theirs / jit.OWNER).write_text("/elsewhere/pnp_twin/twin/fast\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    subprocess.run([sys.executable, "-c", RUN], env=env, cwd=ROOT, check=True)
    folders = sorted(p.name for p in root.iterdir())
    # our stale folder replaced; another checkout's, and ours still in use, kept
    assert folders == sorted([jit.fingerprint(), theirs.name, recent.name])
    assert list((root / jit.fingerprint()).rglob("*.nbi"))
    assert (root / jit.fingerprint() / jit.OWNER).read_text().strip() == str(jit.ENGINE)


def test_a_read_only_package_caches_in_the_users_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    site = tmp_path / "site"
    site.write_text("")  # nothing can be created below a file, not even by root
    monkeypatch.setattr(jit, "ENGINE", site / "fast")
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "home_cache"))
    assert jit.cache_root() == tmp_path / "home_cache" / "pnp_twin" / "numba"
    monkeypatch.setattr(jit, "ENGINE", tmp_path / "checkout" / "fast")
    assert jit.cache_root() == tmp_path / "checkout" / "fast" / "__pycache__" / "numba"
