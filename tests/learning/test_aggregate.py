"""IQM and stratified bootstrap intervals over training runs (marl-eval's protocol)."""

from __future__ import annotations

import numpy as np
import pytest

from pnp_twin.learning.aggregate import aggregate, iqm, normalized


def test_iqm_cuts_a_quarter_at_each_end():
    assert iqm([0, 1, 2, 3, 4, 5, 6, 100]) == pytest.approx(3.5)  # 2, 3, 4, 5 kept
    assert iqm([7.0]) == 7.0
    with pytest.raises(ValueError):
        iqm([])


def test_bootstrap_is_stratified_by_task_and_seeded():
    scores = {"a": [1.0, 1.0, 1.0, 1.0, 1.0], "b": [3.0, 3.0, 3.0, 3.0, 3.0]}
    out = aggregate(scores, resamples=200)
    # every resample keeps five runs of each task: no spread at all
    assert out["iqm_ci"] == [pytest.approx(2.0), pytest.approx(2.0)] and out["mean"] == 2.0
    noisy = {"a": list(np.linspace(0, 1, 5)), "b": list(np.linspace(2, 4, 5))}
    one, two = aggregate(noisy, seed=1), aggregate(noisy, seed=1)
    assert one == two and one["iqm_ci"][0] < one["iqm"] < one["iqm_ci"][1]
    assert one["runs"] == 10 and one["tasks"] == 2


def test_normalized_is_a_share_of_the_bound():
    assert normalized(0.4, 0.8) == 0.5 and np.isnan(normalized(0.1, 0.0))
