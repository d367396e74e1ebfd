"""The reference mirrors the public C API call for call: P_solve_qp() (its argument
checks, the plan it keeps between calls, its diagnostics) and P_status_message()."""
from __future__ import annotations

import numpy as np

from conftest import Built, short_uav_config
from rollmpc_codegen.status import BAD_ARGUMENT, NONFINITE_INPUT, Status


def test_solve_qp_and_status_message_are_the_cs(tmp_path, build_root):
    built = Built(short_uav_config(tmp_path, 12), "double", build_root)
    c, ref = built.fresh_c(), built.reference()
    rng = np.random.default_rng(3)
    n_ref = built.ctx["horizon"] * built.ctx["n_outputs"]
    nx = [m.data.nx for m in built.model.modes]
    calls = [(mode, rng.normal(0, 20, nx[mode]), np.full(n_ref, rng.uniform(-40, 40)))
             for mode in (0, 1, 1, 0, 1)]
    calls.append((0, np.full(nx[0], np.nan), np.zeros(n_ref)))
    for mode, x, r in calls:
        st_c, U_c, its_c = c.solve_qp(mode, x, r)
        st_r, U_r, its_r = ref.solve_qp(mode, x, r)
        n = built.model.modes[mode].data.n
        assert (st_c, its_c) == (st_r, its_r) and np.array_equal(U_c[:n], U_r)
        assert c.info()["status"] == ref.last_info()["status"]
        if st_r != NONFINITE_INPUT:
            assert c.info()["work"] == ref.last_info()["work"] > 0
    assert st_r == NONFINITE_INPUT
    assert ref.solve_qp(5, calls[0][1], calls[0][2])[0] == BAD_ARGUMENT
    assert ref.solve_qp(0, None, calls[0][2])[0] == BAD_ARGUMENT  # a NULL x
    for code in range(-1, len(Status) + 1):
        assert ref.status_message(code) == c.status_message(code)
