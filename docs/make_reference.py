"""Write the guide's reference pages from their sources: docs/reference/cli.md from the
command line's own ``--help`` and docs/reference/scenario.md from the scenario JSON Schema
(scenarios/scenario.schema.json). Run after changing a command or a scenario field:

    python docs/make_reference.py

tests/docs/test_guide.py fails while a page is out of date."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
CLI_PAGE = ROOT / "docs" / "reference" / "cli.md"
SCENARIO_PAGE = ROOT / "docs" / "reference" / "scenario.md"


def help_text(args: list[str]) -> str:
    from typer.testing import CliRunner

    from pnp_twin.cli import COMMANDS, app, load_commands

    load_commands(list(COMMANDS))
    env = {"COLUMNS": "100", "NO_COLOR": "1", "TERM": "dumb"}
    result = CliRunner().invoke(app, [*args, "--help"], env=env, prog_name="pnp-twin")
    return "\n".join(line.rstrip() for line in result.output.splitlines()).strip()


def cli_page() -> str:
    from pnp_twin.cli import COMMANDS

    out = [
        "# Command-line reference",
        "",
        "Generated from `pnp-twin --help` and each command's `--help` by "
        "`python docs/make_reference.py`; do not edit by hand.",
        "",
        "```text",
        help_text([]),
        "```",
    ]
    for name in COMMANDS:
        out += ["", f"## `pnp-twin {name}`", "", "```text", help_text([name]), "```"]
    return "\n".join(out) + "\n"


def _type(spec: dict[str, Any]) -> str:
    if "$ref" in spec:
        name = spec["$ref"].rsplit("/", 1)[-1]
        return f"[{name}](#{name.lower()})"
    if "anyOf" in spec:
        return " or ".join(_type(s) for s in spec["anyOf"])
    if spec.get("type") == "array":
        return f"list of {_type(spec.get('items') or {})}"
    if "enum" in spec:
        return " or ".join(f"`{v}`" for v in spec["enum"])
    return str(spec.get("type", "any"))


def _cell(text: Any) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _table(schema: dict[str, Any]) -> list[str]:
    rows = ["| field | type | default | meaning |", "| --- | --- | --- | --- |"]
    for name, spec in (schema.get("properties") or {}).items():
        default = json.dumps(spec["default"]) if "default" in spec else ""
        rows.append(
            f"| `{name}` | {_cell(_type(spec))} | {_cell(default)} | "
            f"{_cell(spec.get('description', ''))} |"
        )
    return rows


def scenario_page() -> str:
    schema = json.loads((ROOT / "scenarios" / "scenario.schema.json").read_text("utf-8"))
    out = [
        "# Scenario file reference",
        "",
        "Generated from the scenario JSON Schema (`scenarios/scenario.schema.json`, printed by "
        "`pnp-twin schema`) by `python docs/make_reference.py`; do not edit by hand. A "
        "scenario file is TOML or YAML; every field can also be set with "
        "`--set PATH=VALUE` (dotted paths, e.g. `robots.arm_speed`).",
        "",
        "## Scenario (the top level)",
        "",
        *_table(schema),
    ]
    for name, sub in (schema.get("$defs") or {}).items():
        out += ["", f"## {name}", ""]
        if sub.get("description"):
            out += [_cell(sub["description"]), ""]
        out += _table(sub) if sub.get("properties") else [f"Type: {_cell(_type(sub))}"]
    return "\n".join(out) + "\n"


def main() -> None:
    os.environ.setdefault("COLUMNS", "100")
    CLI_PAGE.write_text(cli_page(), encoding="utf-8")
    SCENARIO_PAGE.write_text(scenario_page(), encoding="utf-8")
    print(f"wrote {CLI_PAGE.relative_to(ROOT)} and {SCENARIO_PAGE.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
