"""The HDQN: networks, replay, semi-MDP targets, training, checkpoints, the policy adapter."""

from __future__ import annotations

import csv
import json
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")
torch.set_num_threads(1)  # tiny networks: two intra-op threads are 100x slower on a busy box

from pnp_twin.learning.dqn_update import DQNAgent, semi_mdp_targets  # noqa: E402
from pnp_twin.learning.replay import Batch, ReplayBuffer  # noqa: E402
from pnp_twin.learning.train import TrainArgs, train  # noqa: E402
from pnp_twin.learning.train_checkpoint import save_checkpoint  # noqa: E402
from pnp_twin.policies.hdqn.agent import AgentConfig, decode_joint, encode_joint  # noqa: E402
from pnp_twin.policies.hdqn.checkpoint import load_agent  # noqa: E402
from pnp_twin.policies.hdqn.network import build_network  # noqa: E402
from pnp_twin.policies.registry import make_policy  # noqa: E402
from pnp_twin.twin.loader import load_scenario, with_overrides  # noqa: E402
from pnp_twin.twin.run import simulate  # noqa: E402

TINY = {"robots.count": 2, "feeder.rate": 5.0}


@pytest.mark.parametrize("preset", ["paper", "compact", "pooled"])
@pytest.mark.parametrize(("shape", "extra", "actions"), [((1, 8, 14), 4, 5), ((2, 8, 64), 0, 36)])
def test_network_output_shapes(preset, shape, extra, actions):
    net = build_network(preset, shape, actions, extra)
    obs = torch.zeros((3, *shape), dtype=torch.uint8)
    q = net(obs, torch.zeros(3, extra) if extra else None)
    assert q.shape == (3, actions)
    assert torch.isfinite(q).all()


def test_unknown_preset_names_the_presets():
    with pytest.raises(ValueError, match="allowed paper, compact"):
        build_network("huge", (1, 8, 64), 5)


def test_replay_ring_buffer_wraps():
    buf = ReplayBuffer(3, (1, 2, 2), n_extra=1)
    for i in range(5):
        obs = np.full((1, 2, 2), i, dtype=np.uint8)
        buf.add(obs, i, float(i), obs + 1, 0.1 * i, i == 4, np.array([i]), np.array([i + 1]))
    assert len(buf) == 3 and buf.pos == 2 and buf.added == 5
    # slots 0, 1 were overwritten by transitions 3, 4; slot 2 still holds transition 2
    assert buf.action.tolist() == [3, 4, 2]
    assert buf.obs[:, 0, 0, 0].tolist() == [3, 4, 2]
    assert buf.next_obs[:, 0, 0, 0].tolist() == [4, 5, 3]
    assert buf.done.tolist() == [0.0, 1.0, 0.0]
    assert buf.extra[:, 0].tolist() == [3, 4, 2]
    batch = buf.sample(50, np.random.default_rng(0))
    assert set(batch.action.tolist()) <= {2, 3, 4}
    assert np.allclose(batch.reward, batch.action)


def test_replay_save_and_load_round_trip(tmp_path):
    buf = ReplayBuffer(4, (1, 2, 3))
    for i in range(6):
        buf.add(
            np.full((1, 2, 3), i, np.uint8), i, i / 2, np.zeros((1, 2, 3), np.uint8), 1.0, False
        )
    buf.save(tmp_path / "r.npz")
    back = ReplayBuffer(4, (1, 2, 3))
    back.load(tmp_path / "r.npz")
    assert (back.pos, back.size, back.added) == (2, 4, 6)
    assert np.array_equal(back.obs, buf.obs) and np.array_equal(back.reward, buf.reward)


def test_semi_mdp_target_by_hand():
    reward = torch.tensor([1.0, 0.0, -0.01])
    tau = torch.tensor([0.5, 2.0, 0.05])
    done = torch.tensor([0.0, 0.0, 1.0])
    q_next = torch.tensor([[1.0, 3.0], [4.0, 2.0], [9.0, 9.0]])
    y = semi_mdp_targets(reward, tau, done, q_next, gamma=0.9)
    expected = [1.0 + 0.9**0.5 * 3.0, 0.0 + 0.9**2.0 * 4.0, -0.01]
    assert y.tolist() == pytest.approx(expected, rel=1e-6)
    # Double DQN: the online network picks the action, the target network values it
    online = torch.tensor([[5.0, 0.0], [0.0, 5.0], [0.0, 0.0]])
    y2 = semi_mdp_targets(reward, tau, done, q_next, 0.9, next_q_online=online)
    assert y2.tolist() == pytest.approx([1.0 + 0.9**0.5 * 1.0, 0.9**2.0 * 2.0, -0.01], rel=1e-6)


def test_agent_update_regresses_towards_the_semi_mdp_target():
    torch.manual_seed(0)
    agent = DQNAgent(AgentConfig(lr=3e-3, double=False), (1, 2, 3), 2)
    rng = np.random.default_rng(0)
    obs = rng.integers(0, 2, (8, 1, 2, 3)).astype(np.uint8)
    batch = Batch(
        obs=obs,
        extra=np.zeros((8, 0), np.float32),
        action=rng.integers(0, 2, 8),
        reward=np.ones(8, np.float32),
        next_obs=obs,
        next_extra=np.zeros((8, 0), np.float32),
        tau=np.full(8, 0.5, np.float32),
        done=np.ones(8, np.float32),  # terminal: the target is the reward, 1.0
    )
    first = agent.update(batch)
    for _ in range(60):
        last = agent.update(batch)
    assert np.isfinite(first) and last < first / 10
    q = agent.q_values(obs)[np.arange(8), batch.action]
    assert q == pytest.approx(np.ones(8), abs=0.1)


def test_joint_action_round_trip_matches_the_env_encoding():
    assert decode_joint(encode_joint([1, 0, 4, 2], 5), 4, 5) == [1, 0, 4, 2]
    assert decode_joint(5**3, 4, 5) == [1, 0, 0, 0]  # robot 0 is the most significant digit


def test_checkpoint_loads_into_an_identical_greedy_policy(tmp_path):
    torch.manual_seed(3)
    agent = DQNAgent(AgentConfig(network="paper"), (1, 8, 14), 6, n_extra=4)
    meta = {
        "mode": "async",
        "rules": ["FIFO", "LIFO", "SIRO", "SD", "LD", "SPT"],
        "n_robots": 4,
        "scenario": load_scenario("paper_baseline").model_dump(mode="json"),
    }
    save_checkpoint(tmp_path / "ck", agent, meta)
    back, meta = load_agent(tmp_path / "ck")
    rng = np.random.default_rng(1)
    obs = rng.integers(0, 2, (32, 1, 8, 14)).astype(np.uint8)
    extra = np.eye(4, dtype=np.float32)[rng.integers(0, 4, 32)]
    assert np.array_equal(back.q_values(obs, extra), agent.q_values(obs, extra))
    assert meta["agent"]["network"] == "paper" and meta["obs_shape"] == [1, 8, 14]
    assert json.loads((tmp_path / "ck" / "meta.json").read_text())["versions"]["torch"]
    assert not list((tmp_path / "ck").glob("*.tmp"))  # atomic writes left nothing behind


def _tiny_args(out: Path, steps: int, mode: str = "async", **kw) -> TrainArgs:
    return TrainArgs(
        scenario="paper_baseline",
        mode=mode,
        out=str(out),
        steps=steps,
        episode_time=15.0,
        learning_starts=100,
        train_every=2,
        batch_size=32,
        buffer_size=2_000,
        eval_every=300,
        eval_seeds=2,
        eval_duration=15.0,
        log_every=100,
        overrides=dict(TINY),
        **kw,
    )


def _same_kpis(a: dict, b: dict) -> bool:
    """Equal KPIs, NaN equal to NaN (some KPI series hold NaN for empty bins)."""
    return json.dumps(a, sort_keys=True, default=str) == json.dumps(b, sort_keys=True, default=str)


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("hdqn")
    folder = train(_tiny_args(out, 400, save_replay=True))
    return out, folder


def test_training_logs_finite_losses_and_writes_checkpoints(trained):
    out, folder = trained
    assert folder.name == "paper_baseline__async__1"
    rows = _rows(folder / "log.csv")
    assert [int(r["step"]) for r in rows][-1] == 400
    losses = [float(r["loss"]) for r in rows if r["loss"] != "nan"]
    assert losses and all(np.isfinite(losses))
    evals = _rows(folder / "eval.csv")
    assert len(evals) >= 1 and all(0 <= float(e["gripping_rate"]) <= 100 for e in evals)
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["counters"]["step"] == 400 and meta["mode"] == "async"
    assert (folder / "best" / "model.safetensors").is_file()


def test_policy_runs_through_simulate_and_is_deterministic(trained):
    out, folder = trained
    scenario = with_overrides(
        load_scenario("paper_baseline", TINY), {"duration": 20.0, "warmup": 2.0}
    )
    a = simulate(scenario, make_policy(f"hdqn:{folder}"), seed=7)
    b = simulate(scenario, make_policy(f"hdqn:{out}"), seed=7)  # the run folder is found
    assert 0.0 < a.kpis["gripping_rate"] <= 100.0
    assert _same_kpis(a.kpis, b.kpis)
    used = set(a.decisions["rule"]) - {"NooP"}
    assert used and used <= {"FIFO", "LIFO", "SIRO", "SD", "LD", "SPT"}


def test_resume_continues_the_step_counter(trained, tmp_path):
    out, folder = trained
    import shutil

    copy = tmp_path / folder.name
    shutil.copytree(folder, copy)
    with (copy / "log.csv").open("a") as f:  # a row logged after the checkpoint (a crash)
        f.write("450,9,0.5,70,0.1,0.2,100\n")
    again = train(_tiny_args(tmp_path, 600, resume=True, save_replay=True))
    assert again == copy
    steps = [int(r["step"]) for r in _rows(copy / "log.csv")]
    before = [int(r["step"]) for r in _rows(folder / "log.csv")]
    assert steps[: len(before)] == before and before[-1] == 400  # the old rows are kept
    assert steps[-1] in (600, 601) and steps == sorted(steps) and len(steps) > len(before)
    assert json.loads((copy / "meta.json").read_text())["counters"]["step"] in (600, 601)
    assert 450 not in steps  # the row logged after the checkpoint was dropped


def test_single_mode_trains_a_joint_agent(tmp_path):
    folder = train(_tiny_args(tmp_path, 200, mode="single"))
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["n_actions"] == 6**2 and meta["obs_shape"] == [1, 8, 64]
    scenario = with_overrides(
        load_scenario("paper_baseline", TINY), {"duration": 10.0, "warmup": 1.0}
    )
    result = simulate(scenario, make_policy(f"hdqn:{folder}"), seed=3)
    assert result.kpis["parts_picked"] > 0


def test_missing_checkpoint_is_a_one_line_user_error(tmp_path):
    from pnp_twin.twin.errors import UserError

    with pytest.raises(UserError, match="holds no meta.json") as e:
        make_policy(f"hdqn:{tmp_path}")
    assert "\n" not in str(e.value)


def test_evaluate_command_prints_the_paired_table(trained):
    from typer.testing import CliRunner

    import pnp_twin.cli.learn_cmd  # noqa: F401
    from pnp_twin.cli.app import app

    out, folder = trained
    args = ["evaluate", "paper_baseline", "--policy", f"hdqn:{folder}", "--seeds", "2"]
    args += ["--duration", "15", "--mix", "SPT,FIFO", "--set", "robots.count=2"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    for name in ("HDQN (async)", "FIFO", "SPT", "mix SPT,FIFO", "paired 95% CI"):
        assert name in result.output


def test_training_validates_the_same_on_every_engine_and_records_which_ran(tmp_path):
    evals, metas = {}, {}
    for engine in ("simpy", "fast"):
        folder = train(_tiny_args(tmp_path / engine, 300, engine=engine))
        with (folder / "eval.csv").open() as f:
            rows = list(csv.DictReader(f))
        evals[engine] = [{k: v for k, v in r.items() if k != "wall_time"} for r in rows]
        metas[engine] = json.loads((folder / "meta.json").read_text())
    assert evals["simpy"] == evals["fast"] and len(evals["simpy"]) == 1
    for engine, meta in metas.items():
        assert meta["train_args"]["baseline_engine"] == meta["train_args"]["engine"] == engine


def test_evaluate_gives_the_same_table_on_every_engine_and_records_which_ran(trained, tmp_path):
    import pandas as pd
    from typer.testing import CliRunner

    from pnp_twin.cli import app

    _, folder = trained
    outputs, tables = {}, {}
    for engine in ("simpy", "fast", "auto"):
        args = ["evaluate", "paper_baseline", "--policy", f"hdqn:{folder}", "--seeds", "2"]
        args += ["--duration", "15", "--mix", "SPT,FIFO", "--set", "robots.count=2"]
        args += ["--engine", engine, "--out", str(tmp_path / engine)]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 0, result.output
        outputs[engine] = result.stdout
        tables[engine] = pd.read_csv(tmp_path / engine / "evaluation.csv")
    assert outputs["simpy"] == outputs["fast"] == outputs["auto"]
    for engine, table in tables.items():
        ran = dict(zip(table["kind"], table["engine"], strict=True))
        rules = "simpy" if engine == "simpy" else "fast"
        assert ran == {"hdqn": rules, "rule": rules, "mix": rules}, engine
    plain = [t.drop(columns="engine") for t in tables.values()]
    pd.testing.assert_frame_equal(plain[0], plain[1])
    pd.testing.assert_frame_equal(plain[0], plain[2])


@pytest.mark.parametrize(
    ("mode", "channels", "view"),
    [("async", 2, "window"), ("single", 3, "window"), ("async", 2, "belt")],
)
def test_policy_sees_the_same_observation_as_the_env_driver(mode, channels, view):
    from pnp_twin.learning.envs.driver import EpochDriver
    from pnp_twin.policies.hdqn.agent import robot_onehot
    from pnp_twin.policies.hdqn.policy import HDQNPolicy

    scenario = load_scenario("paper_baseline", TINY)
    driver = EpochDriver(scenario, seed=5, channels=channels)
    window = mode == "async" and view == "window"
    shape = driver.camera.window_shape if window else driver.camera.shape
    agent = DQNAgent(AgentConfig(), shape, 5, 2 if mode == "async" else 0)
    meta = {"mode": mode, "rules": ["FIFO", "LIFO", "SIRO", "SD", "LD"], "n_robots": 2}
    meta["view"] = view
    meta["scenario"] = scenario.model_dump(mode="json")
    policy = HDQNPolicy(agent, meta)
    deciding = driver.reset()
    assert driver.line is not None
    policy.reset(driver.line.specs, np.random.default_rng(0))
    policy.attach(driver.line.belt)
    compared = 0
    for step in range(300):
        for r in deciding:
            if len(deciding) > 1 and channels == 3:
                continue  # the busy channel: the policy sees one deciding robot at a time
            obs, extra = policy.observe(driver.line.robots[r].decision())
            want = driver.observe(r if window else None)
            assert np.array_equal(obs[0], want), f"step {step}, robot {r}"
            if mode == "async":
                assert np.array_equal(extra, robot_onehot([r], 2))
            compared += 1
        deciding = driver.act({r: step % 5 for r in deciding})
    assert compared > 200


def test_training_into_a_finished_run_without_resume_is_refused(trained):
    from pnp_twin.twin.errors import UserError

    out, folder = trained
    with pytest.raises(UserError, match="holds a run already"):
        train(_tiny_args(out, 500))


def test_team_credit_counts_the_picks_of_the_robot_and_those_downstream():
    from pnp_twin.learning.credit import TeamCredit

    credit = TeamCredit("downstream", 3)
    credit.add([1, 0, 1], [0, 2])  # robot 1 had no open option in this epoch
    credit.add([0, 1, 1], [0, 1, 2])
    assert [credit.take(r) for r in range(3)] == [4, 2, 2]
    assert credit.take(0) == 0  # taken once
    team = TeamCredit("team", 3)
    team.add([1, 0, 1], [2])
    assert team.take(2) == 2


def test_team_credit_on_the_driver_matches_the_options_and_all_picks():
    """Downstream credit of the last robot is its own option's pick; team credit of the
    first robot, whose options tile the episode, adds up to every pick of the line."""
    from pnp_twin.learning.credit import TeamCredit
    from pnp_twin.learning.envs.driver import EpochDriver

    driver = EpochDriver(load_scenario("paper_baseline", TINY), seed=3)
    down, team = TeamCredit("downstream", 2), TeamCredit("team", 2)
    deciding, opened, team_total, checked = driver.reset(), set(), 0, 0
    assert 0 in deciding  # the first robot decides at the first epoch
    for step in range(400):
        for r in deciding:
            option, got = driver.option(r), down.take(r)
            if r == 1 and option is not None:
                assert got == option.picks
                checked += 1
        if 0 in deciding:
            team_total += team.take(0)
        opened |= set(deciding)
        deciding = driver.act({r: step % 5 for r in deciding})
        down.add(driver.step_picks, opened)
        team.add(driver.step_picks, opened)
    assert checked > 50
    assert team_total + team.take(0) == sum(driver.total_picks) > 50


def test_belt_view_with_downstream_reward_trains_and_runs(tmp_path):
    folder = train(_tiny_args(tmp_path, 200, view="belt", channels=2, reward="downstream"))
    meta = json.loads((folder / "meta.json").read_text())
    assert meta["view"] == "belt" and meta["train_args"]["reward"] == "downstream"
    assert meta["obs_shape"] == [2, 8, 64] and meta["n_extra"] == 2
    scenario = with_overrides(
        load_scenario("paper_baseline", TINY), {"duration": 10.0, "warmup": 1.0}
    )
    a = simulate(scenario, make_policy(f"hdqn:{folder}"), seed=3)
    b = simulate(scenario, make_policy(f"hdqn:{folder}"), seed=3)
    assert a.kpis["parts_picked"] > 0 and _same_kpis(a.kpis, b.kpis)


def test_checkpoints_without_the_view_option_still_see_windows(tmp_path):
    from pnp_twin.policies.hdqn.policy import HDQNPolicy

    shipped = Path(__file__).resolve().parents[2] / "models" / "paper_baseline__async"
    if not (shipped / "meta.json").is_file():
        pytest.skip("no shipped checkpoint")
    # the shipped model as written before the view option existed: no "view" key
    folder = tmp_path / "before_view"
    shutil.copytree(shipped, folder)
    meta = json.loads((folder / "meta.json").read_text())
    assert meta.pop("view") == "window"
    (folder / "meta.json").write_text(json.dumps(meta))
    policy = HDQNPolicy.load(folder)
    # the window of a 0.2192 m workspace: 7 of the belt image's 64 columns
    assert not policy.whole_belt and policy.agent.obs_shape == (1, 8, 7)
    scenario = with_overrides(load_scenario("paper_baseline"), {"duration": 5.0, "warmup": 1.0})
    assert simulate(scenario, policy, seed=1).kpis["parts_picked"] > 0


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"view": "eyes"}, "view: 'eyes' is not a view; allowed window, belt"),
        ({"reward": "gold"}, "reward: 'gold' is not a reward; allowed own, downstream, team"),
        ({"mode": "single", "view": "belt"}, "single mode"),
    ],
)
def test_bad_view_or_reward_is_a_one_line_user_error(tmp_path, kw, match):
    from pnp_twin.twin.errors import UserError

    with pytest.raises(UserError, match=match) as e:
        train(_tiny_args(tmp_path, 10, **kw))
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(
    ("option", "value"),
    [("--view", "bogus"), ("--reward", "bogus"), ("--network", "huge"), ("--targets", "mc")],
)
def test_train_command_rejects_a_bad_option_in_one_line(option, value, tmp_path):
    from typer.testing import CliRunner

    import pnp_twin.cli.learn_cmd  # noqa: F401
    from pnp_twin.cli.app import app

    args = ["train", "paper_baseline", "--out", str(tmp_path), "--steps", "10", option, value]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert f"{option}: '{value}'" in result.output
    assert "Traceback" not in result.output
    assert not any(tmp_path.iterdir())  # nothing trained, nothing written


def test_training_seeds_on_ray_match_local_processes(tmp_path, foreign_signal_handlers):
    pytest.importorskip("ray")
    from typer.testing import CliRunner

    import pnp_twin.cli.learn_cmd  # noqa: F401
    from pnp_twin.cli.app import app

    # short: 120 steps (training updates from step 8), two evaluations of one 10 s run, on
    # the SimPy engine (what is compared is the backend; it took 982 s at 200 steps with
    # two 300 s evaluation runs on the compiled engine, compiled in each Ray worker)
    base = ["train", "paper_baseline", "--steps", "120", "--eval-every", "60"]
    base += ["--eval-seeds", "1", "--eval-duration", "10", "--episode-time", "15"]
    base += ["--engine", "simpy", "--seeds", "2", "--workers", "2"]
    base += ["--set", "robots.count=2", "--set", "feeder.rate=5"]
    for name, extra in (("local", []), ("ray", ["--backend", "ray"])):
        result = CliRunner().invoke(app, [*base, "--out", str(tmp_path / name), *extra])
        assert result.exit_code == 0, result.output

    def untimed(path: Path) -> list[dict[str, str]]:
        timing = ("steps_per_s", "wall_time")
        return [{k: v for k, v in r.items() if k not in timing} for r in _rows(path)]

    for seed in (1, 2):
        run = f"paper_baseline__async__{seed}"
        local, ray = tmp_path / "local" / run, tmp_path / "ray" / run
        assert (local / "model.safetensors").read_bytes() == (
            ray / "model.safetensors"
        ).read_bytes()
        log = untimed(local / "log.csv")
        assert log == untimed(ray / "log.csv")
        assert any(r["loss"] != "nan" for r in log)  # the networks were trained, not only made
        evals = untimed(local / "eval.csv")
        assert [r["step"] for r in evals] == ["60", "120"]
        assert evals == untimed(ray / "eval.csv")
    # Ray's SIGTERM handler, installed in this process by ray.init, is not left behind
    for s, handler in foreign_signal_handlers.items():
        assert signal.getsignal(s) is handler, signal.Signals(s).name
    # different seeds train different networks
    one, two = (tmp_path / "local" / f"paper_baseline__async__{s}" for s in (1, 2))
    assert (one / "model.safetensors").read_bytes() != (two / "model.safetensors").read_bytes()
