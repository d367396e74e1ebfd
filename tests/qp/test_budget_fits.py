"""A budget refusal says what fits, and a step without active bounds is one figure in
units and cycles everywhere (docs/checks.md, "One figure per step").

The buck of tests/data/newuser at N = 12 was refused with "210 work units ... must be at
least the 1353 of the unconstrained step" and no fix, while generate estimated that step
at about 7,000 cycles: 1353 units at the budget's 20 cycles per unit is 27,000.  The
units were the worst case (every stage its own reference run, every bounded output
predicted) and the cycles a typical step; both now state the same step."""
from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from conftest import ROOT
from rollmpc_codegen.codegen.context import build_context
from rollmpc_codegen.config import ConfigError, load, parse
from rollmpc_codegen.pipeline import build_model, load_model_from_config
from rollmpc_codegen.qp.budget import check_work_budget
from rollmpc_codegen.qp.footprint import predict, rounded
from rollmpc_codegen.qp.sizes import mode_sizes
from rollmpc_codegen.reference.solver import SolverRef

NEWUSER = ROOT / "tests" / "data" / "newuser"
BUCK = yaml.safe_load((NEWUSER / "buck.yaml").read_text())


def buck(horizon: int, **solver) -> dict:
    data = copy.deepcopy(BUCK)
    data["horizon"] = horizon
    data["solver"] = solver
    return data


def refusal(data: dict) -> ConfigError:
    with pytest.raises(ConfigError) as exc:
        load_model_from_config(parse(data))
    return exc.value


def test_a_refused_budget_names_the_step_and_what_fits():
    exc = refusal(buck(12))
    assert exc.key == "solver.work_budget"
    fp = predict(parse(buck(12)))
    assert exc.problem == (
        "75 units (auto: 0.5 of Ts = 50 us at 168 MHz, 20 cycles per unit on the Cortex-M4F "
        "(FPv4-SP), less 135 for the step outside the solver) are below the "
        f"964 a step without active bounds may charge ({fp.step_units:,} with a held "
        f"reference, about {rounded(fp.step_cycles):,} cycles); what fits: horizon <= 2; "
        "or target.cpu_mhz >= 880")
    assert fp.step_units == 318


@pytest.mark.parametrize("fix", [{"horizon": 2}, {"target": {"cpu_mhz": 880}}],
                         ids=["horizon", "clock"])
def test_what_fits_fits_and_no_more(fix):
    data = {**buck(12), **fix}
    load_model_from_config(parse(data))  # accepted
    if "horizon" in fix:
        refusal({**data, "horizon": 3})
    else:
        refusal({**data, "target": {"cpu_mhz": 879}})


def test_a_share_and_a_control_horizon_are_named_where_they_fit():
    exc = refusal(buck(5, budget_share=0.8))
    assert exc.problem.endswith("what fits: horizon <= 4; or control_horizon: 3; or "
                                "solver.budget_share >= 0.92; or target.cpu_mhz >= 193")
    load_model_from_config(parse({**buck(5, budget_share=0.8), "control_horizon": 3}))
    load_model_from_config(parse(buck(5, budget_share=0.92)))
    refusal(buck(5, budget_share=0.919))


def test_an_explicit_budget_is_told_the_budget_it_needs():
    assert refusal(buck(12, work_budget=300)).problem.endswith(
        "what fits: horizon <= 5; or control_horizon: 1; or solver.work_budget >= 964")


@pytest.mark.parametrize("path", [NEWUSER / "buck.yaml", NEWUSER / "ship_heading.yaml",
                                  ROOT / "examples" / "uav_roll.yaml"],
                         ids=["buck", "ship", "uav_roll"])
def test_the_predicted_units_are_what_the_solver_charges_without_active_bounds(path):
    """The footprint's units are exact: the reference solver (the C's mirror, work for
    work) charges them on the QP at rest with a held reference, no bound active."""
    cfg = load(path, "float")
    model = build_model(cfg)
    ctx = build_context(model)
    charged = []
    for mm in model.modes:
        solver = SolverRef(mm.data, ctx["solver"])
        assert solver.solve_mode(np.zeros(mm.plant.nx), np.zeros(cfg.horizon * cfg.n_outputs))[0] == 0
        charged.append(solver.work)
    assert predict(cfg).step_units == max(charged)


def test_the_budget_check_reads_the_sizes_as_it_reads_the_stored_data():
    """The refusal's figures come from the sizes: the same as the stored arrays'."""
    cfg = parse(buck(4, budget_share=0.9))
    model = build_model(cfg)
    sizes = [mode_sizes(cfg, m) for m in cfg.modes]
    assert check_work_budget(cfg, sizes, 1) == check_work_budget(
        cfg, [mm.data for mm in model.modes], 1)


def test_what_fits_bounds_read_as_numbers_a_user_can_paste():
    """A bound is rounded up (it still holds) and never in exponent form: quad_attitude's
    certificate once said "target.cpu_mhz >= 2.64e+03"."""
    from rollmpc_codegen.qp.fits import at_least

    assert at_least(2638.0) == "2,640"
    assert at_least(174.2) == "175"
    assert at_least(0.5163) == "0.517"
    assert at_least(1.2e6) == "1,200,000"
    assert all("e" not in at_least(v) for v in np.geomspace(1e-3, 1e9, 50))
