"""``--backend ray`` on ``design``, ``capacity`` and ``headroom``: the same answers as the
local backend (seeds are fixed per run), on a local Ray as the sweep tests use (issue #32)."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest

from pnp_twin.cli.decision_opts import executor
from pnp_twin.parallel import ray_session
from pnp_twin.studies.backends import Executor
from pnp_twin.studies.capacity import run_capacity
from pnp_twin.studies.design import run_design
from pnp_twin.studies.headroom import HeadroomSettings, run_headroom
from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.loader import load_scenario

LINE = {"robots.count": 2, "feeder.rate": 4.0, "duration": 30.0, "warmup": 5.0, "seed": 5}
SAME = ("choice", "gripping_rate", "ci_low", "ci_high", "total_cost", "rows")


def test_design_capacity_and_headroom_on_ray_equal_local(
    tmp_path: Path, foreign_signal_handlers: dict
) -> None:
    pytest.importorskip("ray")
    sc = load_scenario("paper_baseline", LINE)
    local_d = run_design(sc, tmp_path / "dl", 80.0, ["robots.count=1:3"], ["SD"], None, 0.95, 3, 6)
    local_c = run_capacity(sc, tmp_path / "cl", 80.0, 0.95, ["SD"], 3, 1, "auto")
    settings = HeadroomSettings(seeds=2, mix="SD,SD", engine="fast", lookahead="lookahead:K=4")
    local_h = run_headroom(sc, settings).to_json()
    with ray_session(2, None), Executor("ray", 2) as ray:
        d = run_design(
            sc, tmp_path / "dr", 80.0, ["robots.count=1:3"], ["SD"], None, 0.95, 3, 6,
            executor=ray,
        )  # fmt: skip
        c = run_capacity(sc, tmp_path / "cr", 80.0, 0.95, ["SD"], 3, 2, "auto", executor=ray)
        from dataclasses import replace

        h = run_headroom(sc, replace(settings, backend="ray", workers=2)).to_json()
    assert {k: d[k] for k in SAME} == {k: local_d[k] for k in SAME}
    assert d["runs_simulated"] == local_d["runs_simulated"] > 0
    assert (c["max_rate"], c["ci_low"], c["ci_high"], c["backend"]) == (
        local_c["max_rate"], local_c["ci_low"], local_c["ci_high"], "ray",
    )  # fmt: skip
    for key in ("best_rule", "best_mix", "lookahead", "bound"):
        mine, theirs = h[key], local_h[key]
        assert (mine["gripping_rate"], mine["ci_low"]) == (
            theirs["gripping_rate"],
            theirs["ci_low"],
        )
    for s, handler in foreign_signal_handlers.items():  # Ray's SIGTERM handler given back
        assert signal.getsignal(s) is handler, signal.Signals(s).name


def test_an_address_without_ray_is_one_line() -> None:
    with pytest.raises(StudyError, match="--address: only with --backend ray"):
        executor("local", 1, "127.0.0.1:6379")
    with pytest.raises(StudyError, match="--backend: 'dask' is not allowed"):
        executor("dask", 1, None)
