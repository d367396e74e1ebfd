"""dual_active_set() (templates/solver/active_set.c.j2, reference/active_set.py): a resumed
working set that is dual feasible, violates no row outside it and holds at its point is
accepted as it stands (resumed_set_holds()), not handed to polish() to be solved, corrected
and scanned again. On tests/data/heavy/pmsm_speed.yaml with its budget, samples 146-156 of
the nominal loop were such sets: each stopped at TIME_LIMIT after 4,515-5,743 of its 6,720
units, because polish() could not afford the check it would repeat (issue 44, item 1).

Two things are pinned: the shortcut returns exactly what polish() would (point and
multipliers, bit for bit, on a copy of the solver at every hit), and it turns those
samples OPTIMAL, with C and reference in lockstep."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from conftest import ROOT, Built, lockstep_closed_loop
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

PMSM = ROOT / "tests" / "data" / "heavy" / "pmsm_speed.yaml"


def _recorded_hits(monkeypatch, built, steps):
    """The lockstep closed loop of ``built`` with every accepted resumed set checked
    against polish() on a copy of the solver as it stands there, free of the budget:
    (C/reference mismatches, (status, work) of every sample, one tuple per hit: polish's
    code, same point, same active count, same warm start, polish spent more)."""
    args, hits = [], []
    dual_active_set, holds = SolverRef.dual_active_set, SolverRef.resumed_set_holds

    def recording_dual_active_set(self, lam, th0, K, gam, from_=-1):
        args.append((lam.copy(), th0, K, gam))
        try:
            return dual_active_set(self, lam, th0, K, gam, from_)
        finally:
            args.pop()

    def checked_holds(self, W, z, th, gam):
        twin, (lam, th0, K, _) = copy.deepcopy(self), args[-1]
        twin.work_limit = 10**9
        accepted = holds(self, W, z, th, gam)
        if accepted:
            lam_p = lam.copy()
            code, th_p, active, _ = twin.polish(W, lam_p, th0, K, gam, th=th)
            kept = np.zeros_like(lam_p)
            kept[W] = z  # the warm start converged() leaves
            hits.append((code, th_p.tobytes() == th.tobytes(), active == W.size,
                         lam_p.tobytes() == kept.tobytes(), bool(twin.work > self.work)))
        return accepted

    monkeypatch.setattr(SolverRef, "dual_active_set", recording_dual_active_set)
    monkeypatch.setattr(SolverRef, "resumed_set_holds", checked_holds)
    bad, seen = lockstep_closed_loop(built, steps)
    return bad, seen, hits


def test_an_optimal_resumed_set_is_accepted_as_polish_would(build_root, monkeypatch):
    bad, seen, hits = _recorded_hits(monkeypatch, Built(PMSM, "float", build_root), 160)
    statuses = [s for s, _ in seen]
    assert bad == []
    assert len(hits) >= 10
    # polish() would have found the same optimum, spending more
    assert all(h == (0, True, True, True, True) for h in hits)
    # 146-156 were TIME_LIMIT without the shortcut; the run of stops still starts at 130
    assert all(s == OPTIMAL for s in statuses[146:157])
    assert statuses[130] == TIME_LIMIT


@pytest.mark.slow
@pytest.mark.parametrize("config, fewest", [
    # soft pitch rows and Δu rows: 51 hits over the scenario (float)
    (ROOT / "tests" / "data" / "heavy" / "fw_longitudinal.yaml", 40),
    # Δu rows: 6 hits
    (ROOT / "examples" / "thermal_zones_rate.yaml", 4),
])
def test_the_shortcut_agrees_with_polish_on_soft_and_rate_rows(build_root, monkeypatch,
                                                               config, fewest):
    """The same equivalence where polish() would also switch slack states (soft rows) and
    read Δu quantities, over the whole scenario."""
    bad, _, hits = _recorded_hits(monkeypatch, Built(config, "float", build_root), 100000)
    assert bad == []
    assert len(hits) >= fewest
    assert all(h == (0, True, True, True, True) for h in hits)
