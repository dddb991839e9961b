"""IPPO / MAPPO checkpoints as policies (``--policy marl:DIR``), and the training logs (CSV,
TensorBoard, G from short evaluation runs at fixed step intervals)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from typer.testing import CliRunner  # noqa: E402

from pnp_twin.cli.app import app  # noqa: E402
from pnp_twin.learning.marl_checkpoint import save_marl  # noqa: E402
from pnp_twin.learning.marl_eval import rates  # noqa: E402
from pnp_twin.learning.marl_log import COLUMNS, TrainLog  # noqa: E402
from pnp_twin.learning.marl_ppo import PPOConfig, train  # noqa: E402
from pnp_twin.learning.tasks import get_task  # noqa: E402
from pnp_twin.policies.marl_policy import MarlPolicy  # noqa: E402
from pnp_twin.policies.registry import make_policy  # noqa: E402
from pnp_twin.twin.run import simulate  # noqa: E402

FIVE = ("FIFO", "LIFO", "SD", "LD", "SPT")  # no SIRO: the twin and the env draw it differently
CFG = PPOConfig(algo="mappo", rules=FIVE, total_steps=1024, num_envs=8, rollout=32,
                epochs=2, minibatches=2, duration=20.0, seed=4, eval_every=512,
                eval_seeds=2, eval_duration=20.0)  # fmt: skip


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    folder = tmp_path_factory.mktemp("marl")
    log = TrainLog(folder, tensorboard=True)
    result = train(CFG, progress=log)
    log.close()
    save_marl(result, folder)
    return result, folder


def test_log_has_eval_g_at_fixed_intervals_and_tensorboard(trained):
    result, folder = trained
    with open(folder / "progress.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == COLUMNS and len(rows) == 4  # 1024 steps, 256 per update
    evals = [int(r["env_steps"]) for r in rows if r["eval_G"]]
    assert evals == [512, 1024]
    for r in rows:
        if r["eval_G"]:
            assert float(r["eval_G_low"]) <= float(r["eval_G"]) <= float(r["eval_G_high"])
            assert 0.0 < float(r["eval_G"]) <= 100.0
    assert list(folder.glob("events.out.tfevents.*"))


def test_checkpoint_loads_with_the_actors_logits(trained):
    result, folder = trained
    policy = MarlPolicy.load(folder)
    obs = np.random.default_rng(0).integers(0, 2, (3, 4, 1, 8, 7)).astype(np.uint8)
    mask = np.ones((3, 4, len(FIVE)), np.int8)
    want = result.policy.logits(obs, mask)
    x = result.policy.features.observation(obs, mask)
    with torch.no_grad():
        got = policy.net(x)
    assert torch.allclose(got, want, atol=1e-6)
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["kind"] == "marl" and meta["algo"] == "mappo" and meta["rules"] == list(FIVE)


def test_twin_runs_the_policy_as_the_env_does(trained):
    """Both engines run it identically; over a whole task run its G is the env's within the
    few hundredths by which the env's G and the twin's differ for a fixed rule too (LIFO on
    seed 1000: 66.685 in the twin, 66.661 in the env)."""
    _, folder = trained
    short = get_task("baseline").line(20.0)
    fast, simpy = (
        simulate(short, make_policy(f"marl:{folder}"), seed=7, engine=e).kpis["gripping_rate"]
        for e in ("fast", "simpy")
    )
    assert fast == simpy
    line = get_task("baseline").line()
    twin = simulate(line, make_policy(f"marl:{folder}"), seed=1000, engine="fast")
    env = rates("baseline", MarlPolicy.load(folder).act_env, [1000], rules=FIVE)
    assert twin.kpis["gripping_rate"] == pytest.approx(env[0], abs=0.1)


def test_cli_runs_marl_policy_and_rejects_bad_ones(trained, tmp_path):
    _, folder = trained
    runner = CliRunner()
    ok = runner.invoke(app, ["run", "paper_baseline", "--policy", f"marl:{folder}",
                             "--set", "duration=20", "--set", "warmup=2"])  # fmt: skip
    assert ok.exit_code == 0, ok.output
    five = runner.invoke(app, ["run", "paper_baseline", "--policy", f"marl:{folder}",
                               "--set", "robots.count=5", "--set", "duration=20",
                               "--set", "warmup=2"])  # fmt: skip
    assert five.exit_code == 2 and "trained for 4 robots" in five.output
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "meta.json").write_text(json.dumps({"format": 1, "kind": "marl"}))
    broken = runner.invoke(app, ["run", "paper_baseline", "--policy", f"marl:{bad}"])
    assert broken.exit_code == 2 and "checkpoint:" in broken.output
    assert len(broken.output.strip().splitlines()) == 1


def test_evaluations_during_training_change_nothing(trained):
    """Same seed, same weights, with or without the evaluation runs in between."""
    result, _ = trained
    plain = train(PPOConfig(**{**CFG.__dict__, "eval_every": 0}))
    want = result.policy.actor.state_dict()
    for k, v in plain.policy.actor.state_dict().items():
        assert torch.equal(v, want[k]), k
    assert "eval_G" not in plain.log[-1] and "eval_G" in result.log[-1]
