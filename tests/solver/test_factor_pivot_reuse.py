"""add_to_set() keeps y = L^-1 H_Wp from one step to the next: a row leaving the working
set at position k (chol_delete()), or a soft row switching state there (chol_rank_one()
from k), changes only rows k.. of the factor and of H_Wp, so factor_pivot() solves again
from row k, not from 0, and gets the bits of a solve from scratch. Its charge is still a
whole solve, so no status, command or work unit moves."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT, Built, lockstep_closed_loop
from rollmpc_codegen.reference.factor_update import chol_delete, chol_rank_one
from rollmpc_codegen.reference.linalg import chol_lsolve_from, cholesky_from


def _factor(n: int, rng, dtype):
    B = rng.standard_normal((n, n))
    A = (B @ B.T + n * np.eye(n)).astype(dtype)
    packed = A[np.tril_indices(n)].copy()
    assert cholesky_from(packed, n)
    return packed


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("change", ["delete", "switch"])
def test_rows_above_the_change_keep_their_solve(dtype, change):
    rng = np.random.default_rng(7)
    same_from_k = differs_from_k1 = 0
    for n in range(2, 40):
        for k in range(n - 1):
            L = _factor(n, rng, dtype)
            h = rng.standard_normal(n).astype(dtype)
            y = h.copy()
            chol_lsolve_from(L, n, y)  # the step before
            if change == "delete":
                chol_delete(L, k, n, np.zeros(n, dtype))
                m, h2 = n - 1, np.delete(h, k)
            else:  # a soft row turning slack: + w e_k e_k'
                v = np.zeros(n, dtype)
                v[k] = np.sqrt(dtype(0.5))
                assert chol_rank_one(L, k, n, v, False, dtype(0))
                m, h2 = n, h
            if k >= m:
                continue
            scratch = h2.copy()
            chol_lsolve_from(L, m, scratch)
            reused = np.concatenate((y[:k], h2[k:]))
            chol_lsolve_from(L, m, reused, k)
            assert reused.tobytes() == scratch.tobytes(), (n, k)
            same_from_k += 1
            late = np.concatenate((y[:k + 1], h2[k + 1:]))  # one row too late: stale
            chol_lsolve_from(L, m, late, k + 1)
            differs_from_k1 += late.tobytes() != scratch.tobytes()
    assert same_from_k > 600
    assert differs_from_k1 > 0.9 * same_from_k  # the check can tell a wrong first row


CASES = [("thermal_zones_rate", "double", 222),  # sample 220: 63 steps of the dual active set
         ("chain_soft", "float", 100)]  # soft rows switching state inside the steps


@pytest.mark.parametrize("example, precision, steps", CASES, ids=[c[0] for c in CASES])
def test_the_c_reuses_the_pivot_solve_as_the_reference(example, precision, steps, build_root):
    built = Built(ROOT / "examples" / f"{example}.yaml", precision, build_root)
    ref = built.reference()
    starts = []
    for solver in ref.solvers:
        pivot = solver.factor_pivot

        def recording(y, hpp, start=0, pivot=pivot):
            starts.append(start)
            return pivot(y, hpp, start)

        solver.factor_pivot = recording
    bad, seen = lockstep_closed_loop(built, steps, ref)
    assert bad == [] and len(seen) == steps
    assert sum(s > 0 for s in starts) >= 20, sum(s > 0 for s in starts)
