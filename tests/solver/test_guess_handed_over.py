"""A shifted guess whose polish reaches a dual-feasible working set, and then meets a
dependent joining row or more violated rows than the working set has room for, hands that
working set and the factor the appends kept to the dual active set (GUESS_HANDED_OVER,
docs/solver.md "The default method", step 3), instead of giving up and having the dual
active set make the shifted guess dual feasible again, round for round.
thermal_zones_rate meets both around its reference steps. C and reference stay bit for
bit, work included."""
from __future__ import annotations

from conftest import ROOT, Built, lockstep_closed_loop, reference_closed_loop

ZRATE = ROOT / "examples" / "thermal_zones_rate.yaml"
STEPS = 232  # samples 228 (overflow) and 230 (dependent row) are among them


def test_guess_hands_its_feasible_rows_over(build_root):
    from rollmpc_codegen.solver_codes import GUESS_HANDED_OVER
    from rollmpc_codegen.status import OPTIMAL

    built = Built(ZRATE, "double", build_root)
    bad, seen = lockstep_closed_loop(built, STEPS)
    assert bad == [] and len(seen) == STEPS

    ref = built.reference()
    solver = ref.solvers[0]
    handed = []  # (rows handed over, of them with multipliers, rows of the guess then)
    polish = solver.polish

    def recording(W, *args, **kw):
        out = polish(W, *args, **kw)
        if out[0] == GUESS_HANDED_OVER:
            handed.append((solver.stop[0].size, solver.stop[2]))
        return out

    solver.polish = recording
    steps = reference_closed_loop(built, ref, STEPS)
    assert [w for _, w in steps] == [w for _, w in seen]
    assert handed and all(0 < rows == known for rows, known in handed), handed
    # each gave up, then resumed from the shifted guess again (fb9a525): 102,407 and
    # 114,491 units
    for sample in (228, 230):
        status, work = steps[sample]
        assert status == OPTIMAL and work < 75_000, (sample, status, work)
