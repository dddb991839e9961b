"""Shipped models hold no subnormal floats; flushing at save and load changes no decision."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")

from pnp_twin.learning.dqn_update import DQNAgent  # noqa: E402
from pnp_twin.learning.train_checkpoint import load_trainer, save_checkpoint  # noqa: E402
from pnp_twin.policies.hdqn.agent import AgentConfig  # noqa: E402
from pnp_twin.policies.hdqn.checkpoint import (  # noqa: E402
    MODEL,
    count_subnormals,
    flush_subnormals,
    load_agent,
    read_tensors,
    resolve,
    shipped_models,
)
from pnp_twin.policies.hdqn.policy import HDQNPolicy  # noqa: E402

PINS = json.loads((Path(__file__).parent / "data" / "flush_decisions.json").read_text())
TINY = torch.finfo(torch.float32).tiny


def test_flush_zeroes_subnormals_only():
    t = torch.tensor([TINY / 4, -TINY / 2, TINY, -TINY, 0.5, 0.0, 1e-45])
    out = flush_subnormals({"w": t, "i": torch.tensor([1, 2])})
    assert out["w"].tolist() == [0.0, 0.0, TINY, -TINY, 0.5, 0.0, 0.0]
    assert out["i"].tolist() == [1, 2]
    assert count_subnormals({"w": t}) == 3 and count_subnormals(out) == 0


@pytest.mark.parametrize("name", shipped_models())
def test_shipped_model_has_no_subnormals(name):
    assert count_subnormals(read_tensors(resolve(name) / MODEL)) == 0


def test_every_shipped_model_is_pinned():
    assert sorted(PINS) == shipped_models()


@pytest.mark.parametrize("name", ["paper_baseline__student", "student_general", "student_any"])
def test_flushed_student_decides_as_before(name):
    """The decisions of the weights as they were shipped before the flush (digest pinned by
    ``bench/flush_models.py --pin``) are those of the flushed model."""
    from bench.flush_models import decisions, digest

    pin = PINS[name]
    parts = decisions(HDQNPolicy.load(name), pin["duration"])
    assert (len(parts), digest(parts)) == (pin["parts"], pin["decisions"])


def test_save_flushes_and_resume_keeps_exact_weights(tmp_path):
    from pnp_twin.policies.hdqn.features import size

    extra = size("student-v2", 5, 4)
    agent = DQNAgent(AgentConfig("student-wide", 1e-3, 0.9, False), (0, 1, 1), 5, extra, "cpu")
    with torch.no_grad():
        first = next(agent.q.parameters())
        first.view(-1)[:10] = TINY / 8
    exact = {k: v.clone() for k, v in agent.q.state_dict().items()}
    save_checkpoint(tmp_path, agent, _meta(), train_state=True)
    assert count_subnormals(read_tensors(tmp_path / MODEL)) == 0
    loaded, _ = load_agent(tmp_path)
    assert count_subnormals(dict(loaded.q.state_dict())) == 0
    resumed, _ = load_trainer(tmp_path, train_state=True)
    for k, v in resumed.q.state_dict().items():
        assert torch.equal(v, exact[k]), k


def _meta():
    from pnp_twin.twin.loader import load_scenario

    return {
        "mode": "async",
        "view": "none",
        "features": "student-v2",
        "rules": ["FIFO", "LIFO", "SD", "LD", "SPT"],
        "n_robots": 4,
        "scenario": load_scenario("paper_baseline").model_dump(mode="json"),
        "counters": {},
    }
