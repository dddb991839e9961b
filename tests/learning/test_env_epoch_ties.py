"""Hold-mode epochs of the SimPy driver and the compiled vector env at an instant where an
epoch opens and a repair ends together (a regression test from the review of issue 12)."""

from __future__ import annotations

import numpy as np

from pnp_twin.learning.envs.driver import EpochDriver
from pnp_twin.learning.envs.vector_env import PickPlaceVectorEnv

# fixed breakdowns with a repair too short to move the clock (mttr > 0 is all the loader
# asks): the repaired robot is free again at the very instant it broke down, after the
# other robots' t_all epoch opened there
TIE = {
    "duration": 10.0,
    "warmup": 0.0,
    "feeder.rate": 0.2,
    "robots.mtbf": 0.5,
    "robots.mttr": 1e-300,
    "robots.failure_distribution": "fixed",
}


def test_a_t_all_epoch_and_a_repair_at_the_same_instant_match_in_both_engines() -> None:
    """An opened epoch's robots no longer wait for one, in hold mode too: the repaired robot
    does not reopen it (SimPy's gateway used to, listing robots twice and failing in
    Gateway.release with a KeyError), and both engines agree epoch for epoch."""
    driver = EpochDriver("paper_baseline", termination="t_all", overrides=TIE)
    fast = PickPlaceVectorEnv(
        num_envs=1, termination="t_all", overrides=TIE, action_type="multidiscrete"
    )
    deciding = driver.reset(1)
    fast.reset(options={"line_seed": 1})
    for _ in range(20):
        deciding = driver.act({r: 0 for r in deciding})
        fast.step(np.zeros((1, 4), dtype=np.int64))
        assert fast.batch.now[0] == driver.now
        assert np.flatnonzero(fast.batch.deciding[0]).tolist() == deciding
