"""resume_working_set() (templates/solver/resume.c.j2, reference/resume.py) on a
warm start that independent_rows() empties: it starts cold at once, no further round.

In tests/data/kernels/repeated_rows.yaml the first predicted output is y_1 = 0.5 x_1 +
0.5 x_2, which no input moves: its bound rows have H_pp = 0, dependent on any working
set, even the empty one. From x = (-1, -1), y_1 = -1 is below y_min = -0.8 whatever the
inputs: the polish on the violated row breaks down, the dual active set resumes from it,
independent_rows() keeps none of it, and the QP is infeasible. (In the noisy closed loop
this is step 158: tests/host/test_kernel_variants.py.)"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from conftest import Built
from rollmpc_codegen.codegen.build_flags import kernel_flags
from rollmpc_codegen.status import INFEASIBLE

ROWS = Path(__file__).resolve().parents[1] / "data" / "kernels" / "repeated_rows.yaml"
STATE, REFERENCE = (-1.0, -1.0), 0.0


def test_an_emptied_warm_start_starts_cold_bit_exact(build_root):
    built = Built(ROWS, "float", build_root, extra=kernel_flags("rows", False))
    solver = built.reference().solvers[0]
    emptied, independent = [], solver.independent_rows

    def recording(W):
        kept = independent(W)
        emptied.append(W.size > 0 and kept.size == 0)
        return kept

    solver.independent_rows = recording
    x = np.array(STATE, np.float32)
    r = np.full(built.model.config.horizon, REFERENCE, np.float32)
    status, U, sweeps, corrections, _active = solver.qp_solve(x, r)
    st_c, U_c, _ = built.c.solve_qp(0, x, r)
    info = built.c.info()
    assert emptied == [True]
    assert st_c == status == INFEASIBLE
    assert U_c.tobytes() == U.tobytes()
    assert (info["iterations"], info["polish_iterations"], info["work"]) == \
        (sweeps, corrections, solver.work)
