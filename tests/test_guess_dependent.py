"""A shifted guess whose polish reaches a dual-feasible working set and then meets a
dependent joining row hands that working set, and the factor the appends kept, to the dual
active set (GUESS_DEPENDENT, docs/solver.md "The default method", step 3), instead of
refactoring every row, breaking down and resuming from the shifted guess again.
thermal_zones_rate meets it around its reference steps. C and reference stay bit for bit,
work included."""
from __future__ import annotations

from conftest import ROOT, Built, lockstep_closed_loop, reference_closed_loop

ZRATE = ROOT / "examples" / "thermal_zones_rate.yaml"
STEPS = 232  # its hardest double sample, 230, is one of them


def test_dependent_join_resumes_from_the_feasible_rows(build_root):
    from rollmpc_codegen.reference.polish_dual import GUESS_DEPENDENT
    from rollmpc_codegen.status import OPTIMAL

    built = Built(ZRATE, "double", build_root)
    bad, seen = lockstep_closed_loop(built, STEPS)
    assert bad == [] and len(seen) == STEPS

    ref = built.reference()
    solver = ref.solvers[0]
    handed = []  # (rows handed over, of them with multipliers)
    polish = solver.polish

    def recording(W, *args, **kw):
        out = polish(W, *args, **kw)
        if out[0] == GUESS_DEPENDENT:
            handed.append((solver.stop[0].size, solver.stop[2]))
        return out

    solver.polish = recording
    steps = reference_closed_loop(built, ref, STEPS)
    assert [w for _, w in steps] == [w for _, w in seen]
    assert handed and all(0 < rows == known for rows, known in handed), handed
    status, work = steps[230]
    assert status == OPTIMAL
    # refactoring the 40 rows, then resuming from the shifted guess: 114,491 units (fb9a525)
    assert work < 80_000, work
