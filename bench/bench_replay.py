"""How much a replay adds to a report: paper_baseline as shipped (SD, seed 1), the run report
with its replay window against the same report without the replay, per simulated minute.

    python bench/bench_replay.py [--seconds 60]

The issue's budget: a 60 s replay of paper_baseline adds at most 2 MB."""

from __future__ import annotations

import argparse
import json

from pnp_twin.policies import make_policy
from pnp_twin.reports.html import render
from pnp_twin.reports.record_figures import Animation
from pnp_twin.reports.replay_data import replay_data
from pnp_twin.reports.run_report import build_run_page
from pnp_twin.twin.loader import load_scenario
from pnp_twin.twin.run import simulate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    scn = load_scenario("paper_baseline")
    result = simulate(scn, make_policy(scn.policy, scn.robots.count))
    scenario = scn.model_dump(mode="json")
    page = build_run_page(result.kpis, result.parts, result.spans, scenario, "",
                          Animation(seconds=args.seconds))  # fmt: skip
    with_replay = len(render(page).encode("utf-8"))
    page.sections = [s for s in page.sections if s.id != "replay"]
    without = len(render(page).encode("utf-8"))
    data = replay_data(result.parts, result.spans, scenario, result.kpis["seed"], None,
                       args.seconds)  # fmt: skip
    added = with_replay - without
    print(f"paper_baseline, {args.seconds:g} s replay window: report {with_replay / 1e6:.2f} MB, "
          f"replay adds {added / 1e6:.3f} MB ({added / 1e6 / (args.seconds / 60):.3f} MB per "
          f"simulated minute; its data {len(json.dumps(data, separators=(',', ':'))) / 1e3:.0f} "
          f"kB, {len(data['parts']['id'])} parts); budget 2 MB")  # fmt: skip


if __name__ == "__main__":
    main()
