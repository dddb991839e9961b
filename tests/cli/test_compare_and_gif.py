"""``pnp-twin compare`` (two policies, one seed, both replays in step) and ``run --gif`` /
``--replay-window``: what they print, write and refuse."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.policies import make_policy
from pnp_twin.reports.compare_report import swapped_parts
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate

SHORT = ["--set", "duration=30", "--set", "warmup=5"]


def test_compare_writes_both_replays_and_counts_swapped_parts(tmp_path: Path) -> None:
    out = tmp_path / "cmp.html"
    args = ["compare", "paper_baseline", "-p", "SD", "-p", "FIFO", "--seed", "4", *SHORT]
    result = CliRunner().invoke(app, [*args, "--replay-window", "10", "--report", str(out)])
    assert result.exit_code == 0, result.output
    assert re.search(r"SD\s+\d+\.\d\d\s+\d+\s+\d+\s+\d+", result.output)
    html = out.read_text(encoding="utf-8")
    payload = html.split('class="rp-data">', 1)[1].split("</script>", 1)[0]
    datas = json.loads(payload.replace("<\\/", "</"))
    assert [d["title"] for d in datas] == ["SD", "FIFO"]
    assert all(d["t0"] == 5.0 and d["t1"] == 15.0 for d in datas)
    fed = [dict(zip(d["parts"]["id"], d["parts"]["fed"], strict=True)) for d in datas]
    common = fed[0].keys() & fed[1].keys()
    assert len(common) > 50 and all(fed[0][k] == fed[1][k] for k in common)  # the same parts
    scn = load_scenario("paper_baseline", {"duration": 30.0, "warmup": 5.0})
    a, b = (simulate(scn, make_policy(p, 4), seed=4).parts for p in ("SD", "FIFO"))
    a_only, b_only = swapped_parts(a, b, 5.0)
    assert f"{a_only} parts SD grips are lost by FIFO, {b_only} the other way" in html


@pytest.mark.parametrize(
    "args",
    [
        ["compare", "paper_baseline", "-p", "SD"],
        ["compare", "paper_baseline", "-p", "SD", "-p", "NOPE"],
        ["compare", "paper_baseline", "-p", "SD", "-p", "FIFO", "--report", "x.txt"],
        ["run", "paper_baseline", "--gif", "x.png"],
    ],
)
def test_bad_input_is_one_line_and_exit_2(args: list[str]) -> None:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    assert result.output.count("error:") == 1


def test_run_writes_a_gif_of_the_replay_window(tmp_path: Path) -> None:
    iio = pytest.importorskip("imageio.v3")
    gif, report = tmp_path / "line.gif", tmp_path / "r.html"
    args = ["run", "two_sided", *SHORT, "--replay-window", "4", "--gif", str(gif)]
    result = CliRunner().invoke(app, [*args, "--report", str(report)])
    assert result.exit_code == 0, result.output
    frames = iio.imread(gif)
    assert frames.shape[0] == 9  # 4 s at 5x speed, 10 frames/s: t0, t0 + 0.5, ..., t0 + 4
    assert (frames[0] != frames[-1]).any()
    assert "from t = 5 s to 9 s" in report.read_text(encoding="utf-8")
