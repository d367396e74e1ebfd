"""What a config knows of its aircraft and what `rollmpc fly` makes of it, without flying:
the `aircraft` section (config/aircraft.py), the PID's tuning rule (flight/pid_tuning.py),
the MPC's delay margin on its own model (model/delay_margin.py) and the warning it gives,
the FCS kink through FGLinearization's stencil, and the transition time of the metrics."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from conftest import ROOT, config_error

from rollmpc_codegen.config import load, parse
from rollmpc_codegen.config.canonical import canonical_json

C172 = ROOT / "examples" / "c172_roll.yaml"


@pytest.fixture(scope="module")
def c172_data():
    return yaml.safe_load(C172.read_text())


@pytest.fixture(scope="module")
def c172_model():
    from rollmpc_codegen.pipeline import load_model

    return load_model(C172, "double")[0]


def test_the_example_records_its_aircraft_and_envelope():
    ac = load(C172).aircraft
    assert ac.name == "c172p" and ac.altitude_ft == 4000.0
    assert ac.airspeeds_kts == (70.0, 90.0, 110.0)  # the modes' order
    assert ac.aileron_travel_deg == pytest.approx((-19.996, 14.997), abs=1e-3)
    assert ac.aileron_rate_dps is None and ac.stall_alpha_deg == 16.0
    assert ac.latency_samples == 0 and ac.settings == ()
    assert load(C172).target.part == "stm32f427"  # the part its float image is sized for


def test_a_config_without_the_section_keeps_its_hash(c172_data):
    """The section is left out of the canonical text at its default (OMIT_AT_DEFAULT)."""
    data = dict(c172_data)
    data.pop("aircraft")
    without = parse(data)
    assert without.aircraft is None and '"aircraft"' not in canonical_json(without)
    assert '"aircraft"' in canonical_json(load(C172))


@pytest.mark.parametrize("edit,key", [
    (lambda a: a.update(airspeeds_kts=[70, 90]), "aircraft.airspeeds_kts"),
    (lambda a: a.update(aileron_travel_deg=[5, 10]), "aircraft.aileron_travel_deg"),
    (lambda a: a.update(settings=["gear"]), "aircraft.settings"),
    (lambda a: a.update(stall_alpha_deg=-3), "aircraft.stall_alpha_deg"),
    (lambda a: a.update(winspan=11), "aircraft.winspan"),
    (lambda a: a.pop("name"), "aircraft.name"),
])
def test_a_bad_aircraft_section_names_its_key(c172_data, edit, key):
    data = yaml.safe_load(yaml.safe_dump(c172_data))
    edit(data["aircraft"])
    assert config_error(data, parse).key == key


def test_the_pid_rule_gives_the_c172p_grid_optimum_back():
    from rollmpc_codegen.flight.pid_tuning import C172P_GRID, loop_margins, roll_plant, tune_pid

    cfg = load(C172)
    g = tune_pid(cfg)
    assert g.rule == "model" and g.back_offs == 0
    for key in ("time_constant_s", "feed_forward", "rate_p", "rate_i"):
        assert getattr(g, key) == pytest.approx(getattr(C172P_GRID, key), rel=0.02), key
    assert (g.trim_airspeed_kts, g.min_airspeed_kts) == (90.0, 70.0)  # the envelope's floor
    assert g.max_rate_dps == pytest.approx(14.99 / g.feed_forward, rel=1e-3)
    for pm, gm in loop_margins(*roll_plant(cfg, 1), g, cfg.sample_time):
        assert pm >= 45.0 and gm >= 6.0
    data = yaml.safe_load(C172.read_text())
    data.pop("aircraft")
    assert tune_pid(parse(data)) == C172P_GRID  # no model of the aircraft: the grid's


def test_delay_margin_of_the_example_and_the_warning(c172_model):
    """The 110 kts mode is stable with 4 samples of unmodelled delay, not 5 (docs/flight.md:
    the example limit-cycles at 5): fly is silent at 3, warns of ringing at 4 and of an
    oscillation at 5."""
    from rollmpc_codegen.flight.envelope import delay_warning
    from rollmpc_codegen.model.delay_margin import delay_margins, loop_radius

    assert delay_margins(c172_model) == [6, 5, 4]
    assert loop_radius(c172_model, 2, 4) < 1.0 < loop_radius(c172_model, 2, 5)
    cfg = c172_model.config
    assert delay_warning(cfg, [6, 5, 4], 3) is None
    at = delay_warning(cfg, [6, 5, 4], 4)  # stable, barely damped: it rings
    assert at.code == "delay_at_margin" and "kts110" in at.message and "ring" in at.message
    w = delay_warning(cfg, [6, 5, 4], 5)
    assert w.code == "delay_beyond_margin" and "kts110" in w.message and "--latency 5" in w.message


def test_the_stencil_sees_the_fcs_kink_as_fglinearization_does():
    """Away from 0 a side's slope; at 0 the mean of the two (a symmetric aileron: no kink)."""
    from rollmpc_codegen.flight.identify import STEP, stencil_slope

    class Fcs:
        def __init__(self, lo, hi):
            self.lo, self.hi = lo, hi

        def aileron_deg(self, c):
            return c * self.hi if c >= 0 else -c * self.lo

    c172, t37 = Fcs(-20.0, 15.0), Fcs(-20.05, 20.05)
    assert stencil_slope(c172, 0.04) == pytest.approx(15.0)
    assert stencil_slope(c172, -0.04) == pytest.approx(20.0)
    assert stencil_slope(c172, 0.0) == pytest.approx(17.5)
    assert stencil_slope(t37, 0.0) == pytest.approx(20.05)
    # straddling with one point of four: (8 (30h - 0) - (45h - (-20h))) / 12h, which a
    # higher-order stencil puts outside both slopes
    assert stencil_slope(c172, STEP) == pytest.approx(175.0 / 12.0)


def test_transition_time_starts_when_the_roll_leaves_the_old_level():
    """An MPC that starts before the step (the preview) is timed from its start, as a PID
    starting at the step is: both move 0 -> 10 deg in the same 0.5 s."""
    from rollmpc_codegen.flight.metrics import settling_time, transition_time

    ts, step_at = 0.01, 100
    ramp = np.clip(np.arange(300) / 50.0, 0, 1) * 10.0  # 0 to 10 deg in 0.5 s
    late = np.concatenate([np.zeros(step_at), ramp[:200]])  # starts at the step
    early = np.concatenate([np.zeros(step_at - 30), ramp[:230]])  # starts 0.3 s before
    assert transition_time(late, 0.0, 10.0, step_at, ts) == transition_time(
        early, 0.0, 10.0, step_at, ts) == pytest.approx(0.4)
    assert settling_time(early[step_at:] - 10.0, 10.0, ts) < settling_time(
        late[step_at:] - 10.0, 10.0, ts)
    assert transition_time(np.full(50, 3.0), 0.0, 10.0, 10, ts) is None  # never arrives


def test_weights_follow_the_aircraft_s_aileron_power():
    from rollmpc_codegen.flight.identify import OBSERVER, WEIGHTS, LateralModel, weights_for

    def mode(l_da):
        return LateralModel(trim=None, A=np.zeros((5, 5)), B=np.array([[0], [l_da], [0], [0], [0.0]]))

    assert weights_for(mode(25.6)) == (WEIGHTS, OBSERVER)  # the c172p's own
    weights, observer = weights_for(mode(12.82))  # half the roll acceleration per degree
    assert weights["R"] == pytest.approx(WEIGHTS["R"] / 4, rel=0.02)
    assert observer["Qd"] == pytest.approx(OBSERVER["Qd"] * 4, rel=0.02)
    assert weights["Q"] == WEIGHTS["Q"] and observer["Rn"] == OBSERVER["Rn"]
