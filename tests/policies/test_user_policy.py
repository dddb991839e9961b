"""``py:FILE.py:FACTORY`` / ``py:module:FACTORY``: the user's own policy wherever a policy is
taken, identical to the built-in it copies; every bad spec is one line and exit 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from pnp_twin.cli import app
from pnp_twin.policies import make_policy
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate

MINE = '''
from pnp_twin.policies.rules import RULES


class Copy:
    """Every robot runs one rule, through the user-policy interface."""

    def __init__(self, rule="SPT"):
        self.rule = rule or "SPT"

    def reset(self, robots, rng):
        self.rng = rng

    def choose(self, decision):
        return RULES[self.rule](decision, self.rng)


def broken():
    raise RuntimeError("no weights here")


def not_a_policy():
    return 42
'''


@pytest.fixture
def mine(tmp_path: Path) -> Path:
    path = tmp_path / "mine.py"
    path.write_text(MINE)
    return path


@pytest.mark.parametrize("engine", ["simpy", "fast"])
def test_a_user_policy_runs_exactly_as_the_rule_it_copies(mine: Path, engine: str) -> None:
    sc = load_scenario("paper_baseline", {"duration": 30.0, "warmup": 5.0})
    ours = simulate(sc, make_policy("SD"), seed=4, engine=engine)
    theirs = simulate(sc, make_policy(f"py:{mine}:Copy:SD"), seed=4, engine=engine)
    # the same parts, times and robots; only the "rule" column differs (no last_rule here)
    a, b = (r.parts.drop(columns="rule") for r in (ours, theirs))
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert ours.kpis["gripping_rate"] == theirs.kpis["gripping_rate"]
    # another argument is another policy: the factory's argument reaches it
    other = simulate(sc, make_policy(f"py:{mine}:Copy:FIFO"), seed=4, engine=engine)
    assert not a.equals(other.parts.drop(columns="rule"))


def test_a_module_by_its_dotted_name(mine: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(mine.parent))
    policy = make_policy("py:mine:Copy")
    assert policy.rule == "SPT"  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("spec", "says"),
    [
        ("py:{dir}/absent.py:Copy", "is not a file"),
        ("py:{dir}/mine.py:Nothing", "has no callable 'Nothing'"),
        ("py:{dir}/mine.py:broken", "broken() raised RuntimeError: no weights here"),
        ("py:{dir}/mine.py:not_a_policy", "returned int, which has no reset or choose()"),
        ("py:no_such_module_here:Copy", "cannot import 'no_such_module_here'"),
        ("py:{dir}/mine.py", "give py:FILE.py:FACTORY"),
    ],
)
def test_a_bad_spec_is_one_line(mine: Path, spec: str, says: str) -> None:
    with pytest.raises(UserError) as e:
        make_policy(spec.format(dir=mine.parent))
    assert says in str(e.value) and "\n" not in str(e.value)


def test_the_command_line_takes_it_and_refuses_a_bad_one(mine: Path) -> None:
    args = ["run", "paper_baseline", "--set", "duration=20", "--set", "warmup=2", "--json"]
    good = CliRunner().invoke(app, [*args, "--policy", f"py:{mine}:Copy:SD"])
    rule = CliRunner().invoke(app, [*args, "--policy", "SD"])
    assert good.exit_code == 0, good.output
    assert json.loads(good.stdout)["gripping_rate"] == json.loads(rule.stdout)["gripping_rate"]
    bad = subprocess.run(
        [sys.executable, "-m", "pnp_twin", *args, "--policy", f"py:{mine}:broken"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert bad.returncode == 2
    assert "Traceback" not in bad.stderr and "no weights here" in bad.stderr
