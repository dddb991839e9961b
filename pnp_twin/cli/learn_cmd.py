"""The ``train`` and ``evaluate`` commands of ``pnp-twin``: the learned HDQN policy.

``train`` runs :func:`pnp_twin.learning.train.train` (one run, or several training seeds in
parallel worker processes) with a progress display; every :class:`TrainArgs` field is an
option (built from the dataclass, its field docs are the help). ``evaluate`` compares a
trained policy (``hdqn:DIR`` or ``sb3:MODEL.zip``) with every rule and the best rule mix on
held-out seeds and prints a table of paired differences (with ``--out DIR``, also
``evaluation.csv`` and ``rules.csv`` for the training report). torch is imported only when
a command runs, so the rest of the CLI works without the ``learn`` extra.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import MISSING, fields, replace
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer
from rich import box
from rich.table import Table

from pnp_twin.cli.app import INTERRUPTED, Engine, ScenarioArg, SetOpt, app, fail
from pnp_twin.cli.claim import check_folder, claim_folder, inputs_of
from pnp_twin.cli.console import stdout_console
from pnp_twin.cli.train_progress import TrainProgress
from pnp_twin.learning.envs.options import REWARD_WEIGHTS
from pnp_twin.learning.train_args import TrainArgs, field_help
from pnp_twin.parallel import BACKENDS, pool_map_ordered, ray_map
from pnp_twin.twin.loader import load_scenario, parse_sets
from pnp_twin.twin.trace import check_replications

TD_RULES = "FIFO,LIFO,SIRO,SD,LD,SPT"


class Mode(StrEnum):
    """Training set-ups."""

    single = "single"
    sync = "sync"
    async_ = "async"


def _need_torch() -> None:
    try:
        import safetensors  # noqa: F401
        import torch
    except ImportError:
        fail("train and evaluate need the learn extra: pip install 'pnp-twin[learn]'")
    # The networks are tiny: one intra-op thread is much faster than several on a busy CPU.
    torch.set_num_threads(1)


def _train_one(args: TrainArgs) -> str:
    """Worker entry point: one training run; returns its folder."""
    from pnp_twin.learning.train import train

    return str(train(args))


# -- the options of `train`: hand-written ones, then one per TrainArgs field ----------------------
_EXTRA: list[tuple[str, Any, Any]] = [
    ("scenario", ScenarioArg, MISSING),
    (
        "out",
        Annotated[Path, typer.Option("--out", help="Output folder (one sub-folder per run).")],
        MISSING,
    ),
    ("mode", Annotated[Mode, typer.Option("--mode", help="single | sync | async.")], Mode.async_),
    (
        "network",
        Annotated[
            str | None,
            typer.Option(
                "--network", help="compact (td default) | paper | pooled (rollout default)."
            ),
        ],
        None,
    ),
    (
        "rules",
        Annotated[
            str | None,
            typer.Option(
                "--rules",
                help=f"Comma-separated rules the agent chooses among [td: {TD_RULES}; "
                "rollout: the same without SIRO].",
            ),
        ],
        None,
    ),
    (
        "reward_weights",
        Annotated[
            str,
            typer.Option(
                "--reward-weights", help="Weights of eq. 1 and eq. 2, 'EXTRINSIC,INTRINSIC'."
            ),
        ],
        ",".join(f"{w:g}" for w in REWARD_WEIGHTS),
    ),
    (
        "resume",
        Annotated[
            bool, typer.Option("--resume", help="Continue exactly from the last checkpoint.")
        ],
        False,
    ),
    (
        "seeds",
        Annotated[int, typer.Option("--seeds", min=1, help="Training seeds: seed..seed+K-1.")],
        1,
    ),
    (
        "workers",
        Annotated[
            int,
            typer.Option(
                "--workers",
                min=1,
                help="Parallel runs for --seeds (labelling processes for rollout).",
            ),
        ],
        1,
    ),
    (
        "backend",
        Annotated[
            str, typer.Option("--backend", help="Where --seeds runs go: local processes or ray.")
        ],
        "local",
    ),
    (
        "address",
        Annotated[
            str | None,
            typer.Option(
                "--address", help="Ray cluster address (default RAY_ADDRESS, else local)."
            ),
        ],
        None,
    ),
    (
        "targets",
        Annotated[
            str,
            typer.Option(
                "--targets",
                help="td (DQN on the reward) | rollout (fit to team picks over sampled futures).",
            ),
        ],
        "td",
    ),
    (
        "episodes",
        Annotated[
            int, typer.Option("--episodes", min=1, help="Rollout targets: labelled episodes.")
        ],
        600,
    ),
    (
        "futures",
        Annotated[
            int, typer.Option("--futures", min=1, help="Rollout targets: futures per decision.")
        ],
        12,
    ),
    ("sets", SetOpt, None),
]
_HANDWRITTEN = {
    "scenario",
    "out",
    "mode",
    "network",
    "rules",
    "reward_weights",
    "resume",
    "overrides",
}
_SCALED = {"learning_starts", "eval_every", "log_every", "checkpoint_every"}
MAX_INT = 2**31 - 1


def _field_options() -> list[tuple[str, Any, Any]]:
    """One option per remaining TrainArgs field, typed by its default, its doc as help."""
    helps = field_help()
    out = []
    for f in fields(TrainArgs):
        if f.name in _HANDWRITTEN:
            continue
        flag = "--" + f.name.replace("_", "-")
        default = f.default
        decl: Any
        if isinstance(default, bool):
            decl = Annotated[
                bool, typer.Option(f"{flag}/--no-{f.name.replace('_', '-')}", help=helps[f.name])
            ]
        elif f.name in _SCALED:
            decl = Annotated[
                int | None,
                typer.Option(flag, min=0, max=MAX_INT, help=helps[f.name], show_default=False),
            ]
        else:
            kind = type(default)
            low = (0 if f.name == "seed" else 1) if kind is int else None
            high = MAX_INT if kind is int else None  # a seed or a count a 64-bit int holds
            decl = Annotated[kind, typer.Option(flag, help=helps[f.name], min=low, max=high)]
        out.append((f.name, decl, default))
    return out


_OPTIONS = _EXTRA[:2] + _field_options() + _EXTRA[2:]


def train_cmd(**kw: Any) -> None:
    """Train the HDQN meta-controller; writes OUT/<scenario>__<mode>__<seed>/."""
    _need_torch()
    from pnp_twin.policies.hdqn.network import PRESETS

    _check_train_out(Path(kw["out"]), kw["scenario"])
    targets = kw["targets"]
    if targets not in ("td", "rollout"):
        fail(f"--targets: '{targets}' is not allowed; allowed td, rollout")
    kw["network"] = kw["network"] or ("pooled" if targets == "rollout" else "compact")
    if kw["network"] not in PRESETS:
        fail(f"--network: '{kw['network']}' is not a preset; allowed {', '.join(PRESETS)}")
    if targets == "rollout":
        _train_rollout(kw)
        return
    if kw["backend"] not in BACKENDS:
        fail(f"--backend: '{kw['backend']}' is not allowed; allowed {', '.join(BACKENDS)}")
    args = _train_args(kw)
    from pnp_twin.learning.train import resolve_device

    resolve_device(args.device)  # a bad device is refused before the folder is made
    runs = [replace(args, seed=s) for s in range(args.seed, args.seed + kw["seeds"])]
    out, scenario = Path(kw["out"]), kw["scenario"]
    with claim_folder(out, "train", inputs_of(scenario), lock=False, legacy=_run_names(out)):
        if len(runs) == 1:
            folders = [_train_with_progress(runs[0])]
        else:
            folders = _train_seeds(runs, kw["workers"], kw["backend"], kw["address"])
    for f in sorted(folders):
        typer.echo(f)


def _check_train_out(out: Path, scenario: str) -> None:
    """``--out`` holds one folder per run (``<scenario>__<mode>__<seed>``): it must be new,
    empty or a folder of training runs (to add to or resume), and must not hold the
    scenario it trains on; checked before anything is written."""
    check_folder(out, "train", inputs_of(scenario), legacy=_run_names(out))


def _run_names(out: Path) -> set[str]:
    """The training run folders (``<scenario>__<mode>__<seed>``) ``out`` already holds."""
    if not out.is_dir():
        return set()
    return {e.name for e in out.iterdir() if e.is_dir() and e.name.count("__") >= 2}


def _train_args(kw: dict[str, Any]) -> TrainArgs:
    """The TrainArgs of the options, checked before anything is written."""
    from pnp_twin.learning.envs.driver import EnvError
    from pnp_twin.learning.train_args import check_args

    overrides = parse_sets(kw["sets"] or [])
    load_scenario(kw["scenario"], overrides)  # fail early on a bad scenario
    try:
        weights = tuple(float(w) for w in kw["reward_weights"].split(","))
    except ValueError:
        fail(f"--reward-weights: '{kw['reward_weights']}' is not two numbers, e.g. 1,1")
    values = {f.name: kw[f.name] for f in fields(TrainArgs) if f.name in kw}
    args = TrainArgs(
        **{
            **values,
            "mode": kw["mode"].value,
            "out": str(kw["out"]),
            "rules": tuple(r.strip() for r in (kw["rules"] or TD_RULES).split(",") if r.strip()),
            "reward_weights": weights,
            "overrides": overrides,
        }
    )
    try:
        rules = check_args(args)
    except EnvError as e:
        field, _, rest = str(e).partition(":")
        fail(f"--{field.replace('_', '-')}:{rest}")
    return replace(args, rules=rules)


def _train_with_progress(args: TrainArgs) -> str:
    from pnp_twin.learning.train import TrainingInterrupted, train

    with TrainProgress(f"train {args.mode}", args.steps) as show:
        try:
            return str(train(args, show.training_row))
        except TrainingInterrupted as e:
            show.close()
            fail(str(e), INTERRUPTED)


def _train_seeds(
    runs: list[TrainArgs], workers: int, backend: str, address: str | None
) -> list[str]:
    folders: list[str] = []
    with TrainProgress(f"train {runs[0].mode} x{len(runs)}", len(runs)) as show:

        def done(folder: str) -> None:
            folders.append(folder)
            show.advance(Path(folder).name)

        if backend == "ray":
            ray_map(_train_one, runs, done, workers, address)
        else:
            for folder in pool_map_ordered(_train_one, runs, workers, on_result=done):
                del folder
    return folders


def _train_rollout(kw: dict[str, Any]) -> None:
    """``train --targets rollout``: one async run, labels from ``--workers`` processes."""
    from pnp_twin.learning.rollout import LabelSettings
    from pnp_twin.learning.rollout_train import RolloutArgs, train_rollout

    if kw["mode"] is not Mode.async_:
        fail("--targets rollout trains the async meta-controller; use --mode async")
    if kw["seeds"] != 1:
        fail("--targets rollout trains one seed; --workers sets the labelling processes")
    rules = kw["rules"] or TD_RULES.replace("SIRO,", "")  # SIRO cannot be labelled
    chosen = [r.strip().upper() for r in rules.split(",") if r.strip()]
    overrides = parse_sets(kw["sets"] or [])
    load_scenario(kw["scenario"], overrides)  # fail early on a bad scenario
    episodes = kw["episodes"]
    args = RolloutArgs(
        scenario=kw["scenario"],
        out=str(kw["out"]),
        seed=kw["seed"],
        episodes=episodes,
        round_episodes=min(100, episodes),
        workers=kw["workers"],
        settings=LabelSettings(rules=tuple(chosen), futures=kw["futures"]),
        network=kw["network"],
        device=kw["device"],
        eval_seeds=kw["eval_seeds"],
        resume=kw["resume"],
        overrides=overrides,
        engine=kw["engine"],
    )
    args.settings.check()  # a bad rule set fails before the progress display
    with TrainProgress("train async (rollout)", episodes) as show:
        folder = train_rollout(args, show.rollout_row)
    typer.echo(str(folder))


def _register_train() -> None:
    params = [
        inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=decl)
        if default is not MISSING
        else inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, annotation=decl)
        for name, decl, default in _OPTIONS
    ]
    train_cmd.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    train_cmd.__annotations__ = {name: decl for name, decl, _ in _OPTIONS}
    app.command("train")(train_cmd)


_register_train()


@app.command("evaluate")
def evaluate_cmd(
    scenario: ScenarioArg,
    policy: Annotated[
        str,
        typer.Option(
            "--policy",
            help="The policy to place: hdqn:DIR, sb3:MODEL.zip or lookahead[:K=16,H=1].",
        ),
    ],
    seeds: Annotated[int, typer.Option("--seeds", min=2, help="Held-out seeds 0..N-1.")] = 20,
    first_seed: Annotated[int, typer.Option("--first-seed", min=0, help="First seed.")] = 0,
    mix: Annotated[
        str | None, typer.Option("--mix", help="The best rule mix (default: searched).")
    ] = None,
    duration: Annotated[
        float | None, typer.Option("--duration", min=1.0, help="Feeding time per run, s.")
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Also write evaluation.csv and rules.csv here (e.g. the run folder).",
            show_default=False,
        ),
    ] = None,
    sets: SetOpt = None,
    engine: Annotated[
        Engine,
        typer.Option(
            "--engine",
            help="Engine of every run, the trained policy's too: simpy, fast or auto (same "
            "results).",
        ),
    ] = Engine.auto,
) -> None:
    """Compare a trained policy with every rule and the best rule mix, paired by seed."""
    _need_torch()
    from pnp_twin.learning.evaluate import compare, write_evaluation
    from pnp_twin.policies.registry import make_policy

    prefix, sep, target = policy.partition(":")
    if policy.strip().lower() == "lookahead":  # the lookahead controller with its defaults
        prefix, sep, target = "lookahead", ":", "defaults"
    if not sep or prefix.lower() not in ("hdqn", "sb3", "lookahead") or not target:
        fail(
            f"--policy: '{policy}' is not a trained policy; give hdqn:DIR, sb3:MODEL.zip or "
            "lookahead[:K=16,H=1]"
        )
    reference = target if prefix.lower() == "hdqn" else policy
    line = load_scenario(scenario, parse_sets(sets or []))
    check_replications(line, seeds, "--seeds")  # seed k replays trace k
    if mix is not None:
        make_policy(mix, line.robots.count)  # a bad mix fails here, in one line
    if out is not None and out.exists() and not out.is_dir():
        fail(f"--out: '{out}' is a file; give a folder (e.g. the run folder)")
    make_policy(policy, line.robots.count)  # a broken model fails before any run
    result = compare(
        line,
        reference,
        seeds=seeds,
        first_seed=first_seed,
        mix=mix,
        duration=duration,
        engine=engine.value,
    )
    stdout_console().print(_comparison_table(result, line.name))
    if out is not None:
        for path in write_evaluation(result, reference, out):
            typer.echo(f"wrote {path}", err=True)


def _comparison_table(result: Any, name: str) -> Table:
    table = Table(
        title=f"{name}: gripping rate on seeds {result.seeds[0]}..{result.seeds[-1]}",
        box=box.SIMPLE,
    )
    for col in ("policy", "G %", "95% CI", "trained - policy", "paired 95% CI", "better"):
        table.add_column(col, justify="left" if col == "policy" else "right")
    for row in result.table.itertuples():
        ref = row.policy == result.reference
        ci = (
            ""
            if ref or math.isnan(row.diff_ci_low)
            else f"[{row.diff_ci_low:+.2f}, {row.diff_ci_high:+.2f}]"
        )
        table.add_row(
            row.policy,
            f"{row.gripping_rate:.2f}",
            f"[{row.ci_low:.2f}, {row.ci_high:.2f}]",
            "" if ref else f"{row.diff:+.2f}",
            ci,
            "" if ref else ("yes" if row.diff_ci_low > 0 else "no"),
        )
    return table
