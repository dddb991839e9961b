"""The training report: figures from small hand-made run tables, the page for one run and
for a folder of runs, missing tables left out with a note, ``evaluate --out`` writing the
tables the report reads, and the page in a real headless browser."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from pnp_twin.reports import ReportError, build_report, render_report
from pnp_twin.reports.training import evaluation_table, mode_rows
from pnp_twin.reports.training_figures import (
    episode_rates,
    learning_figure,
    modes_figure,
    rule_shares,
    rules_figure,
)
from pnp_twin.reports.training_load import is_training_folder, load_run, load_runs, run_folders
from tests.study_fixture import make_study

RULES = ["FIFO", "SD", "SPT"]


def write_run(folder: Path, mode: str, offset: float = 0.0, tables: bool = True) -> Path:
    """A run folder as ``pnp-twin train`` and ``evaluate --out`` write it, in small."""
    folder.mkdir(parents=True)
    term = "t_all" if mode == "sync" else "t_continue"
    meta = {
        "mode": mode,
        "termination": term,
        "rules": RULES,
        "n_robots": 2,
        "n_actions": 3,
        "obs_shape": [1, 8, 14],
        "device": "cpu",
        "agent": {"network": "compact", "gamma": 0.9, "lr": 0.00025},
        "counters": {"step": 3000, "episode": 3, "wall_time": 12.5, "best_eval": 71.0},
        "train_args": {"seed": 1, "steps": 4000, "eval_every": 2000, "eval_seeds": 2},
        "scenario": {"name": "tiny", "description": "A tiny line.", "robots": {"count": 2}},
        "versions": {"pnp_twin": "0.1.0"},
    }
    (folder / "meta.json").write_text(json.dumps(meta))
    pd.DataFrame(
        {
            "step": [1000, 2000, 3000, 4000],
            "episode": [0, 1, 1, 3],
            "reward_per_step": [0.5, 0.7, 0.9, 1.0],
            "gripping_rate": [60.0, 65.0, 65.0, 70.0],
        }
    ).to_csv(folder / "log.csv", index=False)
    pd.DataFrame(
        {
            "step": [2000, 4000],
            "wall_time": [6.0, 15.0],
            "gripping_rate": [68.0, 71.0],
            "best_rule": ["SPT", "SPT"],
            "best_rule_gripping_rate": [70.5, 70.5],
        }
    ).to_csv(folder / "eval.csv", index=False)
    if not tables:
        return folder
    g = {"HDQN (x)": [71.0, 73.0, 72.0], "FIFO": [60.0, 62.0, 61.0], "SPT": [70.0, 72.0, 71.5]}
    g = {(f"HDQN ({mode})" if k.startswith("HDQN") else k): v for k, v in g.items()}
    rows = [
        {
            "scenario": "tiny",
            "mode": mode,
            "termination": term,
            "duration": 60.0,
            "policy": p,
            "kind": "hdqn" if p.startswith("HDQN") else "rule",
            "seed": s,
            "gripping_rate": v + offset,
        }
        for p, values in g.items()
        for s, v in enumerate(values)
    ]
    pd.DataFrame(rows).to_csv(folder / "evaluation.csv", index=False)
    pd.DataFrame(
        {
            "robot": [1, 1, 1, 2, 2],
            "rule": ["NooP", "SPT", "SD", "NooP", "SPT"],
            "count": [50, 30, 10, 80, 40],
        }
    ).to_csv(folder / "rules.csv", index=False)
    return folder


@pytest.fixture()
def runs_dir(tmp_path: Path) -> Path:
    write_run(tmp_path / "runs" / "tiny__async__1", "async")
    write_run(tmp_path / "runs" / "tiny__sync__1", "sync", offset=-5.0)
    (tmp_path / "runs" / "notes").mkdir()  # a stray folder is not a run
    return tmp_path / "runs"


def test_learning_figure_draws_the_logged_and_validation_curves(runs_dir: Path) -> None:
    run = load_run(runs_dir / "tiny__async__1")
    fig = learning_figure(run)
    by_name = {t.name: t for t in fig.data}
    assert list(by_name["Reward per step (logged)"].y) == [0.5, 0.7, 0.9, 1.0]
    # one point per finished-episode count; the episode-0 row holds a running value
    assert list(by_name["Training episode"].x) == [2000, 4000]
    assert list(by_name["Validation (HDQN, greedy)"].y) == [68.0, 71.0]
    assert list(by_name["Best checkpoint"].x) == [4000]
    ref = by_name["SPT, best rule (validation)"]
    assert list(ref.y) == [70.5, 70.5] and list(ref.x) == [1000, 4000]


def test_episode_rates_keep_the_first_row_of_each_episode_count() -> None:
    log = pd.DataFrame(
        {"step": [1, 2, 3, 4], "episode": [0, 2, 2, 5], "gripping_rate": [1, 2, 3, 4]}
    )
    assert episode_rates(log)["gripping_rate"].tolist() == [2, 4]


def test_rule_shares_leave_noop_out_and_sum_to_100_per_robot(runs_dir: Path) -> None:
    run = load_run(runs_dir / "tiny__async__1")
    shares = rule_shares(run.rules)
    assert "NooP" not in set(shares["rule"])
    assert shares.groupby("robot")["share"].sum().tolist() == pytest.approx([100.0, 100.0])
    assert shares.set_index(["robot", "rule"]).loc[(1, "SPT"), "share"] == pytest.approx(75.0)
    fig = rules_figure(load_runs(runs_dir))
    assert {t.name for t in fig.data} == {"SD", "SPT"}
    assert sum(t.showlegend for t in fig.data) == 2  # one legend entry per rule


def test_evaluation_table_pairs_by_seed(runs_dir: Path) -> None:
    t = evaluation_table(load_run(runs_dir / "tiny__async__1").evaluation).set_index("policy")
    assert t.loc["HDQN (async)", "mean"] == pytest.approx(72.0)
    assert t.loc["SPT", "diff"] == pytest.approx((1.0 + 1.0 + 0.5) / 3)
    assert t.loc["FIFO", "diff"] == pytest.approx(11.0)  # 11 on every seed: a zero-width CI
    assert t.loc["FIFO", "diff_low"] == pytest.approx(11.0)


def test_mode_comparison_takes_each_runs_best_rule(runs_dir: Path) -> None:
    rows = mode_rows(load_runs(runs_dir)).set_index("mode")
    assert list(rows.index) == ["sync", "async"]  # the paper's order: single, sync, async
    assert rows.loc["async", "rule"] == "SPT"
    assert rows.loc["sync", "hdqn"] == pytest.approx(67.0)
    assert rows.loc["sync", "termination"] == "t_all"
    fig = modes_figure(rows.reset_index())
    assert [t.name for t in fig.data] == ["HDQN", "Best rule, same termination"]
    assert list(fig.data[1].y) == pytest.approx([213.5 / 3 - 5, 213.5 / 3])


def test_report_of_a_folder_of_runs_has_every_section(runs_dir: Path) -> None:
    assert is_training_folder(runs_dir)
    assert [p.name for p in run_folders(runs_dir)] == ["tiny__sync__1", "tiny__async__1"]
    path = build_report(runs_dir)
    html = path.read_text(encoding="utf-8")
    # 2 learning curves + rules + modes
    assert '<meta name="pnp-twin-figures" content="4">' in html
    for anchor in ("curves", "rules", "modes", "evaluation", "setup", "findings"):
        assert f'<section id="{anchor}">' in html
    assert "tiny: HDQN training, 2 runs" in html
    assert html.count('<tr class="best">') == 2  # each run's HDQN row in its table


def test_report_of_one_run_without_evaluation_leaves_sections_out(tmp_path: Path) -> None:
    run = write_run(tmp_path / "tiny__single__1", "single", tables=False)
    html = render_report(run)
    assert '<meta name="pnp-twin-figures" content="1">' in html
    assert '<section id="curves">' in html
    assert '<section id="rules">' not in html and '<section id="modes">' not in html
    assert "No evaluation.csv" in html and "No rules.csv" in html


def test_a_broken_table_is_a_note_not_a_crash(tmp_path: Path) -> None:
    run = write_run(tmp_path / "r", "async")
    pd.DataFrame({"robot": [1], "what": ["x"]}).to_csv(run / "rules.csv", index=False)
    html = render_report(run)
    assert "rules.csv lacks column(s) count, rule" in html
    assert '<section id="rules">' not in html


def test_a_folder_without_runs_or_study_is_a_one_line_error(tmp_path: Path) -> None:
    assert not is_training_folder(tmp_path)
    with pytest.raises(ReportError) as e:
        load_runs(tmp_path)
    assert "\n" not in str(e.value)


def test_a_study_folder_still_gets_the_study_report(tmp_path: Path) -> None:
    study = make_study(tmp_path / "s", grid={"robots.arm_speed": [2, 3]}, records=False)
    assert not is_training_folder(study)
    assert "pnp-twin report<span class='badge'>sweep</span>" in render_report(study)


def test_evaluate_out_writes_the_tables_the_report_reads(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    from typer.testing import CliRunner

    import pnp_twin.cli.learn_cmd  # noqa: F401
    from pnp_twin.cli.app import app

    model = Path(__file__).resolve().parents[2] / "models" / "paper_baseline__async"
    run = tmp_path / "run"
    shutil.copytree(model, run)
    args = ["evaluate", "paper_baseline", "--policy", f"hdqn:{run}", "--seeds", "2"]
    args += ["--duration", "10", "--mix", "SPT", "--out", str(run)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    ev = pd.read_csv(run / "evaluation.csv")
    assert sorted(ev["seed"].unique()) == [0, 1]
    assert set(ev["kind"]) == {"hdqn", "rule"}
    assert (ev["termination"] == "t_continue").all() and (ev["duration"] == 10).all()
    assert len(ev) == 2 * (1 + 6)  # the HDQN and six rules (the mix SPT is the rule SPT)
    rules = pd.read_csv(run / "rules.csv")
    assert set(rules["robot"]) == {1, 2, 3, 4}
    assert set(rules["rule"]) <= {"NooP", "FIFO", "LIFO", "SIRO", "SD", "LD", "SPT"}
    assert rules["count"].sum() > 0
    assert not list(run.glob(".*.tmp"))  # written atomically, nothing left behind
    html = render_report(run)
    assert '<section id="rules">' in html and '<section id="modes">' in html


def test_evaluate_out_on_a_file_is_a_one_line_error(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    from typer.testing import CliRunner

    import pnp_twin.cli.learn_cmd  # noqa: F401
    from pnp_twin.cli.app import app

    target = tmp_path / "file.txt"
    target.write_text("x")
    args = ["evaluate", "paper_baseline", "--policy", "hdqn:models/paper_baseline__async"]
    result = CliRunner().invoke(app, [*args, "--out", str(target)])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and "is a file" in result.output


def test_training_report_renders_offline(runs_dir: Path, tmp_path: Path) -> None:
    from tests.reports.test_report_browser import SCREENSHOT, open_report  # skips without Chromium

    shot = tmp_path / "training.png"
    seen = open_report(build_report(runs_dir), shot)
    assert seen["errors"] == [] and seen["blocked"] == []
    assert seen["declared"] == seen["divs"] == seen["rendered"] == 4
    assert shot.stat().st_size > 50_000
    shutil.copyfile(shot, SCREENSHOT.with_name("report_screenshot_training.png"))


def test_a_rollout_run_is_told_apart_from_the_td_async_run(tmp_path):
    from pnp_twin.reports.training_load import TrainingRun

    rollout = TrainingRun(
        tmp_path, {"mode": "async", "targets": "rollout", "train_args": {"seed": 1}}
    )
    assert rollout.mode == "async (rollout)" and rollout.label == "async (rollout) · seed 1"
    assert TrainingRun(tmp_path, {"mode": "async", "train_args": {"seed": 1}}).mode == "async"
