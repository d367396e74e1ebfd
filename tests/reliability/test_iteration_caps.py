"""Iteration caps from 1 upward stop exactly at the cap, safely.

The cap (``solver.max_iterations``) is a compile-time constant, so every cap is its own
build of the UAV controller (N = 20, small data).  The QP is a -20 deg step from rest,
which the sweeps alone (polish off) need hundreds of sweeps for in the inner mode and
never finish in the outer one.  For each cap: MAX_ITER, exactly ``cap`` sweeps, U finite
and inside the actuator limits, and bit for bit what the NumPy reference returns with
the same cap; ``P_step`` reports the same through ``P_last_info``.  With the polish on,
the cap still bounds the sweeps and MAX_ITER means exactly ``cap`` sweeps.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import Built, short_uav_config
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import MAX_ITER, OPTIMAL

N = 20
QUICK = [("hildreth_plus_prime", cap) for cap in (1, 2, 3, 5)] + \
        [("hildreth", 1), ("hildreth_plus", 2)]
LONG = [(method, cap) for method in ("hildreth", "hildreth_plus", "hildreth_plus_prime")
        for cap in (*range(1, 41), 50, 64, 100, 128, 200, 250)]


def _check_cap(tmp_path, build_root, method: str, cap: int) -> None:
    cfg = short_uav_config(tmp_path, N, f"cap_{method}_{cap}", method=method,
                           max_iterations=cap, polish=False)
    built = Built(cfg, "double", build_root)
    r = np.full(N, -20.0)
    for mode, mm in enumerate(built.model.modes):
        x = np.zeros(mm.data.nx)
        # one more sweep does not finish either (else the cap is not exercised)
        more = SolverRef(mm.data, dict(built.ctx["solver"], max_iterations=cap + 1))
        st_u, _, its_u, _, _ = more.solve_mode(x, r)
        assert not (st_u == OPTIMAL and its_u <= cap)
        c = built.fresh_c()
        st, U, its = c.solve_qp(mode, x, r)
        assert (st, its) == (MAX_ITER, cap), (method, cap, mode)
        assert np.all(np.isfinite(U))
        assert np.all(U >= mm.data.u_min[0]) and np.all(U <= mm.data.u_max[0])
        st_r, U_r, its_r, _, _ = SolverRef(mm.data, built.ctx["solver"]).solve_mode(x, r)
        assert (st_r, its_r) == (st, its) and U_r.tobytes() == U.tobytes()
    c = built.fresh_c()
    st, u = c.step([0.0], [0.0], r)  # at rest the inner mode is active
    info = c.info()
    assert (st, info["status"], info["iterations"], info["mode"]) == (MAX_ITER, MAX_ITER, cap, 0)
    assert np.all(np.isfinite(u)) and -15.0 <= u[0] <= 15.0 and u[1] == 0.0


@pytest.mark.parametrize("method,cap", QUICK)
def test_cap_stops_exactly(tmp_path, build_root, method, cap):
    _check_cap(tmp_path, build_root, method, cap)


@pytest.mark.slow
@pytest.mark.parametrize("method,cap", LONG)
def test_cap_stops_exactly_long(tmp_path, build_root, method, cap):
    _check_cap(tmp_path, build_root, method, cap)


@pytest.mark.parametrize("cap", [10, pytest.param(1, marks=pytest.mark.slow),
                                 pytest.param(25, marks=pytest.mark.slow)])
def test_cap_with_polish_bounds_the_sweeps(tmp_path, build_root, cap):
    """Polish on (the default): sweeps <= cap, MAX_ITER only at exactly the cap, C == NumPy."""
    cfg = short_uav_config(tmp_path, N, f"capp_{cap}", max_iterations=cap)
    built = Built(cfg, "double", build_root)
    rng = np.random.default_rng(cap)
    c = built.fresh_c()
    refs = [SolverRef(mm.data, built.ctx["solver"]) for mm in built.model.modes]
    seen = set()
    for k in range(40):
        mode = k % 2
        x = rng.normal(size=built.model.modes[mode].data.nx) * rng.uniform(0, 30)
        r = np.full(N, rng.uniform(-60, 60))
        st, U, its = c.solve_qp(mode, x, r)
        st_r, U_r, its_r, _, _ = refs[mode].solve_mode(x, r)
        assert (st, its) == (st_r, its_r) and U.tobytes() == U_r.tobytes()
        assert its <= cap and (st != MAX_ITER or its == cap)
        lo, hi = built.model.modes[mode].data.u_min[0], built.model.modes[mode].data.u_max[0]
        assert np.all(np.isfinite(U)) and np.all((U >= lo) & (U <= hi))
        seen.add(st)
    assert OPTIMAL in seen
