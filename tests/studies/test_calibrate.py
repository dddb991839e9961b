"""Calibration (``pnp_twin.studies.calibrate``, ``pnp-twin calibrate``): recovery, resume, errors.

The recovery test is the honest one: targets produced by the twin itself at a known geometry
are fitted back from another starting point. With common random numbers the objective is
exactly zero at the true geometry, so only the optimiser's tolerance separates the fit from
it: we ask for the bin distance within 0.02 m and the grip/release time within 0.02 s.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.calibrate import Problem, calibrate
from pnp_twin.studies.calibrate_eval import EVALS, Evaluator
from pnp_twin.studies.calibrate_fields import apply_values, parse_fit, resolve_path
from pnp_twin.studies.calibrate_targets import read_targets
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin.loader import load_scenario

SHORT = {"duration": 120.0, "warmup": 20.0}
TRUE_BIN, TRUE_TIME = 0.4, 0.06
ARMS = (2.0, 3.0, 4.5)


def _truth_csv(tmp_path: Path, reps: int = 2) -> Path:
    """Gripping rate of two_robot at the true geometry, at three arm speeds (SPT)."""
    sc = load_scenario("two_robot", SHORT)
    truth = {
        resolve_path("robots.bin_offset.1"): TRUE_BIN,
        resolve_path("robots.pick_time"): TRUE_TIME,
        resolve_path("robots.place_time"): TRUE_TIME,
    }
    arm = resolve_path("robots.arm_speed")
    ev = Evaluator(tmp_path / "truth", ["SPT"], replication_seeds(sc.seed, reps), [])
    preds = ev.predict([apply_values(sc, {**truth, arm: a}) for a in ARMS], list(map(str, ARMS)))
    path = tmp_path / "targets.csv"
    lines = ["# made by the twin at the true geometry", "robots.arm_speed,gripping_rate"]
    lines += [f"{a},{p.mean['gripping_rate']!r}" for a, p in zip(ARMS, preds, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_fit_recovers_the_geometry_that_made_the_targets(tmp_path: Path) -> None:
    targets = read_targets(_truth_csv(tmp_path))
    sc = load_scenario("two_robot", SHORT)  # starts at bin 0.25 m, grip/release 0.12 s
    params = (
        parse_fit("robots.bin_offset.1=0.1:0.8"),
        parse_fit("robots.pick_time,robots.place_time=0:0.2"),
    )
    problem = Problem(sc, targets, params, ("SPT",), 2, max_evals=30, profile=0, pairs=0)
    cal = calibrate(problem, tmp_path / "fit")
    fitted = cal.fitted
    assert abs(fitted["robots.bin_offset.1"] - TRUE_BIN) < 0.02, fitted
    assert abs(fitted["robots.pick_time"] - TRUE_TIME) < 0.02, fitted
    assert fitted["robots.pick_time"] == fitted["robots.place_time"]  # one shared parameter
    assert np.max(np.abs(cal.best.residuals)) < 1.0
    start = problem.start()
    assert abs(start[0] - TRUE_BIN) > 0.1 and abs(start[1] - TRUE_TIME) > 0.05


def cli(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def _cli_args(targets: Path, out: Path, *extra: str) -> list[str]:
    return [
        "calibrate", "two_robot", "--targets", str(targets), "--out", str(out),
        "--fit", "robots.bin_offset.1=0.1:0.8", "--policy", "SPT", "--replications", "2",
        "--max-evals", "6", "--profile", "3", "--pairs", "0", "--workers", "1",
        "--set", "duration=60", "--set", "warmup=10", *extra,
    ]  # fmt: skip


@pytest.fixture
def small_targets(tmp_path: Path) -> Path:
    path = tmp_path / "t.csv"
    path.write_text("robots.arm_speed,gripping_rate,weight\n2,80,1\n4,95,2\n")
    return path


def test_json_shape_outputs_and_resume_without_simulating(
    tmp_path: Path, small_targets: Path
) -> None:
    out = tmp_path / "cal"
    code, stdout, err = cli(*_cli_args(small_targets, out, "--json"))
    assert code == 0, err
    info = json.loads(stdout)
    assert set(info["fitted"]) == {"robots.bin_offset.1"}
    assert 0.1 <= info["fitted"]["robots.bin_offset.1"] <= 0.8
    assert math.isfinite(info["objective"])
    assert len(info["points"]) == 2
    for p in info["points"]:
        assert {"target", "predicted", "ci_low", "ci_high", "residual"} <= set(p)
        assert p["ci_low"] <= p["predicted"] <= p["ci_high"]
    scenario_file = Path(info["scenario_file"])
    text = scenario_file.read_text()
    assert "# Calibrated by `pnp-twin calibrate`" in text and "robots.bin_offset.1" in text
    data = tomllib.loads(text)
    assert data["robots"]["bin_offset"][1] == pytest.approx(info["fitted"]["robots.bin_offset.1"])
    assert load_scenario(scenario_file).robots.bin_offset[1] == data["robots"]["bin_offset"][1]
    for name in ("points.csv", "profile.csv", "curve.csv", "calibration.json", "report.html"):
        assert (out / name).is_file(), name
    html = (out / "report.html").read_text()
    assert "<script" in html and "<script src=" not in html and "How well each parameter" in html
    simulated = len(list((out / EVALS).glob("*.json")))
    assert info["simulated_points"] == simulated > 0

    code, stdout, err = cli(*_cli_args(small_targets, out, "--json"))  # the rerun: a resume
    assert code == 0, err
    again = json.loads(stdout)
    assert again["simulated_points"] == 0 and again["replayed_points"] > 0
    assert again["fitted"] == info["fitted"] and again["points"] == info["points"]
    assert len(list((out / EVALS).glob("*.json"))) == simulated

    damaged = sorted((out / EVALS).glob("*.json"))[0]
    damaged.write_text('{"runs": ')  # truncated: the point is simulated again, not a traceback
    code, stdout, err = cli(*_cli_args(small_targets, out, "--json"))
    assert code == 0 and "Traceback" not in err, err
    third = json.loads(stdout)
    assert third["simulated_points"] == 1 and third["fitted"] == info["fitted"]
    assert json.loads(damaged.read_text())["runs"]


def test_engines_give_the_same_fit_and_say_which_ran(tmp_path: Path, small_targets: Path) -> None:
    infos = {}
    for engine in ("simpy", "fast"):
        extra = ("--json", "--no-report", "--profile", "0", "--engine", engine)  # last wins
        code, stdout, err = cli(*_cli_args(small_targets, tmp_path / engine, *extra))
        assert code == 0, err
        infos[engine] = json.loads(stdout)
    for engine, info in infos.items():
        assert info["engine"] == engine and info["engines_ran"] == [engine]
    drop = ("engine", "engines_ran", "wall_time", "date", "command", "scenario_file")
    same = [{k: v for k, v in i.items() if k not in drop} for i in infos.values()]
    assert same[0] == same[1] and same[0]["simulated_points"] > 0


@pytest.mark.parametrize(
    ("csv", "fit", "message"),
    [
        ("robots.arm_speed,gripping_rate\n2,50\n", "robots.no_such=0:1", "not a scenario field"),
        ("robots.arm_speed,gripping_rate\n2,50\n", "robots.workspace_length=0:0.4",
         "outside robots.workspace_length's allowed range (> 0"),
        ("robots.arm_speed,gripping_rate\n2,50\n", "robots.pick_time=0.3:0.1", "must be below"),
        ("robots.arm_speed,gripping_rate\n2,50\n", "robots.bin_offset.5=0:1", "out of range"),
        ("robots.arm_speed,speed_of_light\n2,50\n", "robots.pick_time=0:0.2", "no KPI column"),
        ("robots.arm_speed\n2\n", "robots.pick_time=0:0.2", "no KPI column"),
        ("robots.arm_spede,gripping_rate\n2,50\n", "robots.pick_time=0:0.2",
         "'robots.arm_spede': not a scenario field"),
        ("robots.arm_speed,gripping_rate\n2,lots\n", "robots.pick_time=0:0.2",
         "row 1, column gripping_rate: 'lots' is not a number"),
        ("robots.arm_speed,gripping_rate\n0.5,50\n", "robots.pick_time=0:0.2",
         "cannot simulate"),
        ("robots.arm_speed,gripping_rate\n2,50\n", "robots.workspace_length=0.1:3",
         "cannot simulate"),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, csv: str, fit: str, message: str) -> None:
    targets = tmp_path / "t.csv"
    targets.write_text(csv)
    out = tmp_path / "cal"
    code, _, err = cli(
        "calibrate", "two_robot", "--targets", str(targets), "--out", str(out), "--fit", fit,
        "--policy", "SPT", "--replications", "1", "--max-evals", "1",
    )  # fmt: skip
    assert code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert message in err, err
    assert not (out / EVALS).is_dir() or not any((out / EVALS).iterdir())  # nothing simulated


def test_missing_targets_file_and_no_fit_are_one_line(tmp_path: Path) -> None:
    code, _, err = cli(
        "calibrate", "two_robot", "--targets", str(tmp_path / "none.csv"), "--out",
        str(tmp_path / "o"), "--fit", "robots.pick_time=0:0.2",
    )  # fmt: skip
    assert code == 2 and "no file" in err and err.count("\n") == 1
    targets = tmp_path / "t.csv"
    targets.write_text("robots.arm_speed,gripping_rate\n2,50\n")
    code, _, err = cli("calibrate", "two_robot", "--targets", str(targets), "--out", str(tmp_path))
    assert code == 2 and "--fit" in err and err.count("\n") == 1


def test_fields_are_resolved_with_list_elements_and_ranges() -> None:
    ref = resolve_path("robots.bin_offset.1")
    assert ref.keys == ("robots", "bin_offset") and ref.index == 1 and ref.numeric
    assert parse_fit("robots.pick_time=0:0.2").low == 0.0  # grip time may be 0
    for bad in ("robots=0:1", "policy=0:1", "robots.count=1:3", "robots.pick_time=x:1", "a"):
        with pytest.raises(StudyError):
            parse_fit(bad)
    sc = load_scenario("two_robot")
    moved = apply_values(sc, {ref: 0.5})
    assert moved.robots.bin_offset == (sc.robots.bin_offset[0], 0.5)


def test_shipped_paper_targets_load() -> None:
    from importlib import resources

    path = Path(str(resources.files("pnp_twin.scenarios") / "calibration" / "paper_arm_speed.csv"))
    t = read_targets(path)
    assert [r.path for r in t.varied] == ["robots.arm_speed"]
    assert t.kpis == ("gripping_rate",)
    assert [v[0] for v in t.values] == [2.0, 3.0, 4.0]
    assert t.target[:, 0].tolist() == [47.0, 72.0, 82.0]


def test_near_optimal_span_is_interpolated_around_the_minimum() -> None:
    from pnp_twin.studies.calibrate import near_optimal

    line = [(0.0, 9.0), (1.0, 1.0), (2.0, 0.0), (3.0, 4.0)]
    lo, hi = near_optimal(line, best=0.0, margin=2.0)
    assert lo == pytest.approx(1.0 - 1.0 / 8.0)  # 1 -> 9 crosses 2 an eighth of the way
    assert hi == pytest.approx(2.5)
    assert near_optimal([(0.0, 0.0), (1.0, 0.5)], best=0.0) == (0.0, 1.0)  # flat: whole span


def test_a_held_folder_is_refused_and_a_failed_fresh_keeps_the_journal(
    tmp_path: Path, small_targets: Path
) -> None:
    from pnp_twin.studies.lock import StudyLock

    out = tmp_path / "cal"
    code, _, err = cli(*_cli_args(small_targets, out, "--json"))
    assert code == 0, err
    journal = sorted(p.name for p in (out / EVALS).glob("*.json"))
    lock = StudyLock(out)
    lock.acquire("another calibration")
    try:  # a second calibration into the held folder: one line, nothing touched
        code, _, err = cli(*_cli_args(small_targets, out, "--json", "--fresh"))
    finally:
        lock.release()
    assert code == 2 and "in use by" in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in (out / EVALS).glob("*.json")) == journal


def test_a_fresh_fit_that_fails_puts_the_old_journal_back(
    tmp_path: Path, small_targets: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "cal"
    code, _, err = cli(*_cli_args(small_targets, out, "--json"))
    assert code == 0, err
    journal = {p.name: p.read_bytes() for p in (out / EVALS).glob("*.json")}

    def failing(*args: object, **kwargs: object) -> None:
        assert not (out / EVALS).exists()  # --fresh: the old journal is out of the way
        raise StudyError("calibrate: the fit failed")

    monkeypatch.setattr("pnp_twin.cli.calibrate_cmd.calibrate", failing)
    code, _, err = cli(*_cli_args(small_targets, out, "--json", "--fresh"))
    assert code == 2 and "the fit failed" in err
    assert {p.name: p.read_bytes() for p in (out / EVALS).glob("*.json")} == journal
