"""templates/solver/qp_solve.c.j2 (P_qp_solve's sequence of methods and its finish: the
status, the clamp, and under the budget the fallback point; mirrored by
reference/solver.py), on the UAV at N = 20 under a budget that binds: the C and the
reference agree bit for bit, work included, through OPTIMAL and TIME_LIMIT samples."""
from __future__ import annotations

from partial_runs import unreached
from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT


def test_the_solve_and_its_fallback_match_the_reference(partial_run):
    bad, statuses, calls = partial_run("uav20_budget")
    assert bad == [], bad[0]
    assert set(statuses) == {OPTIMAL, TIME_LIMIT}, statuses
    assert unreached(calls, "qp_solve finish fallback_point afford") == []
