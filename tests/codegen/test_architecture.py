"""The layout of docs/architecture.md holds: stage subpackages, no import cycle, small files,
and the generate path free of measurement tooling.

The import graph is read statically (ast), so a cycle hidden in a function-level import
counts too: the graph is what a reader has to follow, not only what Python executes first.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "rollmpc_codegen"
MAX_LINES = 400
STAGES = ("config", "model", "features", "qp", "codegen", "reference", "host", "target", "sim",
          "verify", "cli")
# what `generate` may import: the stages of the pipeline, never measurement or simulation
GENERATE_MAY_IMPORT = ("config", "model", "features", "qp", "codegen", "status", "pipeline",
                       "solver_codes", "info_struct", "parts")
MEASUREMENT_ONLY = ("qp.exact", "qp.peers")


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in PKG.rglob("*.py")}


def imports_of(name: str, path: Path, known: dict[str, Path], top_level_only: bool) -> set[str]:
    """Modules of the package that ``name`` imports (a package's __init__ counts as the package)."""
    tree = ast.parse(path.read_text())
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    found: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.If) and top_level_only:
            continue  # `if TYPE_CHECKING:` blocks are annotations, not dependencies
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[:len(base) - node.level + 1]
                mod = ".".join(anchor + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [f"{mod}.{a.name}" for a in node.names] + [mod]
        else:
            continue
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def graph(top_level_only: bool = False) -> dict[str, set[str]]:
    known = modules()
    return {n: imports_of(n, p, known, top_level_only) for n, p in known.items()}


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in g[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in g:
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle():
    g = graph()
    # a package's __init__ that only re-exports its own modules is not a cycle with them
    for name in g:
        if (PKG / Path(*name.split(".")[1:]) / "__init__.py").exists():
            g[name] = {d for d in g[name] if not d.startswith(name + ".")}
    assert cycles(g) == []


def test_stage_subpackages_exist_and_nothing_is_flat():
    for stage in STAGES:
        assert (PKG / stage / "__init__.py").is_file(), stage
    flat = sorted(p.name for p in PKG.glob("*.py"))
    # only the façade, the pipeline and single-fact modules stay at the top
    assert set(flat) <= {"__init__.py", "pipeline.py", "api.py", "status.py", "solver_codes.py",
                         "info_struct.py", "parts.py", "extras.py"}, flat


@pytest.mark.parametrize("path", sorted(PKG.rglob("*.py")) + sorted((ROOT / "templates").rglob("*.j2")),
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_file_is_small(path):
    assert len(path.read_text().splitlines()) <= MAX_LINES


def test_generate_path_ships_no_measurement_tooling():
    """What `generate` imports at module level: the pipeline's stages only."""
    g = graph(top_level_only=True)
    seen, todo = set(), ["rollmpc_codegen.pipeline"]
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        todo.extend(g[m])
    stages = {m.split(".")[1] for m in seen if m != "rollmpc_codegen"}
    assert stages <= set(GENERATE_MAY_IMPORT), sorted(seen)
    assert not any(m.endswith(x) for m in seen for x in MEASUREMENT_ONLY), sorted(seen)


def test_cycle_finder_finds_a_cycle():
    """The check above could fail: a two-module loop is reported."""
    assert cycles({"a": {"b"}, "b": {"a"}, "c": set()}) == [["a", "b"]]
