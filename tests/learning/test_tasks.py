"""The task suite (``pnp_twin.learning.tasks``, ``pnp-twin task``): every task loads and runs,
seeds are disjoint, a rule's score is the mean of direct runs, the paired difference to the
best rule is zero for it and negative for a worse rule, bad input is one line."""

from __future__ import annotations

import json
import shlex

import numpy as np
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.learning.tasks import SUITE, TASKS, TaskError, eval_seeds, get_task, make_env, score
from pnp_twin.learning.train import TRAIN_SEED_BASE
from pnp_twin.learning.validation import VALIDATION_SEED_BASE
from pnp_twin.policies import make_policy
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.run import simulate

SHORT = ["--seeds", "2", "--duration", "20"]


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_five_to_eight_tasks_with_their_fields() -> None:
    assert 5 <= len(SUITE) <= 8
    assert list(TASKS) == [t.name for t in SUITE]
    for t in SUITE:
        assert t.description and "\n" not in t.description
        assert t.metric == "gripping_rate"
        assert 0 < t.warmup < t.duration
        with pytest.raises(AttributeError):
            t.name = "x"  # type: ignore[misc]


@pytest.mark.parametrize("name", list(TASKS))
def test_every_task_loads_and_runs_a_short_episode(name: str) -> None:
    task = TASKS[name]
    line = task.line()
    assert (line.duration, line.warmup, line.termination) == (
        task.duration, task.warmup, task.termination,
    )  # fmt: skip
    ws = line.robots
    assert ws.first_workspace_start + ws.count * ws.workspace_length <= line.belt.length
    # the command line's form of the line is the same line
    args = shlex.split(task.command())
    assert load_scenario(args[0], parse_sets(args[2::2])) == load_scenario(
        task.scenario, dict(task.overrides)
    )
    result = simulate(task.line(duration=10.0), make_policy("SD", line.robots.count), seed=1000)
    assert 0.0 < result.kpis["gripping_rate"] <= 100.0
    env = make_env(name, "gym", max_episode_time=3.0)
    obs, info = env.reset(options={"line_seed": task.eval_seeds[0]})
    assert info["line_seed"] == task.eval_seeds[0]
    assert env.unwrapped.options.termination == task.termination
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(0)
        done = terminated or truncated
    assert truncated and info["time"] >= 3.0 and "gripping_rate" in info


@pytest.mark.parametrize("kind", ["aec", "parallel"])
def test_pettingzoo_envs_of_a_task(kind: str) -> None:
    env = make_env("slow_robot", kind, max_episode_time=2.0)
    env.reset(seed=0, options={"line_seed": 1000})
    assert len(env.possible_agents) == 4
    if kind == "aec":
        for _agent in env.agent_iter(max_iter=20_000):
            _, _, term, trunc, _ = env.last()
            env.step(None if term or trunc else 0)
    else:
        while env.agents:
            env.step({a: 0 for a in env.agents})


def test_train_and_eval_seeds_are_disjoint() -> None:
    for t in SUITE:
        train, ev = t.train_seeds, t.eval_seeds
        assert len(ev) >= 2 and len(train) > 1_000_000
        assert ev[-1] < train.start or train[-1] < ev.start  # (min/max would walk the range)
        assert train.start >= TRAIN_SEED_BASE  # what the HDQN trainer draws from
        assert not set(ev) & {VALIDATION_SEED_BASE + i for i in range(100)}
        assert not set(ev) & set(range(20))  # the README's evaluation seeds
    assert eval_seeds(TASKS["baseline"], 2) == [1000, 1001]
    assert eval_seeds(TASKS["baseline"]) == list(range(1000, 1020))


def test_score_of_a_rule_is_the_mean_of_direct_runs() -> None:
    code, stdout, stderr = run("task", "score", "high_load", "--policy", "FIFO", *SHORT, "--json")
    assert code == 0, stderr
    data = json.loads(stdout)
    task = TASKS["high_load"]
    line = task.line(duration=20.0)
    direct = [
        simulate(line, make_policy("FIFO", 4), seed=s, engine="simpy").kpis["gripping_rate"]
        for s in (1000, 1001)
    ]
    assert data["seeds"] == [1000, 1001]
    assert data["per_seed"] == direct
    assert data["gripping_rate"] == float(np.mean(direct))
    assert data["ci_low"] <= data["gripping_rate"] <= data["ci_high"]
    assert data["rules"]["FIFO"] == data["gripping_rate"]
    assert (data["duration"], data["warmup"]) == (20.0, 4.0)


def test_the_best_rule_differs_by_zero_and_a_worse_rule_by_less() -> None:
    first = score("bursty", "SD", 2, duration=20.0)
    best = first.best_rule
    means = {r: float(np.mean(v)) for r, v in first.rules.items()}
    assert means[best] == max(means.values())
    again = score("bursty", best, 2, duration=20.0).to_json()
    assert again["best_rule"]["policy"] == best
    assert again["diff"] == again["diff_ci_low"] == again["diff_ci_high"] == 0.0
    worse = min(means, key=lambda r: means[r])
    assert means[worse] < means[best]
    data = score("bursty", worse, 2, duration=20.0).to_json()
    assert data["diff"] < 0.0
    assert data["diff_ci_low"] <= data["diff"] <= data["diff_ci_high"]
    assert data["diff"] == pytest.approx(means[worse] - means[best])


def test_score_prints_the_interval_and_the_paired_difference() -> None:
    code, stdout, stderr = run("task", "score", "baseline", "-p", "SD,SPT,SD,SD", *SHORT)
    assert code == 0, stderr
    assert "baseline: SD,SPT,SD,SD grips" in stdout and "95 % t interval" in stdout
    assert "best rule" in stdout and "paired 95 % interval" in stdout
    assert "not the task's score" in stderr


def test_list_prints_every_task() -> None:
    code, stdout, stderr = run("task", "list")
    assert code == 0, stderr
    for t in SUITE:
        assert t.name in stdout
    code, stdout, _ = run("task", "list", "--json")
    tasks = json.loads(stdout)["tasks"]
    assert [t["name"] for t in tasks] == list(TASKS)
    assert tasks[0]["eval_seeds"] == [1000, 1019]
    code, stdout, _ = run("task")  # bare: its help
    assert code == 0 and "score" in stdout and "list" in stdout


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["task", "score", "nosuch", "-p", "SD"], ["task", "nosuch", "baseline"]),
        (["task", "score", "baseline", "-p", "SD", "--seeds", "1"], ["--seeds", "2 to 20"]),
        (["task", "score", "baseline", "-p", "SD", "--seeds", "21"], ["--seeds", "1000-1019"]),
        (["task", "score", "baseline", "-p", "SD", "--seeds", "x"], ["--seeds"]),
        (["task", "score", "baseline", "-p", "NOPE"], ["policy", "NOPE"]),
        (["task", "score", "baseline"], ["--policy"]),
        (["task", "nosuch"], ["nosuch"]),
    ],
)
def test_bad_input_is_one_line(args: list[str], needles: list[str]) -> None:
    code, stdout, stderr = run(*args)
    assert code == 2 and stdout == ""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    for n in needles:
        assert n in lines[0]


def test_bad_input_in_python() -> None:
    with pytest.raises(TaskError, match="unknown 'nosuch'"):
        get_task("nosuch")
    with pytest.raises(TaskError, match="--seeds"):
        eval_seeds(TASKS["baseline"], 0)
    with pytest.raises(TaskError, match="kind"):
        make_env("baseline", "nosuch")
    assert get_task(" High_Load ") is TASKS["high_load"]
