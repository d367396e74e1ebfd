"""Infeasible QPs through the generated C: never OPTIMAL, safe outputs, no sticky state.

Output bounds that no input sequence inside the input box can meet (a phase-1 LP shows a
violation of at least 1e-3 max(1, |b|) on some output row), from states pushed far out.
Required: never OPTIMAL; U finite and inside the input bounds; and the next feasible QP
on the same controller gives bit for bit what a freshly initialised controller gives (no
sticky warm start).  The closed-loop test drives ``P_step`` out of its output bounds
through the measurement and back.

The default suite runs a quick campaign (iteration cap 200 to keep it short) and checks
safety, recovery and "never OPTIMAL" on its 32 QPs; the slow test (make check-long)
asserts the same on 1,000 QPs with the product's default cap.
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from conftest import Built, short_uav_config
from rollmpc_codegen.qp.exact import infeasibility_margin, qp_data, solve_exact
from rollmpc_codegen.verify.qp_campaign import (infeasible_campaign, summarise_infeasible)
from rollmpc_codegen.status import NONFINITE_INPUT, OPTIMAL

N = 20


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    root = tmp_path_factory.mktemp("rinf")
    records = infeasible_campaign(4, 8, root, max_iterations=200)
    return records, summarise_infeasible(records)


def test_quick_infeasible_outputs_are_safe(quick):
    records, summary = quick
    assert summary["qps"] == 32
    assert all(r.safe for r in records)
    assert min(r.margin for r in records) > 1e-3


def test_quick_recovery_after_a_failed_sample_is_a_cold_start(quick):
    """The feasible QP after a non-optimal sample: bit for bit a freshly initialised solve."""
    records, summary = quick
    failed = [r for r in records if r.status != OPTIMAL]
    assert len(failed) >= len(records) // 2
    assert all(r.recovery_same_as_cold for r in failed)


def test_quick_infeasible_never_optimal_and_recovery_solves(quick):
    records, summary = quick
    assert summary["double"]["reported_optimal"] == 0, summary
    assert summary["float"]["reported_optimal"] == 0, summary
    assert all(r.recovery_same_as_cold for r in records), summary
    assert all(r.recovery_status == OPTIMAL for r in records if r.precision == "double"), summary


@pytest.mark.slow
def test_thousand_infeasible_qps(tmp_path):
    records = infeasible_campaign(50, 20, tmp_path)
    summary = summarise_infeasible(records)
    assert summary["qps"] == 1000
    bad = [r for r in records if not r.ok]
    assert bad == [], summary


@pytest.mark.parametrize("precision", ["double", "float"])
def test_closed_loop_leaves_its_output_bounds_and_recovers(tmp_path, build_root, precision):
    """P_step with |roll| <= 10 deg: measurements at 30 deg make the QP infeasible."""
    cfg = short_uav_config(tmp_path, N, max_iterations=50)  # the NumPy mirror sweeps slowly
    data = yaml.safe_load(cfg.read_text())
    for m in data["modes"]:
        m["bounds"].update(y_min=-10.0, y_max=10.0)
    cfg.write_text(yaml.safe_dump(data, sort_keys=False))
    built = Built(cfg, precision, build_root)
    c, ref = built.fresh_c(), built.reference()
    lo = [mm.data.u_min[0] for mm in built.model.modes]
    hi = [mm.data.u_max[0] for mm in built.model.modes]
    seen = {"feasible": 0, "infeasible": 0}
    stream = [0.0] * 5 + [30.0] * 6 + [float("nan")] + [0.0] * 35
    for k, y in enumerate(stream):
        mode_before = ref.mode
        x = ref.xhat[mode_before].copy()
        st, u = c.step([y], [0.0], np.full(N, 5.0))
        st_r, u_r = ref.step([y], [0.0], np.full(N, 5.0))
        assert (st, u.tobytes()) == (st_r, u_r.tobytes()), k
        assert np.all(np.isfinite(u)) and lo[ref.mode] <= u[ref.mode] <= hi[ref.mode]
        if st == NONFINITE_INPUT:
            continue
        qp = built.model.modes[ref.mode].qp
        data_k = qp_data(qp, x.astype(float), np.full(N, 5.0))
        if infeasibility_margin(data_k) > 1e-3:
            seen["infeasible"] += 1
            assert st != OPTIMAL, k
        elif solve_exact(data_k).status == "optimal":
            seen["feasible"] += 1
            assert st == OPTIMAL, k
    assert seen["infeasible"] >= 3 and seen["feasible"] >= 10
    assert st == OPTIMAL
