"""The t quantile without scipy: scipy's own values where tabled, within 1e-10 of them
elsewhere, and the core's statistics import no scipy."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from pnp_twin.twin import stats as core_stats
from pnp_twin.twin.stats import t_interval, t_quantile
from pnp_twin.twin.t_table import TABLE

scipy_stats = pytest.importorskip("scipy.stats")

LEVELS = (0.6, 0.75, 0.8, 0.9, 0.95, 0.975, 0.99, 0.995, 0.999, 0.9995, 0.9999)


def close(mine: float, ref: float) -> bool:
    return abs(mine - ref) <= 1e-10 * max(1.0, abs(ref))


def test_the_computed_quantile_matches_scipy_for_df_1_to_1000():
    """The series and root finding alone (the table bypassed), both tails."""
    worst = 0.0
    for df in range(1, 1001):
        for p in LEVELS:
            ref = float(scipy_stats.t.ppf(p, df))
            up = core_stats._upper(1.0 - p, float(df))
            down = -core_stats._upper(1.0 - p, float(df))  # P(T < -t) = 1 - p
            assert close(up, ref), (df, p, up, ref)
            assert close(down, float(scipy_stats.t.ppf(1.0 - p, df))), (df, p)
            worst = max(worst, abs(up - ref) / max(1.0, abs(ref)))
    assert worst < 1e-10


@pytest.mark.parametrize("df", [0.5, 1.5, 2.5, 7.3, 1500.0, 40000.0])
def test_fractional_and_large_degrees_of_freedom(df):
    for p in (0.025, 0.3, 0.7, 0.975, 0.999):
        assert close(t_quantile(p, df), float(scipy_stats.t.ppf(p, df))), (df, p)


def test_the_table_is_scipys_own_values():
    for p, values in TABLE.items():
        assert len(values) == 1000
        ref = scipy_stats.t.ppf(p, np.arange(1, 1001))
        assert np.array_equal(np.asarray(values), ref), p
        assert t_quantile(p, 7) == ref[6] and t_quantile(p, 7.0) == ref[6]


def test_an_interval_is_the_same_double_as_with_scipy():
    rng = np.random.default_rng(3)
    for n in (2, 3, 5, 10, 31, 200):
        x = rng.normal(80.0, 5.0, n)
        for confidence in (0.9, 0.95, 0.99):
            half = scipy_stats.t.ppf(0.5 + confidence / 2.0, n - 1) * x.std(ddof=1) / np.sqrt(n)
            mean, low, high = t_interval(x, confidence)
            assert (low, high) == (float(x.mean()) - half, float(x.mean()) + half)
            assert mean == float(x.mean())


def test_bad_arguments_are_refused():
    for p in (0.0, 1.0, -0.1, float("nan")):
        with pytest.raises(ValueError, match="p: "):
            t_quantile(p, 3)
    for df in (0.0, -1.0, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="df: "):
            t_quantile(0.9, df)
    assert t_quantile(0.5, 4) == 0.0


def test_the_core_statistics_import_no_scipy():
    code = (
        "import sys; from pnp_twin.twin.stats import t_interval, t_quantile; "
        "t_interval([1.0, 2.0, 4.0]); t_quantile(0.97, 12); t_quantile(0.975, 3000); "
        "print('scipy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
