"""`rollmpc identify` on the airframes of the jsbsim wheel a user brings (docs/flight.md,
"Other aircraft"): the aileron's travel at steady state through a lagging actuator (the
f15's), a trim at exactly 0 aileron on a symmetric travel (the T37's), the refusals that
say why (an engine the trim stops, an unknown property), and the five classes of
docs/flight.md's table 3 identified (slow)."""
from __future__ import annotations

import pytest
import yaml

from conftest import cli

from rollmpc_codegen.extras import installed

pytestmark = pytest.mark.skipif(
    not installed("jsbsim"), reason="jsbsim is missing; install with: pip install "
    "'rollmpc-codegen[flight]'")


def test_travel_is_measured_at_steady_state_through_the_actuator():
    """The f15's kinematic actuator takes 0.3 s end to end: one step moved it 1.1 deg of 20
    (identify refused it); held until it stops, the travel is +-20 deg at 222 deg/s."""
    from rollmpc_codegen.flight.aircraft import Aircraft

    f15 = Aircraft("f15", 0.005)
    assert f15.travel.travel_deg == pytest.approx((-19.996, 19.996), abs=1e-3)
    assert f15.travel.rate_dps == pytest.approx(222.2, abs=1.0)
    assert 0.1 < f15.travel.settle_s < 0.3
    c172 = Aircraft("c172p", 0.005)
    assert c172.travel.rate_dps is None and c172.travel.settle_s == 0.005  # no actuator


def test_a_trim_at_zero_aileron_on_a_symmetric_travel_is_identified(tmp_path):
    """The T37 trims at exactly 0 aileron (identify refused it as 'too close to the
    kink'); its travel is symmetric, so there is no kink, and the model predicts the
    doublet within 5 % of its peak."""
    out = tmp_path / "t37.yaml"
    rc, stdout, stderr = cli(["identify", "--aircraft", "T37", "--airspeed", "175",
                              "--altitude", "10000", "-o", str(out), "-q"])
    assert rc == 0, stderr
    data = yaml.safe_load(out.read_text())
    assert data["prefix"] == "t37_roll" and data["target"] == {"part": "stm32f427"}
    ac = data["aircraft"]
    assert ac["name"] == "T37" and ac["airspeeds_kts"] == [175.0]
    assert ac["aileron_travel_deg"][0] == pytest.approx(-ac["aileron_travel_deg"][1])
    assert 10 < ac["stall_alpha_deg"] < 20
    b = data["modes"][0]["plant"]["state_space"]["B"]
    assert b[1][0] > 0  # a positive aileron rolls right
    assert "doublet_poor" not in stderr and "delay margin" in stdout


@pytest.mark.parametrize("args,words", [
    (["--aircraft", "c310", "--airspeed", "107", "--altitude", "1000", "--gear", "up"],
     ["cannot trim c310", "engines stopped in the trim"]),
    (["--aircraft", "c172p", "--airspeed", "90", "--set", "fcs/no-such-lever=1"],
     ["--set", "no JSBSim property 'fcs/no-such-lever'"]),
    (["--aircraft", "c172p", "--airspeed", "90", "--set", "gear"], ["--set", "PROPERTY=NUMBER"]),
    (["--aircraft", "c172p", "--airspeed", "20"], ["cannot trim c172p at 20 kts"]),
    (["--aircraft", "T38", "--airspeed", "300"], ["T38", "0 .. 0 deg"]),
])
def test_what_cannot_be_identified_is_refused_in_one_line(tmp_path, args, words):
    out = tmp_path / "x.yaml"
    rc, _, stderr = cli(["identify", *args, "-o", str(out), "-q"])
    assert rc == 2 and stderr.count("\n") == 1 and not out.exists(), stderr
    assert all(w in stderr for w in words), stderr


def test_settings_reach_the_trim_and_the_config(tmp_path):
    """--gear/--flaps/--set are applied before the trim and written to the config, which
    `fly` applies again: flaps change the c172p's trim."""
    from rollmpc_codegen.flight.identify_config import identify_config

    plain = identify_config("c172p", [80.0], 4000.0)
    flaps = identify_config("c172p", [80.0], 4000.0, settings=[("fcs/flap-cmd-norm", 0.5)])
    assert flaps.aircraft.settings == (("fcs/flap-cmd-norm", 0.5),)
    assert flaps.models[0].trim.pitch_deg < plain.models[0].trim.pitch_deg - 1.0
    assert "--set fcs/flap-cmd-norm=0.5" in flaps.text.splitlines()[1]
    assert yaml.safe_load(flaps.text)["aircraft"]["settings"] == {"fcs/flap-cmd-norm": 0.5}


@pytest.mark.slow
def test_five_classes_are_identified():
    """docs/flight.md's table 3: each identifies, with its delay margins and no trim that
    stops an engine."""
    from rollmpc_codegen.flight.identify_config import identify_config
    from rollmpc_codegen.flight.matrix_aircraft import AIRCRAFT_CASES

    for case in AIRCRAFT_CASES:
        result = identify_config(case.aircraft, case.airspeeds_kts, case.altitude_ft,
                                 settings=case.settings)
        assert len(result.models) == len(case.airspeeds_kts)
        assert all(d is not None and d >= 3 for d in result.delay_margins), case.aircraft
        assert result.aircraft.stall_alpha_deg is not None
