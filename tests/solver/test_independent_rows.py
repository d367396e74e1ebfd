"""A warm start whose dual factor breaks down on dependent rows is resumed from its
linearly independent rows, not abandoned for a cold start (docs/solver.md, "The default
method", step 5: independent_rows()). thermal_zones_rate meets it after its third reference
step: the shifted working set holds a Δu row, an input bound and their neighbours that
are linearly dependent. C and reference stay bit for bit, work included."""
from __future__ import annotations

import numpy as np

from conftest import ROOT, Built, lockstep_closed_loop, reference_closed_loop

ZRATE = ROOT / "examples" / "thermal_zones_rate.yaml"
STEPS = 240  # the breakdowns are at samples 226 and 227


def test_dependent_warm_start_resumes_bit_exact(build_root):
    from rollmpc_codegen.reference import solver as solver_mod

    built = Built(ZRATE, "float", build_root)
    bad, seen = lockstep_closed_loop(built, STEPS)
    assert bad == [] and len(seen) == STEPS

    ref = built.reference()
    solver = ref.solvers[0]
    rebuilt = []  # (rows in, rows kept)
    independent = solver_mod.SolverRef.independent_rows

    def recording(self, W):
        kept = independent(self, W)
        rebuilt.append((W.size, kept.size))
        return kept

    solver.independent_rows = recording.__get__(solver)
    seen_ref = [work for _, work in reference_closed_loop(built, ref, STEPS)]
    assert seen_ref == [w for _, w in seen]
    assert rebuilt and all(kept < rows for rows, kept in rebuilt)
    # a cold start from th0 took 170,954 units at sample 226 (commit 5764e7c)
    assert max(seen_ref) < 120_000, max(seen_ref)


def test_independent_rows_drop_a_copied_row(build_root):
    """A row repeated in the working set leaves; the others keep their order and the
    factor is that of their H_WW."""
    from rollmpc_codegen.solver_codes import CHOL_DUAL

    built = Built(ZRATE, "double", build_root)
    solver = built.reference().solvers[0]
    md = solver.md
    rows = np.array([5, 17, 5, 40, 63], dtype=np.int64)  # 5 twice: the copy is dependent
    assert rows.max() < md.m
    work = solver.work
    kept = solver.independent_rows(rows)
    assert kept.tolist() == [5, 17, 40, 63]
    assert solver.chol_holds == CHOL_DUAL and solver.work > work
    k = kept.size
    L = np.zeros((k, k))
    for i in range(k):
        L[i, :i + 1] = solver.chol[i * (i + 1) // 2:i * (i + 1) // 2 + i + 1]
    H = solver.H[np.ix_(kept, kept)]
    assert np.allclose(L @ L.T, H, rtol=1e-12, atol=1e-12 * np.abs(H).max())
