"""The output prediction computes only the outputs that have constraint rows.

quad_attitude tracks yaw and climb rate but bounds only roll and pitch, fw_lateral bounds
the bank angle but not the sideslip: predict_outputs() (C and reference) skips the
unbounded outputs, which no row reads, and charges only the predicted ones
(qp/work.py predict_work). Measured on quad_attitude's scenario (float, default budget):
215 -> 150 TIME_LIMIT samples; fw_lateral 18 -> 9 (a28a654; docs/solver.md, "Work budget").
Since the prediction is one dot product per output at half a unit per multiply-add
(PREDICT_UNITS_PER_OP, 3/5): quad_attitude 99 -> 63, fw_lateral 9 -> 5.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT, Built, lockstep_closed_loop
from rollmpc_codegen.qp.work import PREDICT_UNITS_PER_OP, predict_work
from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

QUAD = ROOT / "examples" / "quad_attitude.yaml"


@pytest.fixture(scope="module")
def quad_float(build_root) -> Built:
    return Built(QUAD, "float", build_root)


def test_only_bounded_outputs_are_predicted_and_charged():
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.reference.solver import SolverRef

    model, ctx = load_model(QUAD, "double")
    md = model.modes[0].data
    assert md.ny == 4 and md.ny_pred == 2 and list(md.pred_out) == [0, 1, 2, 3]
    stages = md.n_yq // md.ny
    units, per = PREDICT_UNITS_PER_OP
    assert predict_work(md) == 2 * md.nu * stages * (stages + 1) // 2 * units // per + md.n_yq
    ref = SolverRef(md, ctx["solver"])
    th = np.random.default_rng(0).normal(size=md.n)
    y = ref.predict_outputs(th).reshape(stages, md.ny)
    dense = (ref.Gam.astype(np.float64) @ th).reshape(stages, md.ny)
    assert np.all(y[:, 2:] == 0.0)  # yaw and climb: no rows, not predicted
    assert np.allclose(y[:, :2], dense[:, :2], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("example, with_rows", [("chain_of_masses", 6),
                                                ("chain_runtime_bounds", 5)])
def test_only_outputs_with_rows_are_predicted(example, with_rows):
    """Every output with rows, and only those, however many: each is its own dot product,
    so an output without rows would cost as much (until da87413 all of them were
    predicted once more than two thirds had rows, chain_runtime_bounds' 6 for 5)."""
    from rollmpc_codegen.pipeline import load_model

    model, _ = load_model(ROOT / "examples" / f"{example}.yaml", "double")
    md = model.modes[0].data
    q = md.row_q[(md.row_q >= md.n) & (md.row_q < md.n + md.n_yq)] - md.n
    bounded = np.unique(q % md.ny)
    assert bounded.size == with_rows and md.ny == 6
    assert md.ny_pred == with_rows
    assert list(md.pred_out[:md.ny_pred]) == list(bounded)
    assert sorted(md.pred_out) == list(range(md.ny))


def test_partial_prediction_is_bit_exact_with_the_reference(quad_float):
    """The C's dot products over the predicted outputs (two at a time, markov_by_output)
    sum each of them in the reference's order: the closed loop through the tilt-limited
    manoeuvre (TIME_LIMIT included) is the reference's bit for bit: status, command,
    corrections, active rows and work."""
    bad, seen = lockstep_closed_loop(quad_float, 500)
    assert bad == []
    statuses = [s for s, _ in seen]
    # 7 TIME_LIMIT and 493 OPTIMAL with the bound form's product charged by what it does
    assert statuses.count(TIME_LIMIT) >= 5 and statuses.count(OPTIMAL) >= 400


@pytest.mark.parametrize("example", ["quad_attitude", "chain_of_masses"])
def test_markov_by_output_is_the_plants_block_toeplitz_gamma(example):
    """The stored markov_by_output, as the reference's Gamma reads it, is C A^(s-t) B of
    the mode's own discrete model at every (stage s, output a; input stage t): computed
    here from A, B, C, not from the stored array, so a wrong layout would show."""
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.reference.unconstrained import output_prediction

    model, _ = load_model(ROOT / "examples" / f"{example}.yaml", "double")
    md = model.modes[0].data
    Gam, _ = output_prediction(md)
    A, B, C = (np.asarray(a, np.float64) for a in (md.A, md.B, md.C))
    lags, AkB = [], B
    for _ in range(md.N):
        lags.append(C @ AkB)
        AkB = A @ AkB
    expected = np.zeros_like(Gam, dtype=np.float64)
    for k in range(md.n_yq):
        stage, a = divmod(k, md.ny)
        for t in range(stage + 1):
            expected[k, t * md.nu:(t + 1) * md.nu] = lags[stage - t][a]
    scale = np.abs(expected).max()
    assert scale > 0.0
    np.testing.assert_allclose(Gam, expected, rtol=1e-9, atol=1e-12 * scale)
