"""The vector env's first-compile notice: one ``CompileNotice`` warning when numba actually
compiles, none when the machine code comes from numba's on-disk cache."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numba

from pnp_twin.learning.vector.batch import COMPILE_NOTICE, CompileNotice, compile_notice


def _notices(caught: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, CompileNotice)]


def test_a_compile_warns_once_and_a_compiled_function_not():
    @numba.njit
    def add(a, b):
        return a + b

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with compile_notice() as listener:
            assert add(1, 2) == 3
            assert add(1.0, 2.0) == 3.0  # a second compile in the block: still one notice
    assert _notices(caught) == [COMPILE_NOTICE]
    assert listener.warned
    # the notice names the line that called the compiled code, not numba's internals
    assert [Path(w.filename).name for w in caught] == [Path(__file__).name]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with compile_notice():
            assert add(2, 2) == 4  # already compiled: nothing to say
    assert _notices(caught) == []


SCRIPT = """
import sys, warnings
sys.path.insert(0, {folder!r})
from pnp_twin.learning.vector.batch import CompileNotice, compile_notice
import cached_fn
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    with compile_notice():
        assert cached_fn.twice(3) == 6
print(sum(issubclass(w.category, CompileNotice) for w in caught))
"""


def _run(code: str, env: dict[str, str]) -> str:
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip().splitlines()[-1]


def test_a_cache_hit_does_not_warn(tmp_path: Path):
    (tmp_path / "cached_fn.py").write_text(
        "import numba\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    code = textwrap.dedent(SCRIPT.format(folder=str(tmp_path)))
    assert _run(code, env) == "1"  # compiled: one notice
    assert _run(code, env) == "0"  # read from the on-disk cache: none


VECTOR = """
import warnings
import numpy as np
from pnp_twin.learning.vector.batch import CompileNotice
from pnp_twin.learning.envs.vector_marl import PickPlaceParallelVectorEnv
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    env = PickPlaceParallelVectorEnv(2, overrides={"duration": 5.0, "warmup": 1.0})
    env.reset(seed=0)
    env.step(np.zeros((2, 4), dtype=np.int64))
print(sum(issubclass(w.category, CompileNotice) for w in caught))
"""


def test_the_vector_env_warns_only_when_it_compiles():
    env = dict(os.environ)
    first = _run(VECTOR, env)  # compiles (notice) or reads the cache (none)
    assert first in ("0", "1")
    assert _run(VECTOR, env) == "0"  # now cached: a fresh process says nothing
