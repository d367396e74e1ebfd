"""What the work budget costs in hard bounds (sim/budget_cost.py, ``rollmpc simulate
--flights K --against-unbudgeted``): each flight flown again without a budget, the
bounds the budget lost named per flight and warned about, and nothing named on a design
the budget never stops."""
from __future__ import annotations

import json

import pytest

from conftest import ROOT
from rollmpc_codegen.sim.budget_cost import LOST_RATIO, bounds_lost
from rollmpc_codegen.sim.flights_run import run_flights
from test_simulate_cli import run_cli

PMSM = ROOT / "tests" / "data" / "heavy" / "pmsm_speed.yaml"


def test_a_bound_is_lost_only_beyond_the_unbudgeted_excursion():
    tol = 1e-4
    assert bounds_lost({"iq": 4.6, "id": 0.2}, {"iq": 1.76, "id": 0.2}, tol) == {"iq": [4.6, 1.76]}
    assert bounds_lost({"iq": 2.0 * (1 + LOST_RATIO / 2)}, {"iq": 2.0}, tol) == {}  # the same
    assert bounds_lost({"roll": 5e-5}, {}, tol) == {}  # within the tolerance
    assert bounds_lost({}, {"roll": 3.0}, tol) == {}  # the budget kept it better


def test_the_motor_loses_its_current_bound_to_the_budget(tmp_path):
    """pmsm_speed at its budget: TIME_LIMIT runs after the speed steps let the q current
    (a constrained signal) past its 10 A further than the unbudgeted loop on the same
    flights (measured: 2 of 2, iq 10.4 against 3.15 A on seed 100)."""
    s = run_flights(PMSM, flights=2, seed=100, precision="float", noise_std=0.05,
                    mismatch=0.2, against_unbudgeted=True, build_dir=tmp_path).summary
    for f in s["flights"]:
        free = f["unbudgeted"]
        assert free["status_counts"] == {"optimal": f["samples"]}  # no budget: no stop
        assert f["status_counts"].get("time_limit", 0) > 0
    lost = [f["bounds_lost_to_budget"] for f in s["flights"] if f["bounds_lost_to_budget"]]
    assert lost and all(v > u for b in lost for v, u in b.values())
    assert s["totals"]["against_unbudgeted"]["flights_losing_bounds"] == len(lost)
    (w,) = [c for c in s["checks"] if c["code"] == "bound_lost_to_budget"]
    assert w["key"] == "solver.budget_share" and f"on {len(lost)} of 2 flights" in w["message"]


def test_a_design_the_budget_never_stops_loses_nothing(tmp_path, capsys):
    path = tmp_path / "drives.json"
    rc, out, err = run_cli(["simulate", str(ROOT / "examples" / "three_drives.yaml"),
                            "--flights", "2", "--steps", "200", "--against-unbudgeted",
                            "--quiet", "--json", str(path)], capsys)
    assert rc == 0, err
    s = json.loads(path.read_text())
    assert all(f["bounds_lost_to_budget"] == {} for f in s["flights"])
    assert "bound_lost_to_budget" not in {c["code"] for c in s["checks"]}
    assert "the budget lost one on 0" in out and "unbudgeted: violations" in out


@pytest.mark.parametrize("argv", [["--against-unbudgeted"]])
def test_it_needs_flights(capsys, argv):
    rc, out, err = run_cli(["simulate", str(PMSM), *argv], capsys)
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "--against-unbudgeted" in err and "--flights" in err
