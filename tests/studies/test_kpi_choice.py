"""``--kpi`` of ``size``, ``design``, ``capacity`` and ``headroom``: the figure the target is
on. A bad choice is one line and exit code 2 before anything is written; a good one is the
figure each study really judges (checked against the per-kind figures of plain runs of the
same lines and seeds on waste_sorting, whose residual waste no robot picks)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.policies import make_policy
from pnp_twin.studies.headroom import HeadroomSettings, _rates
from pnp_twin.studies.kpi_choice import GRIPPING, KpiChoice, parse_kpi
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.studies.sizing import COUNT, MTBF, sizing_setup
from pnp_twin.twin.loader import load_scenario, with_overrides
from pnp_twin.twin.run import simulate
from pnp_twin.twin.scenario import Scenario

# waste_sorting at 30 parts/s for 20 s: cans are nearly all gripped, PET much less
SETS = {"duration": 20.0, "warmup": 4.0, "feeder.rate": 30.0}
SET_ARGS = [a for k, v in SETS.items() for a in ("--set", f"{k}={v:g}")]
COUNTS = "sweep.grid={'robots.count': [6, 7, 8]}"  # robots 5 and 6 have overrides: >= 6


def cli(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


def waste(**more: Any) -> Scenario:
    return load_scenario("waste_sorting", {**SETS, **more})


def figure(sc: Scenario, kpi: KpiChoice, seed: int, policy: str = "VAL") -> float:
    """The ``kpi`` figure of one plain run, read from the nested KPI dictionary by hand."""
    k = simulate(sc, make_policy(policy, sc.robots.count), seed=seed).kpis
    if kpi.kind is not None:
        return float(k["kinds"][kpi.kind]["gripping_rate"])
    return float(k.get(kpi.name, k["gripping_rate"]))


# --- parsing ----------------------------------------------------------------------------------


def test_choices_and_their_columns() -> None:
    sc, one = waste(), load_scenario("paper_baseline")
    assert parse_kpi(None, sc) is GRIPPING and parse_kpi("gripping_rate", sc).default
    assert parse_kpi("value_rate", sc) == KpiChoice("value_rate", None, "value_rate")
    pet = parse_kpi(" gripping_rate:PET ", sc)
    assert (pet.kind, pet.column, pet.short) == (
        "PET",
        "kind_PET_gripping_rate",
        "PET gripping rate",
    )
    # one kind: every part has the same value, so the value rate is G (its column)
    value = parse_kpi("value_rate", one)
    assert value.column == "gripping_rate" and not value.default and value.short == "value rate"
    assert parse_kpi("gripping_rate", one).short == "G"


def test_the_figure_is_read_from_a_runs_kpis() -> None:
    sc = waste()
    k = simulate(sc, make_policy("VAL", sc.robots.count), seed=3).kpis
    assert parse_kpi("value_rate", sc).of(k) == k["value_rate"] != k["gripping_rate"]
    assert parse_kpi("gripping_rate:can", sc).of(k) == k["kinds"]["can"]["gripping_rate"]
    assert GRIPPING.of(k) == k["gripping_rate"]
    flow, unit = parse_kpi("gripping_rate:PET", sc).flow(k)
    window = k["parts_presented"] / k["part_flow"]
    assert unit == "PET parts" and flow == pytest.approx(
        k["kinds"]["PET"]["parts_presented"] / window
    )


BAD = [
    ("waste_sorting", "throughput", "--kpi: 'throughput' is not allowed; allowed gripping_rate, "
     "value_rate, gripping_rate:PET, gripping_rate:can"),
    ("waste_sorting", "value_rate:PET", "is not allowed; allowed gripping_rate, value_rate,"),
    ("waste_sorting", "gripping_rate:glass", "'glass' is not a kind of waste_sorting; its kinds "
     "(feeder.kinds) are PET, can, residual"),
    ("waste_sorting", "gripping_rate:residual", "no robot picks residual; it passes on by design; "
     "it has no gripping rate"),
    ("paper_baseline", "gripping_rate:PET", "paper_baseline has one kind of part (no "
     "feeder.kinds); give gripping_rate or value_rate"),
    ("paper_baseline", "G", "--kpi: 'G' is not allowed; allowed gripping_rate, value_rate"),
]  # fmt: skip


@pytest.mark.parametrize(("line", "choice", "message"), BAD)
def test_parse_refuses_in_one_line(line: str, choice: str, message: str) -> None:
    with pytest.raises(StudyError, match="^--kpi") as e:
        parse_kpi(choice, load_scenario(line))
    assert message in str(e.value) and "\n" not in str(e.value)


COMMANDS = {
    "size": ["--target", "90"],
    "design": ["--target", "90", "--vary", "robots.count=6:7"],
    "capacity": ["--target", "90"],
    "headroom": [],
}


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize(("line", "choice", "message"), [BAD[0], *BAD[2:5]])
def test_a_bad_choice_exits_2_with_one_line_and_writes_nothing(
    tmp_path: Path, command: str, line: str, choice: str, message: str
) -> None:
    out = tmp_path / "out"
    args = COMMANDS[command]
    if line == "paper_baseline" and command == "design":
        args = ["--target", "90", "--vary", "robots.count=3:4"]
    code, _, stderr = cli(command, line, *args, "--out", str(out), "--kpi", choice)
    assert code == 2, stderr
    assert stderr.startswith("error: --kpi") and stderr.count("\n") == 1, stderr
    assert message in " ".join(stderr.split())
    assert not out.exists()


# --- size ----------------------------------------------------------------------------------


def _fixed_sequence(rows: pd.DataFrame) -> int | None:
    """The smallest count of the unbroken run of reached counts from the largest down."""
    answer = None
    for _, r in rows.sort_values(COUNT, ascending=False).iterrows():
        if not r["reached"]:
            break
        answer = int(r[COUNT])
    return answer


@pytest.fixture(scope="module")
def sized(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One sizing folder asked with each figure in turn (every run simulated once)."""
    out = tmp_path_factory.mktemp("size") / "s"
    base = ["size", "waste_sorting", "--target", "90", *SET_ARGS, "--set", COUNTS, "-r", "3"]
    base += ["--out", str(out), "--workers", "1", "--no-report"]
    found: dict[str, Any] = {}
    for kpi in ("gripping_rate", "gripping_rate:PET", "gripping_rate:can", "value_rate"):
        code, stdout, stderr = cli(*base, "--kpi", kpi)
        assert code == 0, stderr
        meta = json.loads((out / "meta.json").read_text())
        sizing = json.loads((out / "sizing.json").read_text())
        found[kpi] = {"stdout": stdout, "sizing": sizing, "meta": meta}
    found["results"] = pd.read_csv(out / "results.csv")
    return found


def test_size_judges_the_chosen_figure(sized: dict[str, Any]) -> None:
    results = sized["results"]
    answers = {}
    for kpi in ("gripping_rate", "gripping_rate:PET", "gripping_rate:can", "value_rate"):
        s = sized[kpi]["sizing"]
        column = parse_kpi(kpi, waste()).column
        rows = pd.DataFrame(s["rows"])
        for _, r in rows.iterrows():  # each row's mean is the chosen column's, per run
            mine = results[(results["point"] == r["point"]) & (results["policy"] == r["policy"])]
            assert r["gripping_rate_mean"] == pytest.approx(mine[column].mean())
        plain = rows[rows[MTBF] == 0]
        assert s["answer"] == _fixed_sequence(plain)
        answers[kpi] = s["answer"]
        if kpi == "gripping_rate":
            assert "kpi" not in s and "gripping rate" in s["text"]
        else:
            assert s["kpi"]["name"] == kpi and f"90 % {s['kpi']['label']}" in s["text"]
    # cans are all but all gripped; PET needs more robots than the parts on average
    assert answers["gripping_rate:can"] < answers["gripping_rate"] <= answers["gripping_rate:PET"]
    assert "PET gripping rate %" in " ".join(sized["gripping_rate:PET"]["stdout"].split())


def test_size_rows_are_the_per_kind_figures_of_plain_runs(sized: dict[str, Any]) -> None:
    results = sized["results"]
    sc = waste(**{"sweep.grid": {"robots.count": [6, 7, 8]}})
    line, _ = sizing_setup(sc, sc.sweep.grid if sc.sweep else {})
    for _, run in results[(results[MTBF] == 0)].head(3).iterrows():
        at = with_overrides(line, {COUNT: int(run[COUNT]), MTBF: 0.0})
        for kind in ("PET", "can"):
            kpi = parse_kpi(f"gripping_rate:{kind}", sc)
            assert figure(at, kpi, int(run["seed"])) == run[kpi.column]


def test_size_asked_with_another_kpi_reuses_every_run(sized: dict[str, Any]) -> None:
    assert sized["gripping_rate"]["meta"]["runs_executed"] == 18
    for kpi in ("gripping_rate:PET", "gripping_rate:can", "value_rate"):
        meta = sized[kpi]["meta"]
        assert meta["runs_executed"] == 0 and meta["runs_skipped"] == 18
        assert meta["kpi"] == kpi


# --- design ----------------------------------------------------------------------------------


def test_design_meets_the_target_on_the_chosen_figure(tmp_path: Path) -> None:
    args = ["design", "waste_sorting", "--target", "90", *SET_ARGS, "--set", "belt.length=4"]
    args += ["--vary", "robots.count=6:9", "-r", "3", "--max-replications", "6"]
    args += ["--workers", "1", "--no-report", "--json"]
    got = {}
    for kpi in ("gripping_rate:can", "gripping_rate:PET"):
        code, stdout, stderr = cli(*args, "--out", str(tmp_path / kpi), "--kpi", kpi)
        assert code == 0, stderr
        got[kpi] = json.loads(stdout)
    can, pet = got["gripping_rate:can"], got["gripping_rate:PET"]
    assert can["kpi"]["name"] == "gripping_rate:can" and "can gripping rate = " in can["text"]
    assert can["choice"]["robots.count"] < pet["choice"]["robots.count"]
    # the answer's mean is the kind's gripping rate over its replications' seeds
    sc = waste(**{"belt.length": 4.0})
    seeds = replication_seeds(sc.seed, 6)
    stored = json.loads((tmp_path / "gripping_rate:PET" / "design.json").read_text())
    row = next(r for r in stored["rows"] if r["choice"] == pet["choice"])
    at = with_overrides(sc, {COUNT: pet["choice"][COUNT]})
    kpi = parse_kpi("gripping_rate:PET", sc)
    runs = [figure(at, kpi, s) for s in seeds[: row["replications"]]]
    assert pet["gripping_rate"] == pytest.approx(float(np.mean(runs)))
    assert (
        pet["ci_low"]
        >= 90
        > min(r["ci_low"] for r in stored["rows"] if r["choice"][COUNT] < pet["choice"][COUNT])
    )


# --- capacity --------------------------------------------------------------------------------


def test_capacity_searches_the_flow_on_the_chosen_figure(tmp_path: Path) -> None:
    args = ["capacity", "waste_sorting", "--target", "90", "--set", "duration=20"]
    args += ["--set", "warmup=4", "-r", "3", "--workers", "1", "--no-report", "--json"]
    got = {}
    for kpi in ("gripping_rate:can", "gripping_rate:PET", "value_rate"):
        code, stdout, stderr = cli(*args, "--out", str(tmp_path / kpi), "--kpi", kpi)
        assert code == 0, stderr
        got[kpi] = json.loads(stdout)
    assert got["gripping_rate:can"]["ci_low"] > got["value_rate"]["ci_low"]
    assert got["value_rate"]["ci_low"] > got["gripping_rate:PET"]["ci_low"]
    assert "at value rate ≥ 90 %" in got["value_rate"]["text"]
    stored = json.loads((tmp_path / "gripping_rate:PET" / "capacity.json").read_text())
    assert stored["kpi"]["column"] == "kind_PET_gripping_rate"
    sc = load_scenario("waste_sorting", {"duration": 20.0, "warmup": 4.0})
    kpi = parse_kpi("gripping_rate:PET", sc)
    point = next(p for p in stored["curve"] if p["rate"] == stored["ci_low"])
    at = with_overrides(sc, {"feeder.rate": point["rate"]})
    runs = [figure(at, kpi, s) for s in stored["seeds"]]
    assert point["mean"] == pytest.approx(float(np.mean(runs)))
    assert point["low"] >= 90


# --- headroom ----------------------------------------------------------------------------


def test_headroom_measures_the_chosen_figure() -> None:
    sc = waste(duration=12.0)
    seeds = [0, 1]
    for name in ("gripping_rate:PET", "value_rate"):
        kpi = parse_kpi(name, sc)
        settings = HeadroomSettings(seeds=2, kpi=kpi, engine="fast")
        flows: list[tuple[float, str]] = []
        values, _, _ = _rates(sc, "VAL", seeds, settings, figure=flows)
        assert values == [figure(sc, kpi, s) for s in seeds]
        assert flows[0][1] == ("PET parts" if kpi.kind else "in value")


def test_headroom_value_rate_on_a_line_of_one_kind_is_g_and_says_so(tmp_path: Path) -> None:
    fast = ["--seeds", "2", "--duration", "10", "--mix", "SD", "--lookahead", "lookahead:K=2,H=0.5"]
    got = {}
    for kpi in ("gripping_rate", "value_rate"):
        code, stdout, stderr = cli(
            "headroom", "paper_baseline", *fast, "--out", str(tmp_path / kpi), "--kpi", kpi,
            "--json",
        )  # fmt: skip
        assert code == 0, stderr
        got[kpi] = json.loads(stdout)
    g, v = got["gripping_rate"], got["value_rate"]
    for key in ("best_rule", "best_mix", "lookahead", "bound"):
        for field in ("gripping_rate", "ci_low", "ci_high", "gain"):
            a, b = g[key][field], v[key][field]
            assert a == b or (math.isnan(a) and math.isnan(b))
    assert "kpi" not in g and v["kpi"]["name"] == "value_rate"
    assert "reaches a value rate of" in v["answer"] and "grips" in g["answer"]
    runs = pd.read_csv(tmp_path / "value_rate" / "runs.csv")
    assert set(runs["kpi"]) == {"value_rate"}


def test_headroom_on_a_line_of_valued_kinds_compares_val_and_the_lookahead(tmp_path: Path) -> None:
    """On waste_sorting (kinds of different value) the rules compared include VAL, and the
    lookahead plans over futures whose parts carry kinds; each row is the value rate."""
    fast = ["--seeds", "2", "--duration", "12", "--mix", "SPT"]
    fast += ["--lookahead", "lookahead:K=2,H=0.5"]
    code, stdout, stderr = cli(
        "headroom", "waste_sorting", *fast, "--out", str(tmp_path / "h"), "--kpi", "value_rate",
        "--json",
    )  # fmt: skip
    assert code == 0, stderr
    got = json.loads(stdout)
    assert "VAL" in {r["policy"] for r in got["rules"]}
    rate = {r["policy"]: r["gripping_rate"] for r in got["rules"]}  # the value rate, here
    assert rate["VAL"] > rate["FIFO"]  # FIFO lets cans pass to the PET-only robots
    assert got["best_rule"]["policy"] == "VAL"
    assert 0.0 < got["lookahead"]["gripping_rate"] <= 100.0


def test_a_sweep_of_a_line_with_kinds_summarises_the_value_rate_and_each_kind(
    tmp_path: Path,
) -> None:
    from pnp_twin.studies.summary import summarise
    from pnp_twin.twin.kpis import flat_kpis

    rows = []
    for seed in (0, 1, 2):
        k = simulate(waste(duration=12.0), make_policy("VAL", 6), seed=seed).kpis
        rows.append({"point": 0, "policy": "VAL", **flat_kpis(k)})
    summary = summarise(pd.DataFrame(rows), [])
    values = [r["value_rate"] for r in rows]
    assert summary["value_rate_mean"].iloc[0] == pytest.approx(np.mean(values))
    assert summary["value_rate_ci_low"].iloc[0] <= np.mean(values) <= 100.0
    assert "kind_can_gripping_rate_mean" in summary and "kind_PET_gripping_rate_mean" in summary
    assert "kind_residual_gripping_rate_mean" not in summary  # no robot picks it
    one = summarise(
        pd.DataFrame([{**rows[0], "value_rate": None}]).drop(
            columns=[c for c in rows[0] if c.startswith("kind_") or c == "value_rate"]
        ),
        [],
    )
    assert not any(c.startswith(("value_rate", "kind_")) for c in one.columns)
