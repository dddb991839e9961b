"""The training report: learning curves, the rules the HDQN chose per robot (the paper's
figure 13) and the single vs sync vs async comparison (its figure 18), from the tables of
one or more runs (``reports.training_load``). Pure functions from tables to figures to a
Page: nothing here simulates or writes files.
"""

from __future__ import annotations

import math

import pandas as pd

from pnp_twin.reports.html import Page, Section, esc, table_html
from pnp_twin.reports.text import fmt_pct, fmt_seconds
from pnp_twin.reports.training_figures import ci_text, learning_figure, modes_figure, rules_figure
from pnp_twin.reports.training_load import TrainingRun
from pnp_twin.twin.stats import t_interval

MODE_TEXT = {
    "single": "one agent, joint action over all robots",
    "sync": "one agent per robot, shared parameters, synchronous (t_all)",
    "async": "hierarchical multi-agent, asynchronous (t_continue)",
    "async (rollout)": "as async, each agent seeing the whole belt; Q fitted to team picks "
    "over sampled futures (--targets rollout)",
}


def evaluation_table(evaluation: pd.DataFrame) -> pd.DataFrame:
    """Per policy: kind, n, mean and 95 % CI of G, and the paired HDQN − policy difference."""
    wide = evaluation.pivot_table(index="seed", columns="policy", values="gripping_rate")
    kinds = evaluation.drop_duplicates("policy").set_index("policy")["kind"]
    ref = next((p for p in kinds.index if kinds[p] == "hdqn"), None)
    rows = []
    for policy in dict.fromkeys(evaluation["policy"]):
        mean, low, high = t_interval(wide[policy].to_numpy())
        diff = (math.nan, math.nan, math.nan)
        if ref is not None and policy != ref:
            diff = t_interval((wide[ref] - wide[policy]).to_numpy())
        rows.append(
            {
                "policy": policy,
                "kind": kinds[policy],
                "n": int(wide[policy].notna().sum()),
                "mean": mean,
                "ci_low": low,
                "ci_high": high,
                "diff": diff[0],
                "diff_low": diff[1],
                "diff_high": diff[2],
            }
        )
    return pd.DataFrame(rows)


def mode_rows(runs: list[TrainingRun]) -> pd.DataFrame:
    """One row per evaluated run: its HDQN and its best single rule on the same seeds and
    termination scheme, with the paired difference."""
    rows = []
    for run in runs:
        if run.evaluation is None:
            continue
        t = evaluation_table(run.evaluation)
        hdqn, rules = t[t["kind"] == "hdqn"], t[t["kind"] == "rule"]
        if hdqn.empty or rules.empty:
            continue
        h, best = hdqn.iloc[0], rules.loc[rules["mean"].idxmax()]
        term = run.evaluation["termination"].iloc[0] if "termination" in run.evaluation else "?"
        rows.append(
            {
                "run": run.label,
                "mode": run.mode,
                "termination": str(term),
                "n": int(h["n"]),
                "hdqn": h["mean"],
                "hdqn_low": h["ci_low"],
                "hdqn_high": h["ci_high"],
                "rule": best["policy"],
                "rule_mean": best["mean"],
                "rule_low": best["ci_low"],
                "rule_high": best["ci_high"],
                "diff": best["diff"],
                "diff_low": best["diff_low"],
                "diff_high": best["diff_high"],
            }
        )
    return pd.DataFrame(rows)


def evaluation_html(run: TrainingRun) -> str:
    """The held-out comparison of one run as a table (the ``evaluate`` command's)."""
    ev = run.evaluation
    if ev is None:
        return ""
    t = evaluation_table(ev)
    rows, classes = [], []
    for r in t.itertuples():
        ref = r.kind == "hdqn"
        better = "" if ref else ("yes" if r.diff_low > 0 else "no")
        name = r.policy.removeprefix("mix ") if r.kind == "mix" else r.policy
        rows.append(
            [
                esc(name) + ("" if r.kind != "mix" else " <span class='pm'>best static mix</span>"),
                f"{r.mean:.2f} %",
                ci_text(r.ci_low, r.ci_high),
                "" if ref else f"{r.diff:+.2f}",
                "" if ref else ci_text(r.diff_low, r.diff_high, sign=True),
                better,
            ]
        )
        classes.append("best" if ref else "")
    seeds = sorted(ev["seed"].unique().tolist())
    where = f"seeds {seeds[0]}–{seeds[-1]}" if len(seeds) > 1 else f"seed {seeds[0]}"
    extra = []
    for col, unit in (("termination", ""), ("duration", " s")):
        if col in ev.columns:
            extra.append(f"{col} {ev[col].iloc[0]:g}{unit}" if unit else f"{ev[col].iloc[0]}")
    head = (
        f"<h3 style='font-size:15px;margin:18px 0 6px'>{esc(run.label)}"
        f"<span class='pm'> · held-out {esc(where)} · {esc(' · '.join(extra))}</span></h3>"
    )
    header = ["Policy", "G", "95 % CI", "HDQN − policy", "Paired 95 % CI", "HDQN better"]
    return head + table_html(header, rows, left=1, classes=classes)


def trained_steps(run: TrainingRun) -> int:
    """Steps the run trained for: log.csv's last row (meta.json is the kept checkpoint's)."""
    steps = int((run.meta.get("counters") or {}).get("step") or 0)
    if run.log is not None:
        steps = max(steps, int(run.log["step"].max()))
    return steps


def wall_time(run: TrainingRun) -> float:
    """Training wall time in seconds: eval.csv's last figure, else the checkpoint's."""
    wall = float((run.meta.get("counters") or {}).get("wall_time") or 0.0)
    if run.eval is not None and "wall_time" in run.eval.columns:
        wall = max(wall, float(run.eval["wall_time"].max()))
    return wall


def facts_html(runs: list[TrainingRun]) -> str:
    """'What was trained': one column per run."""

    def column(run: TrainingRun) -> dict[str, str]:
        m = run.meta
        args = m.get("train_args") or {}
        agent = m.get("agent") or {}
        counters = m.get("counters") or {}
        steps = trained_steps(run)
        wall = wall_time(run)
        kept = counters.get("step")
        rate = f", {steps / float(wall):,.0f} steps/s" if wall else ""
        target = args.get("steps")
        n_rules = len(m.get("rules") or [])
        scenario = m.get("scenario") or {}
        robots = (scenario.get("robots") or {}).get("count", m.get("n_robots", "?"))
        return {
            "Folder": f"<code>{esc(run.path.name)}</code>",
            "Scenario": f"<b>{esc(run.scenario_name)}</b>, {esc(robots)} robots",
            "Mode": f"<b>{esc(run.mode)}</b> — {esc(MODE_TEXT.get(run.mode, ''))}",
            "Termination": esc(m.get("termination", scenario.get("termination", "–"))),
            "Network": esc(
                f"{agent.get('network', args.get('network', '?'))} preset, input "
                f"{'×'.join(str(x) for x in m.get('obs_shape', []))}, "
                f"{m.get('n_actions', '?')} actions"
            ),
            "Rules": esc(f"{', '.join(m.get('rules') or [])} ({n_rules})"),
            "Steps": esc(
                f"{steps:,}"
                + (f" of {int(target):,}" if target and int(target) != steps else "")
                + (f" · checkpoint kept at step {int(kept):,}" if kept and kept != steps else "")
            ),
            "Wall time": esc(fmt_seconds(float(wall)) + rate if wall else "–")
            + esc(f" · {m.get('device', '?')}"),
            "Agent": esc(
                f"γ {agent.get('gamma', '?')}, lr {agent.get('lr', '?')}, "
                f"batch {args.get('batch_size', '?')}, target every "
                f"{agent.get('target_every', '?')}, double {agent.get('double', '?')}"
            ),
            "Seed": esc(args.get("seed", "–")),
            "Versions": esc(" · ".join(f"{k} {v}" for k, v in (m.get("versions") or {}).items())),
        }

    cols = [column(r) for r in runs]
    body = "".join(
        f"<tr><th>{esc(k)}</th>" + "".join(f"<td>{c[k]}</td>" for c in cols) + "</tr>"
        for k in cols[0]
    )
    return f'<table class="facts"><tbody>{body}</tbody></table>'


def findings(runs: list[TrainingRun], modes: pd.DataFrame) -> list[str]:
    """Plain sentences: each evaluated run against its best rule, then the mode ranking."""
    out = []
    for r in modes.itertuples():
        verdict = (
            "beats" if r.diff_low > 0 else "trails" if r.diff_high < 0 else "cannot be told from"
        )
        out.append(
            f"{r.mode} ({r.termination}): HDQN {fmt_pct(r.hdqn, 2)} on {r.n} held-out seeds "
            f"{verdict} {r.rule}, the best rule under the same scheme ({fmt_pct(r.rule_mean, 2)}"
            f"; paired difference {r.diff:+.2f} points, 95 % CI "
            f"{ci_text(r.diff_low, r.diff_high, sign=True)})."
        )
    if len(modes) > 1:
        ranked = modes.sort_values("hdqn", ascending=False)
        out.append(
            "Held-out ranking of the modes: "
            + " > ".join(f"{r.mode} ({r.hdqn:.1f} %)" for r in ranked.itertuples())
            + "."
        )
    for run in runs:
        if run.eval is not None and r_has(run.eval, "best_rule_gripping_rate"):
            best = run.eval.loc[run.eval["gripping_rate"].idxmax()]
            rule = run.eval["best_rule"].iloc[-1] if r_has(run.eval, "best_rule") else "best rule"
            ref = float(run.eval["best_rule_gripping_rate"].iloc[-1])
            out.append(
                f"{run.label}: best validation {fmt_pct(float(best['gripping_rate']), 2)} at "
                f"step {int(best['step']):,} ({float(best['gripping_rate']) - ref:+.2f} points "
                f"vs {rule} on the same validation seeds)."
            )
    return out


def r_has(table: pd.DataFrame, column: str) -> bool:
    return column in table.columns and len(table) > 0


def cards(runs: list[TrainingRun], modes: pd.DataFrame) -> list[tuple[str, str, str]]:
    """The headline numbers under the title."""
    out = []
    if len(modes):
        top = modes.loc[modes["hdqn"].idxmax()]
        out.append(("Best HDQN, held out", fmt_pct(top["hdqn"], 2), f"{top['run']}"))
        out.append(("Its best rule", fmt_pct(top["rule_mean"], 2), f"{top['rule']}, same seeds"))
    steps = sum(trained_steps(r) for r in runs)
    wall = sum(wall_time(r) for r in runs)
    out.append(("Runs", str(len(runs)), ", ".join(r.mode for r in runs)))
    out.append(("Training steps", f"{steps:,}", "meta-controller transitions"))
    out.append(("Wall time", fmt_seconds(wall) if wall else "–", "all runs together"))
    return out


def build_training_page(runs: list[TrainingRun]) -> Page:
    """The training report of ``runs`` (one run, or several: one column/panel each)."""
    modes = mode_rows(runs)
    notes = [f"{r.path.name}: {n}" for r in runs for n in r.notes]
    items = "".join(f"<li>{esc(t)}</li>" for t in findings(runs, modes))
    note_html = "".join(f'<p class="note">{esc(n)}</p>' for n in notes)
    sections = [
        Section("findings", "Key findings", "", [f'<ul class="findings">{items}</ul>{note_html}']),
        Section("setup", "What was trained", "", [facts_html(runs)]),
    ]
    curves = [learning_figure(r) for r in runs if r.log is not None or r.eval is not None]
    if curves:
        intro = (
            "Reward per meta-controller step (eq. 1 + eq. 2, what the agent maximises) and the "
            "gripping rate of training episodes (exploring, ε-greedy) against training steps; "
            "the validation line is the greedy policy on held-out seeds, the dashed line the "
            "best single rule on the same seeds, the star the checkpoint that was kept."
        )
        sections.append(Section("curves", "Learning curves", esc(intro), list(curves)))
    if any(r.rules is not None for r in runs):
        intro = (
            "How often the trained policy chose each dispatching rule, per robot, over one "
            "held-out run (the paper's figure 13)."
        )
        sections.append(
            Section("rules", "Rules chosen per robot", esc(intro), [rules_figure(runs)])
        )
    if len(modes):
        intro = (
            "The paper's figure 18: each run's HDQN on held-out seeds next to the best single "
            "rule under the same termination scheme and seeds (common random numbers). "
            "Synchronous decisions (t_all) cost every policy, so compare each pair first."
        )
        sections.append(
            Section("modes", "Single vs sync vs async", esc(intro), [modes_figure(modes)])
        )
        tables = [evaluation_html(r) for r in runs if r.evaluation is not None]
        intro = (
            "Every policy on the same held-out seeds; the difference to the HDQN is paired by "
            "seed. “HDQN better” when the paired 95 % CI lies above zero."
        )
        sections.append(Section("evaluation", "Held-out evaluation", esc(intro), tables))
    first = runs[0]
    name = first.scenario_name
    versions = first.meta.get("versions") or {}
    what = "HDQN training" if len(runs) == 1 else f"HDQN training, {len(runs)} runs"
    lead = esc((first.meta.get("scenario") or {}).get("description") or "")
    return Page(
        title=f"{name}: {what}",
        eyebrow="pnp-twin report<span class='badge'>training</span>",
        lead=lead,
        cards=cards(runs, modes),
        sections=sections,
        footer=esc(
            f"Generated by pnp-twin {versions.get('pnp_twin', '')} from "
            f"{first.path.name if len(runs) == 1 else first.path.parent.name}/ · self-contained: "
            "opens offline. Gripping rate G = parts picked / parts presented."
        ),
    )
