"""The sanity checks a control engineer runs by eye (docs/checks.md), on the two designs
of tests/data/newuser: a buck converter (YAML) and a drone's altitude loop (Python API).
A sample time in the wrong unit is a config error naming ``sample_time``; a sample time
the plant outruns, a horizon that sees a sliver of the closed loop, B scaled decades off
the bounds and an explicit work budget beyond the sample period are design warnings
naming the key to change; no example warns."""
from __future__ import annotations

import copy
import sys

import pytest
import yaml

from conftest import ROOT, config_error
from rollmpc_codegen.config import ConfigError, parse
from rollmpc_codegen.pipeline import build_model
from rollmpc_codegen.qp.sanity import design_warnings

NEWUSER = ROOT / "tests" / "data" / "newuser"
BUCK = yaml.safe_load((NEWUSER / "buck.yaml").read_text())
sys.path.insert(0, str(NEWUSER))
import drone_alt  # noqa: E402  (tests/data/newuser/drone_alt.py)


def buck(**top) -> dict:
    data = copy.deepcopy(BUCK)
    for key, value in top.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    return data


def warnings_of(data: dict) -> list:
    return design_warnings(build_model(parse(data)))


def codes(found) -> list[tuple[str, str]]:
    return [(w.code, w.key) for w in found]


@pytest.mark.parametrize("simulation", [BUCK["simulation"], None],
                         ids=["with-scenario", "without-scenario"])
def test_a_sample_time_in_microseconds_written_as_seconds_names_sample_time(simulation):
    """sample_time: 50 for 50 us was blamed on simulation.reference.segment, or without a
    scenario on a controllability pole (s = -1.511)."""
    exc = config_error(buck(sample_time=50, simulation=simulation), parse)
    assert exc.key == "sample_time"
    assert exc.problem == (
        "50 s is 3.37e+05 rad at the fastest pole of modes[0] (ccm: s = -378.8 ± 6731j, "
        "|s| Ts should be below about 3.14): the plant settles or turns many times within "
        "one sample; sample_time is in seconds; meant 5e-05 (50 us)?")


def test_a_drone_sampled_at_20_instead_of_20_ms_is_refused():
    """It generated, with only the nominal-loop warning ("lengthen the horizon")."""
    with pytest.raises(ConfigError) as exc:
        drone_alt.design(sample_time=20)
    assert exc.value.key == "sample_time" and exc.value.problem.endswith("meant 0.02 (20 ms)?")


def test_a_sample_time_the_resonance_outruns_warns():
    """The buck at Ts = 5 ms: omega0 Ts = 33.7 rad, accepted silently."""
    found = warnings_of(buck(sample_time=5e-3, simulation={"reference": {
        "levels": [0, 5], "segment": 0.5}}))
    assert codes(found) == [("sample_time_coarse", "sample_time")]
    assert found[0].message == (
        "sample_time 5 ms is 33.7 rad at the plant's fastest pole (modes[0] ccm: s = -378.8 "
        "± 6731j): it turns 5.4 times per sample, past the Nyquist frequency, so the "
        "controller can neither see nor act on that mode; sample at most 466 us (|s| Ts = "
        "pi), better ten times faster")


def test_a_horizon_far_shorter_than_the_closed_loop_warns():
    """Ts = 50 ns (a 50 us meant in a smaller unit): N Ts = 0.3 us, while the loop's
    slowest mode is the converter's own 2.6 ms."""
    found = warnings_of(buck(sample_time=5e-8, simulation={"reference": {
        "levels": [0, 5], "segment": 1e-6}}))
    assert codes(found) == [("horizon_short", "horizon")]
    assert "the plans see a sliver of the response" in found[0].message


def test_b_off_by_a_million_warns_on_the_output_it_cannot_move():
    """B in the wrong unit: the buck settled with an error equal to its reference."""
    data = buck(horizon=6)  # the figures below: what 6 samples of the wrong B move
    data["modes"][0]["plant"]["state_space"]["B"] = [[0.12], [0.0]]
    found = warnings_of(data)
    assert codes(found) == [("output_scale", "modes[0].plant")] * 2  # vout and iL
    assert "move iL by at most" in found[1].message
    assert found[0].message.startswith("modes[0] (ccm): the inputs within their bounds move "
                                       "vout by at most 1.61e-05 V, 2e-06 of the 8 V its "
                                       "bounds and references span")


def test_an_explicit_work_budget_beyond_the_sample_period_warns():
    """work_budget: 2000 at Ts = 50 us: 4.7 sample periods at 20 cycles per unit."""
    found = warnings_of(buck(solver={"work_budget": 2000}))
    assert codes(found) == [("work_budget_beyond_sample", "solver.work_budget")]
    assert found[0].message.startswith("solver.work_budget 2,000 units take at least 24,000 "
                                       "cycles (at the fewest 12 cycles per unit measured), "
                                       "2.9 sample periods of 8,400")
    assert found[0].message.endswith("use auto (solver.budget_share) or at most 700")


def test_the_designs_as_written_do_not_warn():
    assert warnings_of(BUCK) == []
    assert design_warnings(drone_alt.design().build()[0]) == []
