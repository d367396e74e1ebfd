"""dual_active_set() (templates/solver/active_set.c.j2, reference/active_set.py): a final
working set that violates no row outside it and is optimal at its point is accepted as it
stands (final_set_holds()), not handed to polish() to be solved, corrected and scanned
again (issue 44, item 1).

- A resumed set (exact = 1) was solved exactly by the factor polish() would use: it is
  accepted when its rows hold, and polish() would return the same point and multipliers
  bit for bit. On tests/data/heavy/pmsm_speed.yaml with its budget, samples 146-156 of the
  nominal loop were such sets, each stopped at TIME_LIMIT because polish() could not
  afford the check it would repeat.
- A set the steps reached (exact = 0) carries multipliers accumulated by the steps: it is
  accepted only when its rows are also tight within the tolerance and no multiplier is
  negative, the KKT conditions polish() checks. Its point is then polish()'s up to the
  rounding of the dual form.

Both are checked on a copy of the solver at every accepted set, with C and reference in
lockstep."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from conftest import ROOT, Built, lockstep_closed_loop
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

PMSM = ROOT / "tests" / "data" / "heavy" / "pmsm_speed.yaml"


def _recorded_hits(monkeypatch, built, steps):
    """The lockstep closed loop of ``built`` with every accepted final set checked against
    polish() on a copy of the solver as it stands there, free of the budget: (C/reference
    mismatches, (status, work) of every sample, one dict per accepted set)."""
    args, hits = [], []
    dual_active_set, holds = SolverRef.dual_active_set, SolverRef.final_set_holds

    def recording_dual_active_set(self, lam, th0, K, gam, from_=-1):
        args.append((lam.copy(), th0, K, gam))
        try:
            return dual_active_set(self, lam, th0, K, gam, from_)
        finally:
            args.pop()

    def checked_holds(self, W, z, th, gam, exact):
        twin, (lam, th0, K, _) = copy.deepcopy(self), args[-1]
        twin.work_limit = 10**9
        accepted = holds(self, W, z, th, gam, exact)
        if accepted:
            lam_p = lam.copy()
            code, th_p, active, _ = twin.polish(W, lam_p, th0, K, gam, th=th)
            kept = np.zeros_like(lam_p)
            kept[W] = z  # the warm start converged() leaves
            same = code == 0 and th_p.tobytes() == th.tobytes()
            gap = (float(np.max(np.abs(th_p - th)) / max(1.0, float(np.max(np.abs(th_p)))))
                   if code == 0 else np.inf)
            hits.append({"exact": bool(exact), "polish_optimal": code == 0, "same": same,
                         "same_set": active == W.size,
                         "same_lam": lam_p.tobytes() == kept.tobytes(),
                         "polish_spends_more": bool(twin.work > self.work), "gap": gap})
        return accepted

    monkeypatch.setattr(SolverRef, "dual_active_set", recording_dual_active_set)
    monkeypatch.setattr(SolverRef, "final_set_holds", checked_holds)
    bad, seen = lockstep_closed_loop(built, steps)
    return bad, seen, hits


def _assert_as_polish_would(hits, exact_at_least, steps_at_least, gap):
    exact = [h for h in hits if h["exact"]]
    stepped = [h for h in hits if not h["exact"]]
    assert len(exact) >= exact_at_least and len(stepped) >= steps_at_least
    # a resumed set: polish() would find the same optimum bit for bit, spending more
    assert all(h["same"] and h["same_set"] and h["same_lam"] and h["polish_spends_more"]
               for h in exact)
    # a set the steps reached: polish() accepts it too, at the point up to rounding
    assert all(h["polish_optimal"] and h["polish_spends_more"] for h in stepped)
    assert max((h["gap"] for h in stepped), default=0.0) <= gap


def test_an_optimal_final_set_is_accepted_as_polish_would(build_root, monkeypatch):
    bad, seen, hits = _recorded_hits(monkeypatch, Built(PMSM, "float", build_root), 160)
    statuses = [s for s, _ in seen]
    assert bad == []
    _assert_as_polish_would(hits, 10, 0, 1e-4)
    # 147-156 were TIME_LIMIT without the shortcut; the run of stops still starts at 130
    assert all(s == OPTIMAL for s in statuses[147:157])
    assert statuses[130] == TIME_LIMIT


@pytest.mark.slow
@pytest.mark.parametrize("config, exact, stepped, gap", [
    # soft pitch rows and Δu rows; one stepped set of an ill-conditioned float QP is 1.4 %
    # from polish()'s point, both within the tolerance of every row
    (ROOT / "tests" / "data" / "heavy" / "fw_longitudinal.yaml", 20, 100, 0.05),
    # Δu rows
    (ROOT / "examples" / "thermal_zones_rate.yaml", 2, 10, 1e-3),
])
def test_the_shortcut_agrees_with_polish_on_soft_and_rate_rows(build_root, monkeypatch,
                                                               config, exact, stepped, gap):
    """The same where polish() would also switch slack states (soft rows) and read Δu
    quantities, over the whole scenario."""
    bad, _, hits = _recorded_hits(monkeypatch, Built(config, "float", build_root), 100000)
    assert bad == []
    _assert_as_polish_would(hits, exact, stepped, gap)
