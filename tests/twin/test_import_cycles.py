"""No import circles among the core's modules (issue 17): every ``pnp_twin.twin`` module
imports only modules that do not import it back, directly or through others. Imports under
``TYPE_CHECKING`` and inside functions count too (grimp sees them all), so a circle cannot
hide behind a lazy import."""

from __future__ import annotations

import importlib.machinery
import importlib.util
import subprocess
import sys
from pathlib import Path
from unittest import mock

import grimp

CORE = "pnp_twin.twin"
ROOT = Path(__file__).resolve().parents[2]


def staged_graph(tmp: Path) -> grimp.ImportGraph:
    """The import graph of the package as installed (``.ci/stage_tree.py``: the checkout maps
    its folders into ``pnp_twin`` without links, and grimp reads folders)."""
    stage = tmp / "stage"
    subprocess.run([sys.executable, str(ROOT / ".ci" / "stage_tree.py"), str(stage)], check=True)
    find = importlib.util.find_spec

    def staged(name: str, package: str | None = None) -> importlib.machinery.ModuleSpec | None:
        if name == "pnp_twin":
            return importlib.machinery.PathFinder.find_spec(name, [str(stage)])
        return find(name, package)

    with mock.patch("importlib.util.find_spec", staged):
        return grimp.build_graph("pnp_twin", cache_dir=None)


def cycles(graph: grimp.ImportGraph, package: str) -> list[list[str]]:
    """The strongly connected components of more than one module among ``package``'s
    modules (Tarjan's algorithm, iterative): each is an import circle."""
    modules = sorted(m for m in graph.modules if m == package or m.startswith(package + "."))
    inside = set(modules)
    edges = {m: sorted(inside & graph.find_modules_directly_imported_by(m)) for m in modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for root in modules:
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            if i < len(edges[node]):
                work.append((node, i + 1))
                nxt = edges[node][i]
                if nxt not in index:
                    work.append((nxt, 0))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            if low[node] == index[node]:
                component = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    component.append(top)
                    if top == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
    return found


def test_the_core_has_no_import_cycles(tmp_path: Path) -> None:
    graph = staged_graph(tmp_path)
    assert any(m.startswith(CORE + ".") for m in graph.modules)
    found = cycles(graph, CORE)
    chains = [" -> ".join(graph.find_shortest_chain(c[0], c[1]) or (c[0], c[1])) for c in found]
    assert not found, f"import circles among {CORE}: {found}; e.g. {chains}"


def test_the_check_finds_a_planted_circle(tmp_path: Path) -> None:
    graph = staged_graph(tmp_path)
    graph.add_import(
        importer="pnp_twin.twin.geometry",
        imported="pnp_twin.twin.records",
        line_number=1,
        line_contents="from pnp_twin.twin.records import Recorder",
    )
    found = cycles(graph, CORE)
    assert ["pnp_twin.twin.geometry", "pnp_twin.twin.records"] in found
