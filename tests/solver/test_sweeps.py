"""templates/solver/sweeps.c.j2 (Hildreth's sweeps and their correction of th, mirrored by
reference/sweeps.py): with the polish off they solve every constrained QP, and on a -20 deg
step the C and the reference agree bit for bit, sweep count for sweep count, through
OPTIMAL samples and MAX_ITER ones at the cap of 150."""
from __future__ import annotations

from partial_runs import unreached
from rollmpc_codegen.status import MAX_ITER, OPTIMAL


def test_sweeps_alone_match_the_reference(partial_run):
    bad, statuses, calls = partial_run("sweeps_only")
    assert bad == [], bad[0]
    assert unreached(calls, "sweep correct") == []
    assert calls["polish"] == calls["dual_active_set"] == 0  # nothing else solved them
    assert statuses[OPTIMAL] > 0 and statuses[MAX_ITER] > 0, statuses
