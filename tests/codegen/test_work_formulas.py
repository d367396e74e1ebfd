"""The work formulas are declared once (rollmpc_codegen/qp/work.py): the C functions that
work_formula.c.j2 renders from them compute, on uint32_t, what the Python functions
compute, on random sizes and arguments (every path, not only those a closed loop meets)."""
from __future__ import annotations

import json
import random
import subprocess
from types import SimpleNamespace

import pytest

from conftest import ROOT, require_tool
from rollmpc_codegen.qp import work
from rollmpc_codegen.qp.work_formula import FORMULAS

# trees with every formula: the dual active set and the guess; one with Δu rows (H reads
# cost twice); one with signal rows (generated here: their sizes nzq and z_pred_ops enter
# the formulas, which a tree without them leaves out)
TREES = [("fw_lateral", "fwlat"), ("thermal_zones_rate", "zrate"),
         ("tests/data/constraints/quad_rates.yaml", "quadrates")]
SIZES = ("n", "m", "nyq", "ny", "nu", "nx", "nt", "ny_pred")
SIGNAL_SIZES = ("nzq", "z_pred_ops")
SOFT_SIZES = ("w_cap",)  # a member only where a mode has soft rows (has_soft_rows)


def _cases(count: int, seed: int) -> list[tuple[dict, dict]]:
    """(sizes, arguments) pairs whose every difference the C forms stays non-negative."""
    rng = random.Random(seed)
    out = []
    for _ in range(count):
        ny, stages, nu = rng.randint(1, 4), rng.randint(1, 60), rng.randint(1, 4)
        n = nu * stages
        sizes = {"n": n, "m": rng.randint(1, 400), "nyq": ny * stages, "ny": ny, "nu": nu,
                 "nx": rng.randint(1, 12), "nt": rng.randint(0, 6),
                 "ny_pred": rng.randint(0, ny), "nzq": rng.randint(0, 200),
                 "z_pred_ops": rng.randint(0, 20000),
                 "w_cap": n + rng.choice((0, rng.randint(1, 40)))}  # n: no soft row
        order = rng.randint(1, 120)
        k = rng.randint(0, order - 1)
        kp = rng.randint(0, n)  # a primal factor's order: at most n
        args = {"count": rng.randint(0, 400), "nin": rng.randint(0, n),
                "nout": rng.randint(0, sizes["nyq"]), "nw": rng.randint(0, 60), "n": order,
                "k": k, "nt": rng.randint(0, 6), "start": rng.randint(0, k),
                "bound_form": rng.randint(0, 1), "bound_runs": rng.randint(0, 20),
                "rows": rng.randint(0, 30)}
        out.append((sizes, args, kp))
    return out


def _args(name: str, args: dict, kp: int) -> list[tuple[str, int]]:
    params = [(p, kind) for p, kind in FORMULAS[name].params if kind not in ("md", "design")]
    if name == "primal_work":  # a factor of order k <= n from row start <= k
        return [(p, {"k": kp, "start": min(args["start"], kp)}.get(p, args[p]))
                for p, _ in params]
    return [(p, args[p]) for p, _ in params]


def _harness(prefix: str, names: list[str], cases, signals: bool, soft: bool) -> str:
    lines = [f'#include "{prefix}_solver.c"', '#include <stdio.h>', "int main(void)", "{",
             f"    {prefix}_mode_data md;"]
    for sizes, args, kp in cases:
        lines += [f"    md.{s} = {sizes[s]};" for s in SIZES + (SIGNAL_SIZES if signals else ())
                  + (SOFT_SIZES if soft else ())]
        for name in names:
            call_args = (["&md"] if FORMULAS[name].params[0][1] == "md" else []) + [
                f"{v}u" if dict(FORMULAS[name].params)[p] == "uint" else str(v)
                for p, v in _args(name, args, kp)]
            lines.append(f'    printf("%lu\\n", (unsigned long){name}({", ".join(call_args)}));')
    return "\n".join(lines + ["    return 0;", "}", ""])


def _python(name: str, sizes: dict, args: dict, kp: int, factor: int, signals: bool,
            soft: bool) -> int:
    """The Python formula; a tree without signal rows has no signal sizes (0), one without
    soft rows no soft pairs (w_cap = n)."""
    m = SimpleNamespace(**{("n_yq" if s == "nyq" else s): v for s, v in sizes.items()})
    if not signals:
        m.nzq = m.z_pred_ops = 0
    if not soft:
        m.w_cap = m.n
    f = getattr(work, name)
    positional = ([m] if FORMULAS[name].params[0][1] == "md" else []) + [
        v for _, v in _args(name, args, kp)]
    return f(*positional, **{p: factor for p in FORMULAS[name].design})


@pytest.mark.parametrize("tree,prefix", TREES)
def test_c_work_functions_compute_the_python_formulas(tmp_path, tree, prefix):
    gcc = require_tool("gcc", "apt-get install -y gcc")
    signals = tree.endswith(".yaml")
    src = ROOT / "generated" / tree
    if signals:
        from rollmpc_codegen.pipeline import generate

        src = tmp_path / "tree"
        generate(ROOT / tree, src)
    text = (src / f"{prefix}_solver.c").read_text()
    names = [n for n in FORMULAS if f"static uint32_t {n}(" in text]
    assert len(names) == len(FORMULAS)  # these trees render every formula
    context = json.loads((src / f"{prefix}_context.json").read_text())
    factor, soft = context["solver"]["hq_work_factor"], bool(context.get("has_soft_rows"))
    cases = _cases(60, seed=len(tree))
    (tmp_path / "h.c").write_text(_harness(prefix, names, cases, signals, soft))
    exe = tmp_path / "h"
    subprocess.run([gcc, "-O1", "-w", f"-I{src}", str(tmp_path / "h.c"),
                    str(src / f"{prefix}_linalg.c"), "-lm", "-o", str(exe)], check=True)
    got = [int(v) for v in subprocess.run([str(exe)], capture_output=True, text=True,
                                          check=True).stdout.split()]
    want = [_python(name, s, a, kp, factor, signals, soft) for s, a, kp in cases
            for name in names]
    assert all(v < 2**32 for v in want)
    bad = [(i // len(names), names[i % len(names)], g, w)
           for i, (g, w) in enumerate(zip(got, want)) if g != w]
    assert len(got) == len(want) and bad == [], bad[:5]
