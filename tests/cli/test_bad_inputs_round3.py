"""Bad inputs, round three: the classes issue 31 found reopened by the newer commands.

Each refusal case runs one command in an empty folder under the contract of
``test_bad_inputs``: exit 2, nothing on stdout, one ``error:`` line naming what was wrong,
an answer within seconds, and nothing written, changed or created. The answers that are not
refusals (a trace folder replayed trace k in replication k, a rebuilt report, a bound that
does not claim to bound) are checked by what they print and write.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.policies.user_guard import PolicyAnswerError, checked_answer
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.stats import percent_interval
from tests.cli.test_bad_inputs_round2 import Case, fifo, link, run_case

YEAR = "31536000"
LINE = (
    'name = "r3"\nduration = 30.0\nwarmup = 2.0\n[belt]\nlength = 1.6\n[feeder]\nrate = 4.0\n'
    "[robots]\ncount = 2\nworkspace_length = 0.5\nbin_offset = [0.0, 0.25]\n"
)
SHIFTS = 'name = "r3"\nduration = 15.0\nwarmup = 1.0\n[feeder]\narrival = "trace"\n'
SHIFTS += 'trace = "shifts"\n[belt]\nlength = 1.6\n[robots]\ncount = 2\nworkspace_length = 0.5\n'


def shifts(n: int = 3) -> dict[str, str | bytes]:
    """A scenario replaying a folder of ``n`` traces of different flows."""
    files: dict[str, str | bytes] = {"s.toml": SHIFTS}
    for k in range(n):
        gap = 0.15 + 0.1 * k
        rows = [
            f"{i * gap:.3f},{0.05 + 0.3 * ((i * 7) % 10) / 10:.3f}" for i in range(int(19 / gap))
        ]
        files[f"shifts/{k}.csv"] = "time,y\n" + "\n".join(rows) + "\n"
    return files


HEADROOM = ["--seeds", "2", "--duration", "10", "--lookahead", "lookahead:K=2,H=0.5", "--mix", "SD"]

CASES: dict[str, Case] = {
    # --- data loss: outputs into another command's folder or into an input folder ----------
    "headroom into a design folder": Case(
        ["headroom", "l.toml", "--out", "d", *HEADROOM],
        ["--out d", "pnp-twin design", "choose another folder"],
        {
            "l.toml": LINE,
            "d/.pnp-twin.json": '{"kind": "design", "format": 1}',
            "d/report.html": "x",
        },
    ),
    "design into a finished headroom folder of an earlier version": Case(
        ["design", "l.toml", "--out", "h", "--target", "80", "--vary", "robots.arm_speed=2,3"],
        ["--out h", "pnp-twin headroom"],
        {"l.toml": LINE, "h/headroom.json": "{}", "h/report.html": "x"},
    ),
    "design of a trace folder into a headroom folder (one line, no note first)": Case(
        ["design", "s.toml", "--out", "h", "--target", "80", "--vary", "robots.arm_speed=2,3"],
        ["--out h", "pnp-twin headroom"],
        {**shifts(), "h/headroom.json": "{}"},
    ),
    "sweep into a tune folder": Case(
        ["sweep", "l.toml", "--out", "t"],
        ["--out t", "pnp-twin tune"],
        {"l.toml": LINE, "t/tune.json": "{}", "t/report.html": "x"},
    ),
    "--events inside the trace folder": Case(
        ["run", "s.toml", "--events", "shifts/parts.csv"],
        ["--events", "inside the trace folder"],
        shifts(),
    ),
    "--out inside the trace folder": Case(
        ["headroom", "s.toml", "--out", "shifts/h", *HEADROOM],
        ["--out", "inside the trace folder"],
        shifts(),
    ),
    # --- silent nonsense: one trace counted twice, more replications than traces -----------
    "a trace listed twice": Case(
        ["run", "s.toml"],
        ["feeder.trace", "named twice"],
        {**shifts(1), "s.toml": SHIFTS.replace('"shifts"', '["shifts/0.csv", "shifts/0.csv"]')},
    ),
    "a trace listed twice through a link": Case(
        ["run", "s.toml"],
        ["feeder.trace", "named twice"],
        {**shifts(1), "s.toml": SHIFTS.replace('"shifts"', '["shifts/0.csv", "again.csv"]')},
        (link("again.csv", "shifts/0.csv"),),
    ),
    "headroom seeds beyond the traces": Case(
        ["headroom", "s.toml", "--out", "h", "--seeds", "4"],
        ["--seeds", "3 traces", "at most 3"],
        shifts(),
    ),
    "calibration weights all 0": Case(
        [
            "calibrate",
            "l.toml",
            "--targets",
            "t.csv",
            "--out",
            "c",
            "--fit",
            "robots.pick_time=0:0.3",
        ],
        ["--targets t.csv", "weight", "every row's weight is 0"],
        {"l.toml": LINE, "t.csv": "robots.arm_speed,gripping_rate,weight\n2,60,0\n3,80,0\n"},
    ),
    "headroom --mix lookahead": Case(
        ["headroom", "l.toml", "--out", "h", "--mix", "lookahead"],
        ["--mix", "not a static rule mix"],
        {"l.toml": LINE},
    ),
    # --- tracebacks and hangs -----------------------------------------------------------
    "lookahead K=\u00b2": Case(
        ["run", "l.toml", "-p", "lookahead:K=\u00b2"], ["K=", "whole number"], {"l.toml": LINE}
    ),
    "a cost file that is a FIFO": Case(
        [
            "design",
            "l.toml",
            "--out",
            "d",
            "--target",
            "80",
            "--vary",
            "robots.arm_speed=2,3",
            "--costs",
            "c.toml",
        ],
        ["--costs", "FIFO"],
        {"l.toml": LINE},
        (fifo("c.toml"),),
    ),
    "a cost file linked to /dev/zero": Case(
        [
            "design",
            "l.toml",
            "--out",
            "d",
            "--target",
            "80",
            "--vary",
            "robots.arm_speed=2,3",
            "--costs",
            "c.toml",
        ],
        ["--costs", "character device"],
        {"l.toml": LINE},
        (link("c.toml", "/dev/zero"),),
    ),
    "a policy file that is a FIFO": Case(
        ["run", "l.toml", "-p", "py:p.py:P"],
        ["py:p.py:P", "FIFO"],
        {"l.toml": LINE},
        (fifo("p.py"),),
    ),
    # --- the work limit on every command that simulates --------------------------------
    **{
        f"{cmd} of a year": Case(
            [cmd, "l.toml", "--out", "o", *extra],
            ["duration", "--force"],
            {"l.toml": LINE},
        )
        for cmd, extra in (
            ("headroom", ["--duration", YEAR]),
            ("tune", ["--duration", YEAR]),
            ("capacity", ["--target", "80", "--set", f"duration={YEAR}"]),
            (
                "design",
                ["--target", "80", "--vary", "robots.arm_speed=2,3", "--set", f"duration={YEAR}"],
            ),
        )
    },
}


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_round_three(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run_case(CASES[name], tmp_path, monkeypatch)


def invoke(root: Path, args: list[str], monkeypatch: pytest.MonkeyPatch) -> tuple[int, str, str]:
    monkeypatch.chdir(root)
    result = CliRunner().invoke(app, args)
    return result.exit_code, result.stdout, result.stderr


def write(root: Path, files: dict[str, str | bytes]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(text if isinstance(text, bytes) else text.encode())


def test_design_replays_trace_k_in_replication_k(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before, every replication of a design replayed the first trace: G 90.0 [90.0, 90.0]."""
    write(tmp_path, shifts())
    args = [
        "design",
        "s.toml",
        "--out",
        "d",
        "--target",
        "50",
        "--vary",
        "robots.arm_speed=2,3",
        "--no-report",
    ]
    code, _, err = invoke(tmp_path, args, monkeypatch)
    assert code == 0, err
    assert "at most 3 replications" in err
    rows = json.loads((tmp_path / "d" / "design.json").read_text())["rows"]
    assert rows and all(r["replications"] == 3 for r in rows), rows
    assert all(r["ci_low"] < r["ci_high"] for r in rows), rows  # three traces, not one thrice


def test_headroom_replays_trace_k_for_seed_k(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write(tmp_path, shifts())
    args = [
        "headroom",
        "s.toml",
        "--out",
        "h",
        "--seeds",
        "3",
        "--lookahead",
        "lookahead:K=2,H=0.5",
        "--mix",
        "SD",
    ]
    code, _, err = invoke(tmp_path, args, monkeypatch)
    assert code == 0, err
    runs = (tmp_path / "h" / "runs.csv").read_text().splitlines()[1:]
    sd = {line.split(",")[3] for line in runs if line.startswith("rule,SD,")}
    assert len(sd) == 3, runs  # a trace fixes the arrivals: three Gs, three traces


def test_report_rebuilds_every_kind_of_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``pnp-twin report DIR`` on a design or headroom folder rebuilds its own report (before,
    it tried to read it as a sweep and failed)."""
    write(tmp_path, {"l.toml": LINE})
    for args in (
        [
            "design",
            "l.toml",
            "--out",
            "d",
            "--target",
            "50",
            "--vary",
            "robots.arm_speed=2,3",
            "-r",
            "2",
            "--max-replications",
            "2",
        ],
        ["headroom", "l.toml", "--out", "h", *HEADROOM],
    ):
        code, _, err = invoke(tmp_path, args, monkeypatch)
        assert code == 0, err
        folder = tmp_path / args[args.index("--out") + 1]
        first = (folder / "report.html").read_text()
        (folder / "report.html").unlink()
        code, _, err = invoke(tmp_path, ["report", folder.name], monkeypatch)
        assert code == 0, err
        assert (folder / "report.html").read_text() == first


def test_a_kind_is_recorded_and_resumed_by_the_same_kind(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write(tmp_path, {"l.toml": LINE})
    args = ["headroom", "l.toml", "--out", "h", *HEADROOM]
    assert invoke(tmp_path, args, monkeypatch)[0] == 0
    assert json.loads((tmp_path / "h" / ".pnp-twin.json").read_text())["kind"] == "headroom"
    code, _, err = invoke(tmp_path, args, monkeypatch)  # asked again: its own kind, rewritten
    assert code == 0, err


def test_every_answer_a_user_policy_may_give() -> None:
    spec = RobotSpec(0, 2, (0.3, 0.8), (0.55, 0.65), 3.0, 0.0, 0.1, 0.1, 0.5, 0.4)
    d = Decision(spec, 1.0, (0.5, 0.5), [4, 7], [0.4, 0.5], [0.1, 0.2], [0.2, 0.3])
    import numpy as np

    assert checked_answer(None, d, "p") is None
    assert checked_answer(np.int64(1), d, "p") == 1
    for bad in (-1, 2, 10**9, 0.5, "0", True, float("nan"), [0]):
        with pytest.raises(PolicyAnswerError, match=r"robot 1 at t=1\.000 s \(2 candidates\)"):
            checked_answer(bad, d, "py:p.py:P")


def test_a_slow_user_policy_stops_the_run_in_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write(
        tmp_path,
        {
            "l.toml": LINE,
            "p.py": "import time\nclass P:\n    def reset(self, r, g): pass\n"
            "    def choose(self, d):\n        time.sleep(5)\n",
        },
    )
    code, out, err = invoke(
        tmp_path, ["--decision-timeout", "0.5", "run", "l.toml", "-p", "py:p.py:P"], monkeypatch
    )
    os.environ.pop("PNP_TWIN_DECISION_TIMEOUT", None)
    assert code == 2 and out == ""
    assert "took longer than 0.5 s" in err and err.count("\n") == 1


def test_intervals_of_a_percentage_stay_within_0_and_100() -> None:
    mean, low, high = percent_interval([99.0, 100.0, 94.0])
    assert 0.0 <= low <= mean <= high == 100.0


def test_the_bound_does_not_claim_to_bound_what_the_lookahead_beat() -> None:
    from pnp_twin.studies.headroom import Entry, _bound_clause

    def entry(gain: float) -> Entry:
        e = Entry.__new__(Entry)
        e.gain, e.gain_ci_low, e.gain_ci_high = gain, gain - 0.1, gain + 0.1
        return e

    assert "could gain up to" in _bound_clause(entry(1.2), entry(1.0))
    below = _bound_clause(entry(0.42), entry(0.70))
    assert "could gain" not in below and "below the lookahead" in below


def test_the_repository_holds_no_symbolic_links() -> None:
    """git on Windows checks links out as small text files: the checkout must work without."""
    root = Path(__file__).resolve().parents[2]
    links = [
        p.relative_to(root)
        for p in root.rglob("*")
        if p.is_symlink() and ".venv" not in p.parts and ".git" not in p.parts
    ]
    assert not links, links
