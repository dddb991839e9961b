"""Rollout targets: sampled futures in the twin, the labels, and train --targets rollout."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")
torch.set_num_threads(1)

from pnp_twin.learning.rollout import LabelSettings, label_episode  # noqa: E402
from pnp_twin.learning.rollout_train import RolloutArgs, train_rollout  # noqa: E402
from pnp_twin.policies.base import RuleMix  # noqa: E402
from pnp_twin.policies.registry import make_policy  # noqa: E402
from pnp_twin.twin.feeder import resampled, splice  # noqa: E402
from pnp_twin.twin.line import Line  # noqa: E402
from pnp_twin.twin.loader import load_scenario, with_overrides  # noqa: E402
from pnp_twin.twin.run import simulate  # noqa: E402

SMALL = LabelSettings(futures=2, episode_time=6.0, window=(2.0, 3.0))


def test_splice_keeps_the_past_and_takes_the_future_from_the_other_stream():
    now = (np.array([0.1, 0.5, 0.9]), np.array([1.0, 2.0, 3.0]), ["a", "b", "c"])
    then = (np.array([0.2, 0.6, 0.7, 1.2]), np.array([9.0, 8.0, 7.0, 6.0]), ["w", "x", "y", "z"])
    t, y, kind = splice(now, then, 0.5)
    assert t.tolist() == [0.1, 0.5, 0.6, 0.7, 1.2]
    assert y.tolist() == [1.0, 2.0, 8.0, 7.0, 6.0]
    assert kind == ["a", "b", "x", "y", "z"]


def test_a_sampled_future_changes_only_the_parts_fed_after_its_start():
    scenario = load_scenario("paper_baseline")
    real = Line(scenario, RuleMix(["SPT"]), seed=4, duration=20.0)
    future = resampled(scenario, 4, 99, 8.0, 20.0)
    other = Line(scenario, RuleMix(["SPT"]), seed=4, duration=20.0, parts=future)
    fed, alt = np.asarray(real.belt.fed), np.asarray(other.belt.fed)
    k = int((fed <= 8.0).sum())
    assert np.array_equal(alt[:k], fed[:k]) and np.array_equal(
        np.asarray(other.belt.y)[:k], np.asarray(real.belt.y)[:k]
    )
    assert alt[k] > 8.0 and not np.array_equal(alt[k : k + 20], fed[k : k + 20])


def test_labels_are_advantages_over_the_base_rule_and_repeat_exactly():
    scenario = load_scenario("paper_baseline")
    a = label_episode(scenario, 7, SMALL)
    b = label_episode(scenario, 7, SMALL)
    assert len(a) > 0
    assert a.obs.shape[1:] == (2, 8, 64) and a.obs.dtype == np.uint8
    assert set(a.robot.tolist()) <= {0, 1, 2, 3}
    base = SMALL.rules.index("SPT")
    assert np.all(a.advantage[:, base] == 0.0)
    assert np.any(a.advantage != 0.0)  # some other choice changes what gets gripped
    # an advantage is a difference of mean counts over 2 futures: a multiple of 1/2
    assert np.allclose(a.advantage * 2, np.round(a.advantage * 2))
    assert np.array_equal(a.obs, b.obs) and np.array_equal(a.advantage, b.advantage)


@pytest.mark.parametrize(
    ("name", "seeds"), [("paper_baseline", (7, 8)), ("breakdowns", (2,)), ("two_robot", (4,))]
)
def test_forked_labels_equal_the_replayed_labels(name, seeds):
    """The fast engine forks at each decision; the SimPy path replays from t = 0."""
    scenario = with_overrides(load_scenario(name), {"termination": "t_continue", "warmup": 0.0})
    settings = LabelSettings(futures=3)
    for seed in seeds:
        a = label_episode(scenario, seed, settings, engine="simpy")
        b = label_episode(scenario, seed, settings, engine="fast")
        assert len(a) > 0
        for field in ("obs", "robot", "advantage"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_labelled_observations_show_the_parts_on_the_belt():
    scenario = load_scenario("paper_baseline")
    labels = label_episode(scenario, 3, SMALL)
    parts, claimed = labels.obs[:, 0], labels.obs[:, 1]
    assert parts.sum(axis=(1, 2)).min() >= 5  # 10 parts/s on a 2.4 m belt at 0.8 m/s
    assert np.all(claimed <= parts)  # a claimed part is a part


def test_rollout_training_writes_a_policy_identical_for_any_worker_count(tmp_path):
    folders = []
    for workers in (1, 2):
        args = RolloutArgs(
            out=str(tmp_path / f"w{workers}"),
            episodes=2,
            round_episodes=2,
            workers=workers,
            settings=SMALL,
            epochs=2,
            eval_seeds=2,
            eval_duration=20.0,
        )
        folders.append(train_rollout(args))
    one, two = folders
    # the weights depend on the labels and the seed, not on the worker count
    assert (one / "model.safetensors").read_bytes() == (two / "model.safetensors").read_bytes()
    meta = json.loads((one / "meta.json").read_text())
    assert meta["mode"] == "async" and meta["view"] == "belt" and meta["targets"] == "rollout"
    assert meta["obs_shape"] == [2, 8, 64] and meta["rules"] == list(SMALL.rules)
    rows = (one / "eval.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[1].split(",")[1] == "2"  # step (labels), episodes
    assert 0.0 < float(rows[1].split(",")[3]) <= 100.0
    policy = make_policy(f"hdqn:{one}")
    line = with_overrides(load_scenario("paper_baseline"), {"duration": 15.0, "warmup": 2.0})
    kpis = simulate(line, policy, seed=5).kpis
    assert set(kpis["decisions"]) - {"NooP"} <= set(SMALL.rules)
    assert not math.isnan(kpis["gripping_rate"])


def test_rollout_training_resumes_from_its_labels(tmp_path):
    # a window of 2 s: on paper_baseline the second episode has no labelled decision in SMALL's
    args = RolloutArgs(
        out=str(tmp_path),
        episodes=1,
        round_episodes=1,
        settings=LabelSettings(futures=2, episode_time=6.0, window=(2.0, 4.0)),
        epochs=1,
        eval_seeds=2,
        eval_duration=20.0,
    )
    folder = train_rollout(args)
    first = np.load(folder / "labels.npz")["advantage"]
    args.episodes, args.resume = 2, True
    train_rollout(args)
    with np.load(folder / "labels.npz") as z:
        assert int(z["done"]) == 2
        assert np.array_equal(z["advantage"][: len(first)], first)
        assert len(z["advantage"]) > len(first)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--mode", "sync"], "use --mode async"),
        (["--seeds", "2"], "trains one seed"),
        (["--rules", "FIFO,SIRO,SPT"], "SIRO chooses at random"),
        (["--rules", "FIFO,LD"], "base: 'SPT' must be one of the rules"),
        (["--network", "huge"], "--network: 'huge' is not a preset"),
    ],
)
def test_train_with_rollout_targets_rejects_bad_options_in_one_line(extra, message, tmp_path):
    from typer.testing import CliRunner

    import pnp_twin.cli.learn_cmd  # noqa: F401
    from pnp_twin.cli.app import app

    args = ["train", "paper_baseline", "--targets", "rollout", "--out", str(tmp_path), *extra]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output
    assert not any(tmp_path.iterdir())


def test_the_shipped_rollout_model_beats_spt_on_held_out_seeds():
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "models" / "paper_baseline__async_rollout"
    line = load_scenario("paper_baseline")  # 600 s runs, seeds that training never saw
    for seed in (0, 1):
        hdqn = simulate(line, make_policy(f"hdqn:{folder}"), seed=seed).kpis
        spt = simulate(line, make_policy("SPT"), seed=seed).kpis
        assert hdqn["gripping_rate"] > spt["gripping_rate"]
        assert hdqn["decisions"].get("FIFO", 0) > 0  # it does switch rules, not SPT throughout
