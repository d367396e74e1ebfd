"""The C and its NumPy mirror are bound by name (docs/architecture.md, "The C and its
mirror"): every C function of the rendered sources has a reference function of the same
name in its partial's module, or is one of the declared exceptions
(rollmpc_codegen/reference/mirror.py); the architecture table lists them all; the solver's
internal codes and constants are the declared ones on both sides.  The planted renames
below show that a rename on one side only fails the check."""
from __future__ import annotations

import ast
import json
import re
from functools import cache

import numpy as np
import pytest

from conftest import ROOT
from rollmpc_codegen import solver_codes
from rollmpc_codegen.codegen.render import render_template
from rollmpc_codegen.reference.mirror import PARTIAL_MODULES, UNMIRRORED

PKG = ROOT / "rollmpc_codegen"
TEMPLATES = ROOT / "templates"
DOC = ROOT / "docs" / "architecture.md"
# together they render every function: soft and Δu rows, run-time bounds, move blocking,
# the float tree's wide kernels
# committed trees, and a design with signal rows and a terminal set (generated here)
TREES = ("fw_lateral", "chain_runtime_bounds", "uav_roll_blocked_f32", "uav_roll",
         "tests/data/constraints/servo_terminal.yaml")
# the generated .c files and the templates they start from
SOURCES = {"solver.c.j2": "_solver.c", "linalg.c.j2": "_linalg.c",
           "controller.c.j2": "_controller.c"}
DEFINITION = re.compile(r"^[A-Za-z_][\w \t*]*?\b(\w+)\(([^;{}]*?)\)\s*\{", re.M)


def c_functions(text: str, prefix: str) -> set[str]:
    """The functions a C text defines (a prototype ends in `;`, a definition in a body),
    with the prefix written P_."""
    return {re.sub(rf"^{prefix}_", "P_", m.group(1)) for m in DEFINITION.finditer(text)}


@cache
def _tree(tree: str) -> tuple[dict, dict]:
    """(context, generated file name -> text) of a committed tree, or of a config's."""
    if tree.endswith(".yaml"):
        from rollmpc_codegen.codegen.render import render_sources
        from rollmpc_codegen.pipeline import load_model

        ctx = load_model(ROOT / tree)[1]
        files = render_sources(ctx)
        return ctx, {n: t for n, t in files.items() if n.endswith((".c", ".h"))}
    src = ROOT / "generated" / tree
    ctx = json.loads(next(src.glob("*_context.json")).read_text())
    return ctx, {p.name: p.read_text() for p in src.iterdir() if p.suffix in (".c", ".h")}


def _included(template: str) -> list[str]:
    return re.findall(r'{%\s*include\s+"([^"]+)"', (TEMPLATES / template).read_text())


def partial_functions(tree: str) -> dict[str, set[str]]:
    """Template -> the C functions it defines itself in this tree: an included partial's
    are those of it rendered alone that the generated file defines (a partial the build
    leaves out defines none), a top template's the rest of its file."""
    ctx, files = _tree(tree)
    out = {}
    for top, suffix in SOURCES.items():
        whole = c_functions(files[ctx["prefix"] + suffix], ctx["prefix"])
        for partial in _included(top):
            out[partial] = c_functions(render_template(ctx, partial, this_file=""), ctx["prefix"]) & whole
        out[top] = whole - set().union(*(out[p] for p in _included(top)))
    return out


def mirror_modules(template: str) -> tuple[str, ...]:
    name = template.removesuffix(".c.j2").rpartition("/")[2]
    return PARTIAL_MODULES.get(template, (f"reference/{name}.py",))


def python_functions(source: str) -> set[str]:
    """Every function and method a module defines."""
    return {n.name for n in ast.walk(ast.parse(source))
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}


def _module_sources() -> dict[str, str]:
    return {str(p.relative_to(PKG)): p.read_text() for p in PKG.glob("*/*.py")}


def table() -> dict[str, tuple[tuple[str, ...], set[str], set[str]]]:
    """The architecture page's table: partial -> (modules, mirrored, unmirrored)."""
    text = DOC.read_text()
    section = text.split("## The C and its mirror", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0].startswith("`"):
            names = [set(re.findall(r"`(\w+)`", c)) for c in cells[2:]]
            rows[cells[0].strip("`")] = (tuple(re.findall(r"`([\w/]+\.py)`", cells[1])), *names)
    return rows


def mirror_problems(functions: dict[str, set[str]], modules: dict[str, str],
                    rows: dict) -> list[str]:
    """Every way the C functions (template -> names), the reference (module -> source)
    and the table (table()) disagree with the rule of reference/mirror.py."""
    problems = []
    defined = {m: python_functions(src) for m, src in modules.items()}
    for template, names in sorted(functions.items()):
        mods = mirror_modules(template)
        python = set().union(*(defined.get(m, set()) for m in mods))
        for name in sorted(names):
            mirrored = name.removeprefix("P_") in python
            if name in UNMIRRORED and mirrored:
                problems.append(f"{name}: declared unmirrored, but {mods} define it")
            elif name not in UNMIRRORED and not mirrored:
                problems.append(f"{name} ({template}): no function of that name in {mods}")
        if names and template not in rows:
            problems.append(f"{template}: not in the architecture table")
        elif names:
            row_mods, row_mirrored, row_unmirrored = rows[template]
            if row_mods != mods:
                problems.append(f"{template}: the table names {row_mods}, the rule {mods}")
            declared = names & set(UNMIRRORED)
            if row_mirrored != names - declared or row_unmirrored != declared:
                problems.append(f"{template}: the table lists {sorted(row_mirrored)} | "
                                f"{sorted(row_unmirrored)}, the C defines {sorted(names)}")
    every = set().union(*functions.values())
    problems += [f"{t}: in the table, no C function" for t in sorted(set(rows) - {
        t for t, n in functions.items() if n})]
    for name, entry in sorted(UNMIRRORED.items()):
        module, _, function = entry.covered_by.partition(".py.")
        if name not in every:
            problems.append(f"{name}: declared unmirrored, but no C function has that name")
        if function not in defined.get(module + ".py", set()):
            problems.append(f"{name}: covered by {entry.covered_by}, which does not exist")
    return problems


def functions_of_trees() -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for tree in TREES:
        for template, names in partial_functions(tree).items():
            out.setdefault(template, set()).update(names)
    return out


def test_every_c_function_has_its_mirror_and_its_table_row():
    assert mirror_problems(functions_of_trees(), _module_sources(), table()) == []


@pytest.mark.parametrize("tree", TREES)
def test_each_function_is_one_partials(tree):
    """No two partials define the same function (so each has one mirror module)."""
    by_template = partial_functions(tree)
    seen = [n for names in by_template.values() for n in names]
    assert len(seen) == len(set(seen)) > 100


def test_a_rename_on_one_side_fails():
    functions, modules, rows = functions_of_trees(), _module_sources(), table()
    # the C renames sweep() (its partial rendered with the new name)
    ctx, _ = _tree("uav_roll")
    renamed = render_template(ctx, "solver/sweeps.c.j2").replace("sweep(", "gauss_seidel(")
    c_side = dict(functions, **{"solver/sweeps.c.j2": c_functions(renamed, ctx["prefix"])})
    assert any("gauss_seidel" in p for p in mirror_problems(c_side, modules, rows))
    # the reference renames its mirror of build_set()
    py_side = dict(modules, **{"reference/sweeps.py": modules["reference/sweeps.py"]
                               .replace("def build_set(", "def sweep_set(")})
    assert any(p.startswith("build_set ") for p in mirror_problems(functions, py_side, rows))
    # an exception no longer needed (the reference now has the function)
    py_side = dict(modules, **{"reference/dot.py": modules["reference/dot.py"]
                               + "\ndef sym_product():\n    pass\n"})
    assert any(p.startswith("sym_product: declared") for p in
               mirror_problems(functions, py_side, rows))


def constant_problems(files: dict[str, str], prefix: str, modules: dict[str, str],
                      real=float) -> list[str]:
    """The internal codes, chol states and P_LAMBDA_LIMIT of solver_codes.py: each defined
    in the rendered C with its value and used there, and never restated in the reference."""
    problems = []
    solver = files[f"{prefix}_solver.c"]
    P = prefix.upper()
    declared = ({c.name: c.value for c in solver_codes.INTERNAL_CODES}
                | {f"{P}_CHOL_{n}": v for n, v in solver_codes.CHOL_STATES})
    text = "".join(files.values())
    for name, value in declared.items():
        defs = re.findall(rf"^#define {name} \(?(-?\d+)\)?", text, re.M)
        if defs != [str(value)]:
            problems.append(f"{name}: defined as {defs} in the C, declared {value}")
        if len(re.findall(rf"\b{name}\b", solver)) < 2:
            problems.append(f"{name}: defined, never used in {prefix}_solver.c")
    limit = re.findall(rf"^#define {P}_LAMBDA_LIMIT ([\d.e+]+)f?$", text, re.M)
    if ([real(float(v)) for v in limit] != [real(solver_codes.LAMBDA_LIMIT)]
            or f"{P}_LAMBDA_LIMIT" not in solver):
        problems.append(f"{P}_LAMBDA_LIMIT: {limit} in the C")
    names = {c.name for c in solver_codes.INTERNAL_CODES} | {
        f"CHOL_{n}" for n, _ in solver_codes.CHOL_STATES} | {"LAMBDA_LIMIT"}
    for module, source in modules.items():
        if not module.startswith("reference/"):
            continue
        for node in ast.walk(ast.parse(source)):
            targets = node.targets if isinstance(node, ast.Assign) else []
            for t in (e for target in targets for e in ast.walk(target)):
                if isinstance(t, ast.Name) and t.id in names:
                    problems.append(f"{module}: restates {t.id} (import it from solver_codes)")
            if isinstance(node, ast.Constant) and node.value == solver_codes.LAMBDA_LIMIT:
                problems.append(f"{module}: restates LAMBDA_LIMIT as a literal")
    return problems


@pytest.mark.parametrize("tree", ["fw_lateral", "uav_roll_f32"])
def test_shared_constants_are_the_declared_ones(tree):
    ctx, files = _tree(tree)
    real = np.float32 if ctx["precision"] == "float" else float  # the literal, rounded
    assert constant_problems(files, ctx["prefix"], _module_sources(), real) == []


def test_a_renamed_constant_fails():
    ctx, files = _tree("uav_roll")
    p, modules = ctx["prefix"], _module_sources()
    c_side = dict(files, **{f"{p}_solver.c": files[f"{p}_solver.c"].replace(
        "#define GUESS_CAPPED", "#define GUESS_CAP")})
    assert any(m.startswith("GUESS_CAPPED:") for m in constant_problems(c_side, p, modules))
    py_side = dict(modules, **{"reference/polish.py": modules["reference/polish.py"]
                               + "\nOUT_OF_WORK = -2\n"})
    assert any("restates OUT_OF_WORK" in m for m in constant_problems(files, p, py_side))
