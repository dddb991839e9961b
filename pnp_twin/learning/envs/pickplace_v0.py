"""PettingZoo-style constructors, as PettingZoo's own environments have them.

>>> from pnp_twin.learning.envs import pickplace_v0
>>> env = pickplace_v0.env(render_mode="ansi")            # AEC, wrapped (order enforcing)
>>> par = pickplace_v0.parallel_env(termination="t_all")  # Parallel
>>> raw = pickplace_v0.raw_env()                          # AEC, unwrapped

Keyword arguments go to :class:`~pnp_twin.learning.envs.pz_aec.PickPlaceAEC` (``env``,
``raw_env``) or :class:`~pnp_twin.learning.envs.pz_parallel.PickPlaceParallel`
(``parallel_env``): the options of :class:`~pnp_twin.learning.envs.options.EnvOptions`,
``max_cycles`` included, so PettingZoo's ``max_cycles_test(pickplace_v0)`` passes.
"""

from __future__ import annotations

from typing import Any

from pettingzoo.utils import wrappers

from pnp_twin.learning.envs.pz_aec import PickPlaceAEC
from pnp_twin.learning.envs.pz_parallel import PickPlaceParallel


def raw_env(render_mode: str | None = None, **kwargs: Any) -> PickPlaceAEC:
    """The AEC environment itself (asynchronous decisions, ``t_continue`` by default)."""
    return PickPlaceAEC(render_mode=render_mode, **kwargs)


def env(render_mode: str | None = None, **kwargs: Any) -> Any:
    """The AEC environment with PettingZoo's order-enforcing wrapper (the usual entry)."""
    return wrappers.OrderEnforcingWrapper(raw_env(render_mode=render_mode, **kwargs))


def parallel_env(render_mode: str | None = None, **kwargs: Any) -> PickPlaceParallel:
    """The Parallel environment (synchronous decisions, ``t_all`` by default)."""
    return PickPlaceParallel(render_mode=render_mode, **kwargs)
