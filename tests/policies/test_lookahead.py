"""The lookahead controller: same run on both engines, only candidates picked, the
clairvoyant variant is the planner told the true future, names parsed or refused."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.policies.lookahead import (
    TRIED,
    Lookahead,
    LookaheadError,
    LookaheadSettings,
    from_spec,
    parse,
)
from pnp_twin.policies.rules import RULES
from pnp_twin.twin.decision import Decision
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate
from pnp_twin.twin.scenario import Scenario


def short(name: str = "paper_baseline", **sets: Any) -> Scenario:
    return load_scenario(name, {"duration": 15.0, "warmup": 2.0, **sets})


def same_on_both_engines(sc: Scenario, spec: str, seed: int = 3) -> Any:
    policies = [from_spec(spec.partition(":")[2]), from_spec(spec.partition(":")[2])]
    a = simulate(sc, policies[0], seed=seed, engine="simpy")
    b = simulate(sc, policies[1], seed=seed, engine="fast")
    assert b.meta["engine"] == "fast"
    for table in ("parts", "spans", "decisions"):
        pd.testing.assert_frame_equal(getattr(a, table), getattr(b, table), check_exact=True)
    assert repr(a.kpis) == repr(b.kpis)
    sa, sb = (p.stats() for p in policies)
    assert (sa["decisions"], sa["planned"], sa["base"]) == (
        sb["decisions"],
        sb["planned"],
        sb["base"],
    )
    assert sa["planned"] > 0 and sa["cpu_ms_per_decision"] > 0
    return a


@pytest.mark.parametrize(
    ("name", "sets", "spec"),
    [
        ("paper_baseline", {}, "lookahead:K=4,H=1.5,base=SD"),
        ("paper_baseline", {"termination": "t_any"}, "lookahead:K=3,H=1,base=SPT"),
        # breakdowns often enough that failures and repairs are redrawn inside the run
        ("breakdowns", {"robots.mtbf": 4.0, "robots.mttr": 1.0}, "lookahead:K=3,H=1"),
        ("paper_baseline", {"feeder.arrival": "normal", "feeder.cv": 0.5}, "lookahead:K=3"),
        ("paper_baseline", {}, "lookahead:H=1.5,oracle=1"),
    ],
)
def test_the_same_run_on_both_engines(name: str, sets: dict[str, Any], spec: str) -> None:
    a = same_on_both_engines(short(name, **sets), spec)
    assert a.kpis["parts_picked"] > 0
    again = simulate(short(name, **sets), make_policy(spec), seed=3, engine="fast")
    assert repr(again.kpis) == repr(a.kpis)  # reproducible


class _Checked(Lookahead):
    """Records, at each decision, the rules' picks and the answer."""

    def __init__(self, settings: LookaheadSettings) -> None:
        super().__init__(settings)
        self.seen: list[tuple[set[int], int, str | None]] = []
        self.valued: list[list[int]] = []

    def choose(self, decision: Decision) -> int:
        picks = {RULES[r](decision, np.random.default_rng(0)) for r in TRIED}
        k = super().choose(decision)
        self.seen.append((picks, k, self.last_rule))
        return k

    def values(self, line: Any, candidates: list[int]) -> list[int]:
        self.valued.append(list(candidates))
        return super().values(line, candidates)


def test_the_planner_picks_only_candidates() -> None:
    policy = _Checked(parse("K=4,H=2,base=SD"))
    result = simulate(short(), policy, seed=1, engine="fast")
    assert policy.seen and policy.valued
    assert all(k in picks for picks, k, _ in policy.seen)
    assert all(rule in TRIED for _, _, rule in policy.seen)
    assert any(k != min(picks) for picks, k, _ in policy.seen)  # it does not always take one
    for cands in policy.valued:
        assert len(cands) == len(set(cands)) >= 2
    names = set(result.decisions["rule"]) - {"NooP"}
    assert names <= set(TRIED)


class _TrueFutures(Lookahead):
    """K sampled futures replaced by K copies of the true one."""

    def futures(self, line: Any, n_kept: int, until: float) -> list[Any]:
        m = int(np.searchsorted(line.fed, until, "right"))
        return [(line.fed[:m], line.y[:m])] * self.settings.futures


class _Futures(Lookahead):
    def __init__(self, settings: LookaheadSettings) -> None:
        super().__init__(settings)
        self.drawn: list[Any] = []
        self.choices: list[int] = []

    def futures(self, line: Any, n_kept: int, until: float) -> list[Any]:
        out = super().futures(line, n_kept, until)
        self.drawn.append((line.fed.copy(), line.y.copy(), n_kept, until, out))
        return out

    def choose(self, decision: Decision) -> int:
        self.choices.append(super().choose(decision))
        return self.choices[-1]


def test_the_clairvoyant_variant_is_the_planner_told_the_true_future() -> None:
    sc = short()
    oracle = _Futures(parse("H=1.5,base=SD,oracle=1"))
    told = _TrueFutures(parse("K=3,H=1.5,base=SD"))
    a = simulate(sc, oracle, seed=2, engine="fast")
    b = simulate(sc, told, seed=2, engine="fast")
    pd.testing.assert_frame_equal(a.parts, b.parts, check_exact=True)
    # the oracle's one future is the run's own stream, through the continuation's end
    for fed, y, _, until, out in oracle.drawn:
        assert len(out) == 1
        f, lat = out[0]
        assert np.array_equal(f, fed[: len(f)]) and np.array_equal(lat, y[: len(f)])
        assert len(f) == len(fed) or fed[len(f)] > until
    sampled = _Futures(parse("K=3,H=1.5,base=SD"))
    c = simulate(sc, sampled, seed=2, engine="fast")
    assert sampled.choices != oracle.choices or not c.parts.equals(a.parts)
    for fed, y, n_kept, until, out in sampled.drawn:  # the belt kept, later parts redrawn
        assert len(out) == 3
        for f, lat in out:
            assert np.array_equal(f[:n_kept], fed[:n_kept])
            assert np.array_equal(lat[:n_kept], y[:n_kept])
            assert np.all(np.diff(f) >= 0) and np.all(f[n_kept:] <= until)


def test_names_and_defaults() -> None:
    assert parse("") == LookaheadSettings()
    p = make_policy("lookahead")
    assert isinstance(p, Lookahead) and p.name == "lookahead:K=16,H=1,base=auto"
    q = make_policy(" LOOKAHEAD:k=8, h=2.5 ,Base=spt ")
    assert isinstance(q, Lookahead) and q.name == "lookahead:K=8,H=2.5,base=SPT"
    assert from_spec("oracle=1,H=1").name == "lookahead:H=1,base=auto,oracle=1"


@pytest.mark.parametrize(
    "arg",
    ["K=0", "K=x", "K=1.5", "H=0", "H=-1", "H=nan", "H=inf", "base=SIRO", "base=best",
     "oracle=maybe", "depth=3", "K", "K=", "K=8,K=9", "=3"],
)  # fmt: skip
def test_bad_names_are_one_line(arg: str) -> None:
    with pytest.raises(LookaheadError) as e:
        make_policy(f"lookahead:{arg}")
    assert isinstance(e.value, UserError)
    assert "\n" not in str(e.value) and str(e.value).startswith("policy: lookahead:")


def test_a_run_it_was_not_bound_to_is_refused() -> None:
    policy = make_policy("lookahead:K=2")
    sc = short()
    policy.reset([], np.random.default_rng(0))
    with pytest.raises(RuntimeError, match="bind_run"):
        policy.choose(
            Decision(_spec(sc), 0.0, (0.0, 0.0), [0, 1], [0.5, 0.6], [0.1, 0.2], [0.1, 0.2])
        )


def _spec(sc: Scenario) -> Any:
    from pnp_twin.twin.fast.engine import FastLine

    return FastLine(sc, rules=["SD"]).specs[0]


def test_evaluate_places_the_lookahead_controller(tmp_path: Any) -> None:
    from typer.testing import CliRunner

    from pnp_twin.cli import app

    args = ["evaluate", "paper_baseline", "--policy", "lookahead:K=2", "--seeds", "2"]
    args += ["--duration", "12", "--mix", "SD", "--out", str(tmp_path / "ev")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.stderr
    assert "lookahead:K=2,H=1,base=auto" in result.stdout
    rows = (tmp_path / "ev" / "evaluation.csv").read_text().splitlines()
    assert rows[1].startswith("paper_baseline,lookahead,")
