"""The student for any robot count and order (feature set ``student-any-v1``): one checkpoint
on 2 to 16 robots, both engines alike, pooled robots (order within a group does not count),
and one warning line on lines far outside its training range."""

from __future__ import annotations

import logging

import numpy as np
import pytest

pytest.importorskip("torch")

from pnp_twin.learning.student import LineSpec, StudentArgs, train_student  # noqa: E402
from pnp_twin.policies.hdqn import (
    features_any,  # noqa: E402
    ranges,  # noqa: E402
)
from pnp_twin.policies.hdqn import features_compiled as fc  # noqa: E402
from pnp_twin.policies.hdqn.checkpoint import read_meta  # noqa: E402
from pnp_twin.policies.hdqn.features import size  # noqa: E402
from pnp_twin.policies.hdqn.policy import HDQNPolicy  # noqa: E402
from pnp_twin.policies.registry import make_policy  # noqa: E402
from pnp_twin.twin.loader import load_scenario  # noqa: E402
from pnp_twin.twin.run import simulate  # noqa: E402

ANY = "student-any-v1"


def line(count: int, rate: float, **extra: object):  # type: ignore[no-untyped-def]
    sets = {"robots.count": count, "feeder.rate": rate, "duration": 20.0, "warmup": 2.0}
    if count > 8:  # room on the belt for every workspace
        sets["belt.length"] = 0.3 + 0.2192 * count + 0.2
    return load_scenario("paper_baseline", {**sets, **extra})


@pytest.fixture(scope="module")
def student(tmp_path_factory):  # type: ignore[no-untyped-def]
    args = StudentArgs(
        lines=[LineSpec("paper_baseline", ("robots.count=2", "feeder.rate=5")),
               LineSpec("paper_baseline", ("robots.count=5", "feeder.rate=12.5"))],
        out=str(tmp_path_factory.mktemp("any")), name="any", teacher="lookahead:K=4,H=1,base=SD",
        runs=2, duration=20.0, dagger=0, epochs=3, features=ANY, holdout=0.5,
    )  # fmt: skip
    return train_student(args)


def test_size_does_not_depend_on_the_count():
    assert size(ANY, 5, 2) == size(ANY, 5, 4) == size(ANY, 5, 16) == features_any.size(5)


def test_checkpoint_records_its_training_range(student):
    meta = read_meta(student)
    assert meta["features"] == ANY
    assert meta["train_args"]["ranges"]["robots"] == [2.0, 5.0]
    assert meta["train_args"]["ranges"]["feeder_rate"] == [5.0, 12.5]


@pytest.mark.parametrize("count,rate", [(3, 7.5), (6, 15.0), (12, 30.0)])
def test_one_student_runs_on_any_count_on_both_engines(student, count, rate):
    scenario = line(count, rate)
    runs = [
        simulate(scenario, HDQNPolicy.load(student), seed=3, engine=e) for e in ("fast", "simpy")
    ]
    assert runs[0].kpis["gripping_rate"] == runs[1].kpis["gripping_rate"]
    assert runs[0].parts["robot"].tolist() == runs[1].parts["robot"].tolist()
    assert runs[0].parts["robot"].nunique() == count  # every robot picks
    assert 0.0 < runs[0].kpis["gripping_rate"] <= 100.0


def test_pooled_features_ignore_the_order_of_the_other_robots():
    n, r = 6, 5
    rng = np.random.default_rng(0)
    v4 = rng.random(size("student-v4", r, n)).astype(np.float32)
    params = rng.random((n, features_any.PARAMS))
    args = (fc.PER_PICK, fc.PER_ROBOT, fc.slots_size(r))
    a = np.empty(features_any.size(r), np.float32)
    features_any.pool(a, v4, 1, n, r, *args, params)
    at = n + fc.PER_PICK * r  # the per-robot blocks: swap robots 3 and 5 (both downstream)
    b4 = v4.copy()
    b4[at + 4 * 3 : at + 4 * 4], b4[at + 4 * 5 : at + 4 * 6] = (
        v4[at + 4 * 5 : at + 4 * 6].copy(), v4[at + 4 * 3 : at + 4 * 4].copy())  # fmt: skip
    b = np.empty_like(a)
    features_any.pool(b, b4, 1, n, r, *args, params)
    np.testing.assert_allclose(a, b, rtol=1e-6)
    b4[at + 4 * 2] += 0.5  # the nearest downstream robot is seen on its own
    features_any.pool(b, b4, 1, n, r, *args, params)
    assert not np.allclose(a, b)


def test_one_warning_far_outside_the_training_range(student, caplog, monkeypatch):
    monkeypatch.setattr(ranges, "_WARNED", set())  # earlier tests of this process warned
    policy = make_policy(f"hdqn:{student}")
    with caplog.at_level(logging.WARNING):
        simulate(line(4, 10.0), policy, seed=1, engine="fast")
        assert not caplog.records  # inside: 4 robots, 10 parts/s
        for _ in range(2):  # once per process, not per run
            simulate(line(12, 30.0), make_policy(f"hdqn:{student}"), seed=1, engine="fast")
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and "robots 12 (trained 2 to 5)" in lines[0]
    assert "feeder_rate 30" in lines[0]


def test_student_general_warns_at_belt_one_metre_a_second(caplog, monkeypatch):
    """Trained across lines at belt 0.8 m/s: at 1.0 m/s, one warning (issue #33)."""
    monkeypatch.setattr(ranges, "_WARNED", set())
    scenario = load_scenario("paper_baseline", {"belt.speed": 1.0, "duration": 10.0, "warmup": 1.0})
    with caplog.at_level(logging.WARNING):
        simulate(scenario, make_policy("hdqn:student_general"), seed=1, engine="fast")
    assert any("belt_speed 1 (trained 0.8 to 0.8)" in r.getMessage() for r in caplog.records)
    general = HDQNPolicy.load("student_general")
    assert general.ranges is not None and general.ranges["arm_speed"] == [1.5, 4.0]
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        simulate(load_scenario("paper_baseline", {"duration": 10.0, "warmup": 1.0}), general)
    assert not caplog.records  # a line it was trained on
