"""A dual polish whose corrected point violates no row checks its working set against the
output prediction violated_outside() has just made at that point, instead of predicting
the outputs again (working_set_holds(..., predicted = 1)). chain_of_masses meets it on its
hardest samples; C and reference stay bit for bit, work included."""
from __future__ import annotations

from conftest import ROOT, Built, lockstep_closed_loop

CHAIN = ROOT / "examples" / "chain_of_masses.yaml"
STEPS = 74  # sample 72, its hardest before (18,371 units)


def test_the_final_check_reuses_the_prediction(build_root):
    from rollmpc_codegen.qp.work import predict_work
    from rollmpc_codegen.status import OPTIMAL

    built = Built(CHAIN, "double", build_root)
    bad, seen = lockstep_closed_loop(built, STEPS)
    assert bad == [] and len(seen) == STEPS
    status, work = seen[72]
    # one prediction fewer; the certificate (n + m) is paid as before
    assert status == OPTIMAL
    assert work == 18_371 - predict_work(built.model.modes[0].data), work
