"""The rule-mix search: exhaustive is a brute force; GRASP stays in budget and is seeded."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from pnp_twin.policies import make_policy
from pnp_twin.studies import Options
from pnp_twin.studies.plan import StudyError
from pnp_twin.studies.rulemix import run_mix
from pnp_twin.studies.seeds import replication_seeds
from pnp_twin.twin import load_scenario, simulate, with_overrides

RULES = ["FIFO", "LD", "SPT"]


@pytest.fixture(scope="module")
def two_robots():
    return with_overrides(
        load_scenario("paper_baseline"),
        {"robots.count": 2, "feeder.rate": 6.0, "duration": 40, "warmup": 5},
    )


def test_exhaustive_finds_the_brute_force_best(two_robots, tmp_path):
    _, mix = run_mix(two_robots, tmp_path, Options(workers=1), RULES, replications=2)
    assert mix["method"] == "exhaustive" and mix["evaluated"] == 9
    seeds = replication_seeds(two_robots.seed, 2)
    brute = {}
    for combo in itertools.product(RULES, repeat=2):
        name = ",".join(combo)
        g = [simulate(two_robots, make_policy(name), seed=s).kpis["gripping_rate"] for s in seeds]
        brute[name] = float(np.mean(g))
    assert mix["best"] == max(brute, key=brute.__getitem__)
    ranked = {r["mix"]: r["gripping_rate_mean"] for r in mix["ranked"]}
    assert ranked == pytest.approx(brute)
    means = [r["gripping_rate_mean"] for r in mix["ranked"]]
    assert means == sorted(means, reverse=True)
    saved = json.loads((tmp_path / "mix.json").read_text())
    assert saved["best"] == mix["best"]
    assert json.loads((tmp_path / "meta.json").read_text())["kind"] == "mix"


def test_grasp_is_seeded_and_within_budget(tmp_path):
    line = with_overrides(load_scenario("paper_baseline"), {"duration": 30, "warmup": 5})
    rules = ["FIFO", "SD", "SPT", "LD"]  # 4^4 = 256 mixes: beyond the exhaustive limit
    _, a = run_mix(line, tmp_path / "a", Options(workers=1), rules, replications=1, budget=12)
    assert a["method"] == "grasp" and a["evaluated"] == 12
    uniform = {",".join([r] * 4) for r in rules}
    assert uniform <= {r["mix"] for r in a["ranked"]}  # GRASP starts from the uniform mixes
    _, b = run_mix(line, tmp_path / "b", Options(workers=1), rules, replications=1, budget=12)
    assert a["ranked"] == b["ranked"]


def test_bad_rule_is_an_error(two_robots, tmp_path):
    with pytest.raises(StudyError, match="mix: 'XYZ' is not a rule"):
        run_mix(two_robots, tmp_path, Options(workers=1), ["FIFO", "XYZ"])


class ScoredSearch:
    """A MixSearch stand-in that scores mixes by a formula instead of simulating them."""

    def __init__(self, budget: int) -> None:
        self.budget, self.order, self.scores = budget, [], {}
        self.stopped = ""

    @property
    def left(self) -> int:
        return self.budget - len(self.order)

    def evaluate(self, mixes):
        for m in dict.fromkeys(mixes):
            if m not in self.scores and self.left > 0:
                self.order.append(m)
                self.scores[m] = float(sum(len(r) for r in m.split(",")) + m.count("SPT"))
        return {m: self.scores[m] for m in mixes if m in self.scores}


def test_grasp_ends_when_every_reachable_mix_is_known():
    # 2 rules on 3 robots is 8 mixes, far below the budget: the search used to spin for good
    # once every neighbour was scored (issue 10, item 1)
    import threading

    from pnp_twin.studies.rulemix import grasp

    search = ScoredSearch(budget=1000)
    worker = threading.Thread(
        target=grasp, args=(search, ["FIFO", "SPT"], 3, np.random.default_rng(0), 0.3), daemon=True
    )
    worker.start()
    worker.join(timeout=10)
    assert not worker.is_alive(), "grasp did not end within 10 s"
    assert search.stopped == "converged"
    assert len(search.order) <= 8 and "SPT,SPT,SPT" in search.order


def test_mix_json_gives_the_paired_margin_over_the_runner_up(two_robots, tmp_path):
    _, mix = run_mix(two_robots, tmp_path, Options(workers=1), ["FIFO", "SPT"], replications=3)
    m = mix["margin"]
    assert m["best"] == mix["ranked"][0]["mix"] and m["runner_up"] == mix["ranked"][1]["mix"]
    gap = mix["ranked"][0]["gripping_rate_mean"] - mix["ranked"][1]["gripping_rate_mean"]
    assert m["diff_mean"] == pytest.approx(gap)
    assert m["ci_low"] <= m["diff_mean"] <= m["ci_high"] and m["n"] == 3
    assert m["distinguishable"] == (m["ci_low"] > 0)


def test_mix_takes_the_cost_file_of_sweep_and_size(tmp_path):
    """``mix --costs FILE``: each mix's total cost in meta.json (the what-if panel's), in
    mix.json's ranking, the terminal table and the report's table; a bad file is one line."""
    import json

    from typer.testing import CliRunner

    from pnp_twin.cli import app

    (tmp_path / "costs.toml").write_text(
        "robot_price = 25000\nbelt_price = 8000\nlost_part_cost = 0.05\nhours = 4000\n"
    )
    args = ["mix", "paper_baseline", "--rules", "FIFO,SPT", "-r", "2", "--workers", "1"]
    for s in ("robots.count=2", "feeder.rate=6", "duration=20", "warmup=2"):
        args += ["--set", s]
    out = tmp_path / "mix"
    runner = CliRunner()
    done = runner.invoke(app, [*args, "--out", str(out), "--costs", str(tmp_path / "costs.toml")])
    assert done.exit_code == 0, done.output
    meta = json.loads((out / "meta.json").read_text())
    assert meta["costs"]["file"] == "costs.toml" and len(meta["costs"]["rows"]) == 4
    ranked = json.loads((out / "mix.json").read_text())["ranked"]
    lost = {r["mix"]: r["total_cost"] - 2 * 25000 - 8000 for r in ranked}
    assert all(v >= 0 for v in lost.values())
    assert "total cost" in done.stdout
    html = (out / "report.html").read_text()
    assert '">Total cost</th>' in html and f"{ranked[0]['total_cost']:,.0f}" in html
    assert "priced from costs.toml" in html  # the what-if panel's cost
    bad = runner.invoke(app, [*args, "--out", str(tmp_path / "b"), "--costs", "nope.toml"])
    assert bad.exit_code == 2 and "--costs" in bad.stderr and len(bad.stderr.splitlines()) == 1
    assert not (tmp_path / "b").exists()
