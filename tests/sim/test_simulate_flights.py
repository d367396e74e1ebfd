"""`rollmpc simulate --flights K`: random flights of the host C (sim/flights_run.py), each
with its statuses, longest TIME_LIMIT run and hard-bound violations; the totals adding them
up; flight i flown again alone with --seed S+i, its counts those of the reference; and
one-line errors for the options that write one closed loop."""
from __future__ import annotations

import json

import numpy as np
import pytest

from rollmpc_codegen.sim.metrics import longest_run, time_limit_warning
from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

from conftest import ROOT
from test_simulate_cli import run_cli

QUAD = ROOT / "examples" / "quad_attitude.yaml"
STEPS = 600  # the scenario's first segments: tilt steps, TIME_LIMIT samples among them


def _flights(tmp_path, capsys, count, seed, name):
    path = tmp_path / f"{name}.json"
    rc, out, err = run_cli(["simulate", str(QUAD), "--precision", "float", "--flights",
                            str(count), "--seed", str(seed), "--steps", str(STEPS), "--quiet",
                            "--json", str(path)],
                           capsys)
    assert rc == 0, err
    return json.loads(path.read_text()), out


@pytest.fixture(scope="module")
def three_flights():
    from rollmpc_codegen.sim.flights_run import run_flights

    return run_flights(QUAD, flights=3, seed=7, precision="float", steps=STEPS).summary


def test_totals_add_up_the_flights(three_flights):
    s = three_flights
    flights, t = s["flights"], s["totals"]
    assert [f["seed"] for f in flights] == [7, 8, 9]
    assert len({tuple(map(tuple, f["levels"])) for f in flights}) == 3  # distinct references
    for f in flights:
        assert f["samples"] == STEPS == sum(f["status_counts"].values())
    assert t["samples"] == 3 * STEPS
    for name in {n for f in flights for n in f["status_counts"]}:
        assert t["status_counts"][name] == sum(f["status_counts"].get(name, 0) for f in flights)
    assert t["optimal_percent"] == round(100 * t["status_counts"]["optimal"] / (3 * STEPS), 2)
    assert t["longest_time_limit_run"] == max(f["longest_time_limit_run"] for f in flights)
    assert t["flights_with_violations"] == sum(f["constraint_violations"]["total"] > 0
                                               for f in flights)
    assert t["status_counts"].get("time_limit", 0) > 0  # the budget binds on these flights
    works = [f["work"] for f in flights]
    assert t["work"]["max"] == max(w["max"] for w in works) <= t["work"]["budget"]
    assert min(w["median"] for w in works) <= t["work"]["median"] <= max(w["median"]
                                                                         for w in works)
    assert t["work"]["budget"] == s["solver"]["work_budget"]
    # seeds 7 and 9 press the envelope, 8 stays inside: each kind adds up its own flights
    assert [f["kind"] for f in flights] == ["envelope", "inside", "envelope"]
    kinds = s["by_kind"]
    assert list(kinds) == ["inside", "envelope"]
    assert [kinds[k]["flights"] for k in kinds] == [1, 2]
    assert kinds["inside"]["status_counts"] == flights[1]["status_counts"]
    assert sum(k["samples"] for k in kinds.values()) == t["samples"]
    assert max(k["longest_time_limit_run"] for k in kinds.values()) == t["longest_time_limit_run"]


def test_a_flight_flies_again_alone_and_as_the_reference(three_flights, tmp_path, capsys):
    """Flight 1 of --seed 7 is flight 0 of --seed 8, and the reference controller over the
    same reference, plant and noise has its OPTIMAL count and longest TIME_LIMIT run."""
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.reference.controller import ControllerRef
    from rollmpc_codegen.sim.flight_plan import FlightPlan
    from rollmpc_codegen.sim.simulate import run_closed_loop

    again, out = _flights(tmp_path, capsys, 1, 8, "again")
    one = dict(again["flights"][0], flight=1)
    assert one == three_flights["flights"][1]
    assert out.count("\n  flight ") == 1 and "all flights: optimal" in out

    model, ctx = load_model(QUAD, "float")
    plan = FlightPlan(flights=1, seed=8)
    ref = ControllerRef(ctx, [m.data for m in model.modes])
    log = run_closed_loop(model.config, ref, steps=STEPS,
                          **plan.loop_options(plan.plan(model.config, STEPS)[0]))
    statuses = log.status
    assert np.count_nonzero(statuses == OPTIMAL) == one["status_counts"]["optimal"]
    assert longest_run(statuses) == one["longest_time_limit_run"]


def test_time_limit_warning_names_a_run_that_outlasts_the_plan():
    """A TIME_LIMIT sample falls back to the last plan for horizon - 1 samples; a longer run
    is said, since the clamped unconstrained optimum after it ignores the output bounds."""
    counts = {"optimal": 900, "time_limit": 100}
    plain = time_limit_warning(counts, 1000, longest=29, horizon=30)
    long = time_limit_warning(counts, 1000, longest=30, horizon=30)
    assert "outlasted" not in plain
    assert "The longest run, 30 samples, outlasted the last plan (it covers 29)" in long
    assert time_limit_warning({"optimal": 5}, 5, longest=0, horizon=30) is None


def test_longest_run():
    assert longest_run([]) == 0
    assert longest_run([OPTIMAL, TIME_LIMIT, TIME_LIMIT, OPTIMAL, TIME_LIMIT]) == 2
    assert longest_run([TIME_LIMIT] * 3) == 3


@pytest.mark.parametrize("extra, word", [
    (["--flights", "-1"], "--flights"),
    (["--flights", "2", "--csv", "x.csv"], "--csv"),
    (["--flights", "2", "--plot", "x.png"], "--plot"),
    (["--flights", "2", "--baseline", "lqr"], "--baseline"),
])
def test_bad_flight_options_one_line_exit_2(extra, word, capsys, monkeypatch, tmp_path):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    monkeypatch.chdir(tmp_path)
    rc, out, err = run_cli(["simulate", str(QUAD), *extra], capsys)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("rollmpc: error: ") and word in err, err
    assert list(tmp_path.iterdir()) == []  # nothing written
