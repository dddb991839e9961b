"""Broken checkpoints: each kind is one ``error:`` line and exit code 2, in ``run`` and
``evaluate``; a model trained on another line gives one warning line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

pytest.importorskip("torch")
pytest.importorskip("safetensors")
import torch  # noqa: E402
from safetensors.torch import load_file, save_file  # noqa: E402

from pnp_twin.cli import app  # noqa: E402
from pnp_twin.policies.hdqn.checkpoint import CheckpointError, load_agent  # noqa: E402

SHIPPED = Path(__file__).resolve().parents[2] / "models" / "paper_baseline__async"
SHORT = ["--set", "duration=8", "--set", "warmup=1"]


def _meta(folder: Path) -> dict:
    return json.loads((folder / "meta.json").read_text())


def _write_meta(folder: Path, meta) -> None:
    (folder / "meta.json").write_text(json.dumps(meta))


def _tensors(folder: Path, change) -> None:
    tensors = load_file(str(folder / "model.safetensors"))
    change(tensors)
    save_file(tensors, str(folder / "model.safetensors"))


def _edit(folder: Path, change) -> None:
    meta = _meta(folder)
    change(meta)
    _write_meta(folder, meta)


def _first(tensors) -> str:
    return sorted(tensors)[0]


BROKEN = {
    "meta is a list": (lambda f: _write_meta(f, [1, 2]), "must be a JSON object"),
    "missing key": (lambda f: _edit(f, lambda m: m.pop("obs_shape")), "obs_shape: missing"),
    "extra key": (lambda f: _edit(f, lambda m: m.update(colour="red")), "colour: unknown key"),
    "bad scenario": (
        lambda f: _edit(f, lambda m: m["scenario"]["belt"].update(speed=-1)),
        "scenario: belt.speed",
    ),
    "unknown rule": (lambda f: _edit(f, lambda m: m.update(rules=["FIFO", "EDD"])), "'EDD'"),
    "absurd shape": (
        lambda f: _edit(f, lambda m: m.update(obs_shape=[3, 4096, 4096])),
        "obs_shape",
    ),
    "truncated weights": (
        lambda f: (f / "model.safetensors").write_bytes(
            (f / "model.safetensors").read_bytes()[:100]
        ),
        "not a readable safetensors file",
    ),
    "empty weights": (
        lambda f: (f / "model.safetensors").write_bytes(b""),
        "not a readable safetensors file",
    ),
    "wrong tensor shape": (
        lambda f: _tensors(f, lambda t: t.update({_first(t): torch.zeros(3, 3)})),
        "has shape (3, 3)",
    ),
    "missing tensor": (
        lambda f: _tensors(f, lambda t: t.pop(_first(t))),
        "is missing",
    ),
    "all NaN": (
        lambda f: _tensors(f, lambda t: [v.fill_(float("nan")) for v in t.values()]),
        "NaN or infinite",
    ),
}


@pytest.fixture
def broken(tmp_path, request):
    folder = tmp_path / "ck"
    shutil.copytree(SHIPPED, folder)
    breaker, message = BROKEN[request.param]
    breaker(folder)
    return folder, message


@pytest.mark.parametrize("broken", list(BROKEN), indirect=True)
@pytest.mark.parametrize("command", ["run", "evaluate"])
def test_a_broken_checkpoint_is_one_error_line_and_exit_2(broken, command):
    folder, message = broken
    args = [command, "paper_baseline", "--policy", f"hdqn:{folder}", *SHORT]
    if command == "evaluate":
        args += ["--seeds", "2", "--mix", "SPT"]
    result = CliRunner().invoke(app, args)
    out = result.output.strip().splitlines()
    assert result.exit_code == 2, result.output
    assert len(out) == 1 and out[0].startswith("error: checkpoint: "), result.output
    assert message in out[0] and "Traceback" not in result.output
    with pytest.raises(CheckpointError):
        load_agent(folder)


def test_a_model_trained_on_another_line_gives_one_warning(tmp_path, caplog):
    from pnp_twin.policies.registry import make_policy
    from pnp_twin.twin.loader import load_scenario
    from pnp_twin.twin.run import simulate

    scenario = load_scenario("paper_baseline", {"duration": 5.0, "warmup": 1.0, "belt.speed": 0.7})
    with caplog.at_level("WARNING"):
        simulate(scenario, make_policy(f"hdqn:{SHIPPED}"), seed=0)
    lines = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(lines) == 1 and "trained on scenario 'paper_baseline'" in lines[0]
    assert "belt.speed 0.7 (trained 0.8)" in lines[0]
