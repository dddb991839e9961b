"""``pnp-twin headroom``: its JSON and files, the order of its intervals, bad input refused
in one line before anything is written, the folder's lock."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.studies.lock import StudyLock

FAST = ["--seeds", "3", "--duration", "12", "--lookahead", "lookahead:K=2,H=1,base=SD"]


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, list(args))
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("h") / "study"
    code, stdout, stderr = run("headroom", "paper_baseline", *FAST, "--mix", "SD,SPT,SD,SD",
                               "--policy", "FIFO", "--out", str(out), "--json")  # fmt: skip
    assert code == 0, stderr
    return out, json.loads(stdout)


def test_json_keys_and_interval_order(study: tuple[Path, dict]) -> None:
    out, data = study
    for key in ("best_rule", "best_mix", "lookahead", "bound"):
        e = data[key]
        assert {"policy", "gripping_rate", "ci_low", "ci_high"} <= set(e)
        assert e["ci_low"] <= e["gripping_rate"] <= e["ci_high"]
        assert e["gain_ci_low"] <= e["gain"] <= e["gain_ci_high"]
    best = data["best_rule"]
    assert best["gain"] == best["gain_ci_low"] == best["gain_ci_high"] == 0.0
    assert best["policy"] in {r["policy"] for r in data["rules"]}
    assert best["gripping_rate"] == max(r["gripping_rate"] for r in data["rules"])
    assert data["lookahead"]["policy"] == "lookahead:K=2,H=1,base=SD"
    assert data["bound"]["policy"] == "lookahead:H=1,base=SD,oracle=1"
    assert data["lookahead"]["cpu_ms_per_decision"] > 0
    assert data["best_mix"]["policy"] == "SD,SPT,SD,SD"
    assert [p["policy"] for p in data["policies"]] == ["FIFO"]
    assert data["seeds"] == [0, 1, 2]
    # what the gain is worth is counted on the flow the runs measured, not feeder.rate
    assert 9.0 < data["part_flow"] < 11.0 and data["part_flow"] != 10.0
    worth = data["lookahead"]["gain"] / 100 * data["part_flow"] * 3600
    assert f"worth {worth:+,.0f} parts an hour" in data["answer"]
    assert "one-step lookahead with rule continuations" in data["note"]
    assert (
        data["answer"].startswith("On paper_baseline the best rule") and "\n" not in data["answer"]
    )
    assert json.loads((out / "headroom.json").read_text()) == data
    runs = (out / "runs.csv").read_text().splitlines()
    assert runs[0] == "role,policy,seed,gripping_rate"
    assert len(runs) == 1 + 3 * (6 + 1 + 1 + 1 + 1)  # 6 rules, mix, FIFO, lookahead, bound
    page = (out / "report.html").read_text()
    assert "How much could smarter coordination gain" in page
    # the best rule is the reference: no made-up zero-width paired interval for it
    row = page[page.index("<td>best rule</td>") :].split("</tr>")[0]
    assert ">reference</td>" in row and "+0.00" not in row
    assert not list(out.glob(".*.tmp"))  # atomic writes leave nothing behind
    assert not (out / ".study.lock.json").exists()  # the lock is let go


def test_a_paired_gain_is_the_mean_of_the_per_seed_differences(study: tuple[Path, dict]) -> None:
    import pandas as pd

    out, data = study
    runs = pd.read_csv(out / "runs.csv")
    g = runs.pivot_table(index="seed", columns="policy", values="gripping_rate")
    best = data["best_rule"]["policy"]
    for key in ("lookahead", "bound"):
        name = data[key]["policy"]
        assert (g[name] - g[best]).mean() == pytest.approx(data[key]["gain"])


def test_the_table_and_the_answer(tmp_path: Path) -> None:
    code, stdout, stderr = run("headroom", "paper_baseline", *FAST, "--mix", "SD",
                               "--out", str(tmp_path / "s"))  # fmt: skip
    assert code == 0, stderr
    assert "lookahead" in stdout and "best rule" in stdout
    assert "clairvoyant one-step bound" in stdout
    assert "not every possible controller" in stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--lookahead", "lookahead:K=0"], "K is a whole number"),
        (["--lookahead", "SD"], "is not a lookahead controller"),
        (["--policy", "NOPE"], "'NOPE' is not a rule"),
        (["--mix", "SD,SD"], "names 2 rules for 4 robots"),
        (["--seeds", "1"], "--seeds"),
        (["--duration", "0"], "--duration"),
        (["--set", "belt.speed=-1"], "belt.speed"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    tmp_path: Path, args: list[str], message: str
) -> None:
    out = tmp_path / "s"
    code, stdout, stderr = run("headroom", "paper_baseline", "--out", str(out), *args)
    assert code == 2
    assert stderr.startswith("error: ") and stderr.count("\n") == 1 and message in stderr
    assert not out.exists()


def test_a_file_or_a_foreign_folder_is_refused(tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    code, _, stderr = run("headroom", "paper_baseline", "--out", str(f))
    assert code == 2 and stderr.startswith("error: --out") and "give a folder" in stderr
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    code, _, stderr = run("headroom", "paper_baseline", "--out", str(other))
    assert code == 2 and "holds other files" in stderr
    code, _, stderr = run("headroom", "no_such_line", "--out", str(tmp_path / "n"))
    assert code == 2 and stderr.startswith("error: ") and not (tmp_path / "n").exists()


def test_a_held_folder_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "s"
    lock = StudyLock(out)
    lock.acquire("pnp-twin headroom (another)")
    try:
        code, _, stderr = run("headroom", "paper_baseline", *FAST, "--out", str(out))
    finally:
        lock.release()
    assert code == 2 and "in use by" in stderr and stderr.count("\n") == 1
