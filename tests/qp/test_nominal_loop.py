"""`rollmpc generate`'s warning on a controller that does not stabilise its own model with
no bound active (qp/nominal_loop.py), on a cart-pole written as a new user would
(tests/data/newuser/cart_pole.yaml: N = 40 at 10 ms, P = Q). Every example is checked
not to warn in test_generate_design_checks.py::test_no_example_warns."""
from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from conftest import ROOT
from rollmpc_codegen import pipeline
from rollmpc_codegen.cli import main as cli
from rollmpc_codegen.codegen.context import build_context
from rollmpc_codegen.config import parse
from rollmpc_codegen.qp.nominal_loop import closed_loop_radius, unstable_law_warnings
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import OPTIMAL

CART = ROOT / "tests" / "data" / "newuser" / "cart_pole.yaml"
BASE = yaml.safe_load(CART.read_text())
WARNING = ("modes[0] (balance): with no bound active this controller does not stabilise "
           "its model (the nominal closed loop has an eigenvalue of magnitude 1.00715, "
           "outside the unit circle), so the loop diverges wherever the bounds are "
           "inactive; lengthen the horizon or raise the terminal weight (weights.P)")
REMEDIES = {"horizon 80": {"horizon": 80}, "P = 100 Q": {"P": [1000, 5000]}}


def cart(**changes) -> dict:
    """The cart-pole design with top-level ``changes`` or its one mode's weights (``P``)."""
    d = copy.deepcopy(BASE)
    for key, value in changes.items():
        if key == "P":
            d["modes"][0]["weights"]["P"] = value
        else:
            d[key] = value
    return d


def model_of(data: dict):
    return pipeline.build_model(parse(data))


def test_the_cart_pole_warns_with_its_radius():
    model = model_of(cart())
    assert closed_loop_radius(model, 0) == pytest.approx(1.00715, abs=5e-6)
    assert [w.message for w in unstable_law_warnings(model)] == [WARNING]
    assert [(w.code, w.key) for w in unstable_law_warnings(model)] == [
        ("unstable_nominal_loop", "modes[0].weights.P")]


@pytest.mark.parametrize("changes", REMEDIES.values(), ids=REMEDIES.keys())
def test_a_longer_horizon_or_a_larger_terminal_weight_stabilises_it(changes):
    model = model_of(cart(**changes))
    assert closed_loop_radius(model, 0) < 0.996
    assert unstable_law_warnings(model) == []


@pytest.mark.parametrize("changes, grows", [({}, True), ({"horizon": 80}, False)],
                         ids=["as written", "horizon 80"])
def test_the_radius_is_what_the_solver_does_near_rest(changes, grows):
    """The reference solver (the C's mirror) in a nominal closed loop from a small state,
    where no bound is active: every solve OPTIMAL, and the state grows by about the
    radius' power as written, decays with the longer horizon."""
    model = model_of(cart(**changes))
    plant = model.modes[0].plant
    solver = SolverRef(model.modes[0].data, build_context(model)["solver"])
    x = np.array([1e-4, 0.0, 1e-4, 0.0])
    r = np.zeros(model.config.horizon * 2)
    start, steps = np.linalg.norm(x), 400
    for _ in range(steps):
        status, U, *_ = solver.solve_mode(x, r)
        assert status == OPTIMAL
        x = plant.A @ x + plant.B @ U[:1]
    growth = np.linalg.norm(x) / start
    rho = closed_loop_radius(model, 0)
    if grows:
        assert growth > 0.5 * rho ** steps > 5
    else:
        assert growth < 0.5


def test_generate_prints_it_on_stderr_and_writes_the_controller(tmp_path, capsys):
    out = tmp_path / "out"
    rc = cli.main(["generate", str(CART), "-o", str(out), "--no-float-check"])
    captured = capsys.readouterr()
    assert rc == 0 and (out / "cartpole.h").is_file() and "rollmpc: wrote" in captured.out
    assert captured.err == f"rollmpc: warning: {WARNING}\n"


def test_simulate_names_it_too(tmp_path, capsys):
    """The loop that diverges is explained where it is seen: simulate's summary and JSON."""
    import json

    out = tmp_path / "run.json"
    rc = cli.main(["simulate", str(CART), "--precision", "double", "--steps", "50",
                   "--json", str(out)])
    printed = capsys.readouterr().out
    assert rc == 0 and f"  warning: {WARNING}\n" in printed
    assert json.loads(out.read_text())["design_warnings"] == [WARNING]


DOUBLE_INTEGRATOR = {
    "prefix": "di", "sample_time": 0.1, "horizon": 1, "outputs": ["y"], "actuators": ["u"],
    "modes": [{"name": "m",
               "plant": {"state_space": {"A": [[1, 1], [0, 1]], "B": [[0], [1]],
                                         "C": [[1, 0]], "discrete": True}},
               "weights": {"Q": 1, "R": 0.1, "P": 1},
               "bounds": {"u_min": -1, "u_max": 1, "y_min": -2, "y_max": 2}}]}


@pytest.mark.parametrize("changes, ignores", [
    ({}, True),  # N = 1 and C B = 0: y_1 does not depend on u_0
    ({"horizon": 3}, False),
    ({"weights": {"Q": 0, "R": 0.1, "P": 0}}, True),  # nothing weighted
], ids=["N=1, CB=0", "N=3", "Q=P=0"])
def test_a_law_that_ignores_its_state_is_named(changes, ignores):
    """A new user's double integrator at N = 1 generated u = 0 for every state, silently;
    so did Q = P = 0. generate now says so (and not that the loop is unstable)."""
    data = copy.deepcopy(DOUBLE_INTEGRATOR)
    for key, value in changes.items():
        (data["modes"][0] if key == "weights" else data)[key] = value
    lines = [w.message for w in unstable_law_warnings(model_of(data))]
    named = [ln for ln in lines if "does not depend on the state" in ln]
    assert len(named) == int(ignores) and len(lines) == len(named)
