"""The ``train`` and ``evaluate`` commands of ``pnp-twin``: the learned HDQN policy.

``train`` runs :func:`pnp_twin.learning.train.train` (one run, or several training seeds in
parallel worker processes) with a progress bar; ``evaluate`` compares a trained policy with
every rule and the best rule mix on held-out seeds and prints a table of paired differences
(with ``--out DIR``, also ``evaluation.csv`` and ``rules.csv`` for the training report).
torch is imported only when a command runs, so the rest of the CLI works without the
``learn`` extra.
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from enum import StrEnum
from multiprocessing import get_context
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from pnp_twin.cli.app import ScenarioArg, SetOpt, app, fail
from pnp_twin.cli.console import stdout_console
from pnp_twin.parallel import BACKENDS, ray_map
from twin.loader import load_scenario, parse_sets

if TYPE_CHECKING:
    from pnp_twin.learning.train import TrainArgs


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


def _progress_columns() -> list[Any]:
    return [
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[info]}"),
    ]


@app.command("train")
def train_cmd(
    scenario: ScenarioArg,
    out: Annotated[Path, typer.Option("--out", help="Output folder (one sub-folder per run).")],
    mode: Annotated[Mode, typer.Option("--mode", help="single | sync | async.")] = Mode.async_,
    steps: Annotated[
        int, typer.Option("--steps", min=1, help="Transitions to train for.")
    ] = 200_000,
    seed: Annotated[
        int, typer.Option("--seed", min=0, help="Training seed (first of --seeds).")
    ] = 1,
    device: Annotated[str, typer.Option("--device", help="auto | cpu | cuda.")] = "auto",
    network: Annotated[
        str | None,
        typer.Option("--network", help="compact (td default) | paper | pooled (rollout default)."),
    ] = None,
    rules: Annotated[
        str, typer.Option("--rules", help="Comma-separated rules the agent chooses among.")
    ] = "FIFO,LIFO,SIRO,SD,LD,SPT",
    resume: Annotated[
        bool, typer.Option("--resume", help="Continue from the last checkpoint.")
    ] = False,
    seeds: Annotated[
        int, typer.Option("--seeds", min=1, help="Training seeds: seed..seed+K-1.")
    ] = 1,
    workers: Annotated[
        int, typer.Option("--workers", min=1, help="Parallel runs for --seeds.")
    ] = 1,
    backend: Annotated[
        str, typer.Option("--backend", help="Where --seeds runs go: local processes or ray.")
    ] = "local",
    address: Annotated[
        str | None,
        typer.Option("--address", help="Ray cluster address (default RAY_ADDRESS, else local)."),
    ] = None,
    eval_every: Annotated[
        int, typer.Option("--eval-every", min=1, help="Steps between evaluations.")
    ] = 20_000,
    eval_seeds: Annotated[
        int, typer.Option("--eval-seeds", min=2, help="Validation seeds per evaluation.")
    ] = 4,
    view: Annotated[
        str,
        typer.Option("--view", help="Multi-agent input: window (own workspace) | belt (whole)."),
    ] = "window",
    reward: Annotated[
        str,
        typer.Option("--reward", help="Multi-agent reward: own (eq. 1 + 2) | downstream | team."),
    ] = "own",
    targets: Annotated[
        str,
        typer.Option(
            "--targets",
            help="td (DQN on the reward) | rollout (fit to team picks over sampled futures).",
        ),
    ] = "td",
    episodes: Annotated[
        int, typer.Option("--episodes", min=1, help="Rollout targets: labelled episodes.")
    ] = 600,
    futures: Annotated[
        int, typer.Option("--futures", min=1, help="Rollout targets: futures per decision.")
    ] = 12,
    sets: SetOpt = None,
) -> None:
    """Train the HDQN meta-controller; writes OUT/<scenario>__<mode>__<seed>/."""
    _need_torch()
    from policies.hdqn.network import PRESETS

    if targets not in ("td", "rollout"):
        fail(f"--targets: '{targets}' is not allowed; allowed td, rollout")
    network = network or ("pooled" if targets == "rollout" else "compact")
    if network not in PRESETS:
        fail(f"--network: '{network}' is not a preset; allowed {', '.join(PRESETS)}")
    if targets == "rollout":
        _train_rollout(
            scenario,
            out,
            mode,
            seed,
            seeds,
            workers,
            episodes,
            futures,
            rules,
            network,
            device,
            eval_seeds,
            resume,
            sets,
        )
        return
    from pnp_twin.learning.envs.driver import check_rules
    from pnp_twin.learning.train import REWARDS, VIEWS, TrainArgs

    if backend not in BACKENDS:
        fail(f"--backend: '{backend}' is not allowed; allowed {', '.join(BACKENDS)}")
    if view not in VIEWS:
        fail(f"--view: '{view}' is not a view; allowed {', '.join(VIEWS)}")
    if reward not in REWARDS:
        fail(f"--reward: '{reward}' is not a reward; allowed {', '.join(REWARDS)}")
    load_scenario(scenario, parse_sets(sets or []))  # fail early on a bad scenario
    base = TrainArgs(
        scenario=scenario,
        mode=mode.value,
        out=str(out),
        seed=seed,
        steps=steps,
        device=device,
        network=network,
        rules=check_rules([r.strip() for r in rules.split(",") if r.strip()]),
        resume=resume,
        eval_every=eval_every,
        eval_seeds=eval_seeds,
        view=view,
        reward=reward,
        overrides=parse_sets(sets or []),
    )
    runs = [replace(base, seed=s) for s in range(seed, seed + seeds)]
    with Progress(*_progress_columns(), transient=False) as bar:
        if len(runs) == 1:
            from pnp_twin.learning.train import train

            task = bar.add_task(f"train {mode.value}", total=steps, info="")

            def show(p: dict[str, Any]) -> None:
                info = (
                    f"{p['steps_per_s']:.0f} steps/s  reward/step {p['reward']:.3f}  "
                    f"G {p['gripping_rate']:.1f} %  eps {p['epsilon']:.2f}"
                )
                bar.update(task, completed=p["step"], info=info)

            folders = [str(train(runs[0], show))]
        else:
            task = bar.add_task(f"train {mode.value} x{len(runs)}", total=len(runs), info="")
            folders = []

            def done(folder: str) -> None:
                folders.append(folder)
                bar.update(task, advance=1, info=Path(folder).name)

            if backend == "ray":
                ray_map(_train_one, runs, done, workers, address)
            else:
                ctx = get_context("spawn")
                with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
                    for fut in as_completed([pool.submit(_train_one, r) for r in runs]):
                        done(fut.result())
    for f in sorted(folders):
        typer.echo(f)


def _train_rollout(
    scenario: str,
    out: Path,
    mode: Mode,
    seed: int,
    seeds: int,
    workers: int,
    episodes: int,
    futures: int,
    rules: str,
    network: str,
    device: str,
    eval_seeds: int,
    resume: bool,
    sets: list[str] | None,
) -> None:
    """``train --targets rollout``: one async run, labels from ``workers`` processes."""
    from pnp_twin.learning.rollout import LabelSettings
    from pnp_twin.learning.rollout_train import RolloutArgs, train_rollout

    if mode is not Mode.async_:
        fail("--targets rollout trains the async meta-controller; use --mode async")
    if seeds != 1:
        fail("--targets rollout trains one seed; --workers sets the labelling processes")
    chosen = [r.strip().upper() for r in rules.split(",") if r.strip()]
    if rules == "FIFO,LIFO,SIRO,SD,LD,SPT":  # the td default; SIRO cannot be labelled
        chosen.remove("SIRO")
    load_scenario(scenario, parse_sets(sets or []))  # fail early on a bad scenario
    args = RolloutArgs(
        scenario=scenario,
        out=str(out),
        seed=seed,
        episodes=episodes,
        round_episodes=min(100, episodes),
        workers=workers,
        settings=LabelSettings(rules=tuple(chosen), futures=futures),
        network=network,
        device=device,
        eval_seeds=eval_seeds,
        resume=resume,
        overrides=parse_sets(sets or []),
    )
    args.settings.check()  # a bad rule set fails before the progress bar
    with Progress(*_progress_columns(), transient=False) as bar:
        task = bar.add_task("train async (rollout targets)", total=episodes, info="")

        def show(row: dict[str, Any]) -> None:
            info = (
                f"{row['step']} labels  G {row['gripping_rate']:.2f} %  "
                f"vs {row['best_rule']} {row['diff_vs_best_rule']:+.2f}"
            )
            bar.update(task, completed=row["episodes"], info=info)

        folder = train_rollout(args, show)
    typer.echo(str(folder))


@app.command("evaluate")
def evaluate_cmd(
    scenario: ScenarioArg,
    policy: Annotated[str, typer.Option("--policy", help="The trained policy, hdqn:DIR.")],
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
) -> None:
    """Compare a trained HDQN with every rule and the best rule mix, paired by seed."""
    _need_torch()
    from pnp_twin.learning.evaluate import compare, write_evaluation
    from policies.registry import make_policy

    prefix, sep, folder = policy.partition(":")
    if not sep or prefix.lower() != "hdqn" or not folder:
        fail(f"--policy: '{policy}' is not a trained policy; give hdqn:DIR")
    line = load_scenario(scenario, parse_sets(sets or []))
    if mix is not None:
        make_policy(mix, line.robots.count)  # a bad mix fails here, in one line
    if out is not None and out.exists() and not out.is_dir():
        fail(f"--out: '{out}' is a file; give a folder (e.g. the run folder)")
    result = compare(line, folder, seeds=seeds, first_seed=first_seed, mix=mix, duration=duration)
    table = Table(
        title=f"{line.name}: gripping rate on seeds {result.seeds[0]}..{result.seeds[-1]}",
        box=box.SIMPLE,
    )
    for col in ("policy", "G %", "95% CI", "HDQN - policy", "paired 95% CI", "HDQN better"):
        table.add_column(col, justify="left" if col == "policy" else "right")
    for row in result.table.itertuples():
        ref = row.policy == result.reference
        diff = "" if ref else f"{row.diff:+.2f}"
        ci = (
            ""
            if ref or math.isnan(row.diff_ci_low)
            else (f"[{row.diff_ci_low:+.2f}, {row.diff_ci_high:+.2f}]")
        )
        better = "" if ref else ("yes" if row.diff_ci_low > 0 else "no")
        table.add_row(
            row.policy,
            f"{row.gripping_rate:.2f}",
            f"[{row.ci_low:.2f}, {row.ci_high:.2f}]",
            diff,
            ci,
            better,
        )
    stdout_console().print(table)
    if out is not None:
        for path in write_evaluation(result, folder, out):
            typer.echo(f"wrote {path}", err=True)
