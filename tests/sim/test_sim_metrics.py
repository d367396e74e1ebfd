"""`rollmpc simulate`'s metrics a new user met (sim/metrics.py), on designs of our own:
hard violations counted beyond the solver's feasibility tolerance, soft-bound excursions
apart from them, and settled errors whose window would contain the preview flagged and
left out of the max."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from rollmpc_codegen.config import load
from rollmpc_codegen.qp.work import UNBOUNDED_WORK
from rollmpc_codegen.sim.metrics import (constraint_violations, shortest_preview_free_segment,
                                         soft_bound_excursions, summarize)
from rollmpc_codegen.sim.simulate import ClosedLoopLog

from conftest import ROLL45, ROLL45_SOFT, cli

def _config(tmp_path, name="roll45", precision="double", soft=False, **top):
    data = json.loads(json.dumps(ROLL45))
    data.update(precision=precision, **top)
    if soft:
        data["modes"][0]["bounds"]["soft"] = ROLL45_SOFT
        # the metric, not the real-time cap: with the default work budget this design has
        # 705 TIME_LIMIT samples whose commands pass the soft bound by 15 deg
        data["solver"] = dict(data.get("solver") or {}, work_budget=UNBOUNDED_WORK)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _log(y, u=None, r=None) -> ClosedLoopLog:
    K = len(y)
    return ClosedLoopLog(t=np.arange(K) * 0.01,
                         r=np.zeros((K, 1)) if r is None else np.asarray(r, float)[:, None],
                         y=np.asarray(y, float)[:, None], sched=np.zeros((K, 0)),
                         u=np.zeros((K, 1)) if u is None else np.asarray(u, float)[:, None],
                         mode=np.zeros(K, int), status=np.zeros(K, int),
                         iterations=np.zeros(K, int), solve_us=np.zeros(K))


@pytest.mark.parametrize("precision, inside, outside", [
    ("double", 45 + 1.4e-14, 45 + 1e-6),  # tolerance 1e-9 * 45 = 4.5e-8 deg
    ("float", 45 + 4e-3, 45 + 5e-3),  # tolerance 1e-4 * 45 = 4.5e-3 deg
])
def test_hard_violations_beyond_the_feasibility_tolerance(tmp_path, precision, inside, outside):
    cfg = load(_config(tmp_path, precision=precision))
    assert cfg.feasibility_tol == (1e-9 if precision == "double" else 1e-4)
    y = [0.0, inside, -inside, outside, -outside, 44.0]
    u = [15.0, 15 + 1e-14 * (precision == "double"), -15.0, 0.0,
         15.0 * (1 + 2 * cfg.feasibility_tol), 0.0]
    cv = constraint_violations(cfg, _log(y, u))
    assert {k: cv[k] for k in ("u", "inactive_actuator_nonzero", "y", "total")} == {
        "u": 1, "inactive_actuator_nonzero": 0, "y": 2, "total": 3}
    assert cv["y_max_beyond"] == {"roll": pytest.approx(outside - 45, rel=1e-6)}
    assert constraint_violations(cfg, _log([0.0, inside]))["y_max_beyond"] == {}


def test_configured_tolerance_is_the_one_used(tmp_path):
    cfg = load(_config(tmp_path, solver={"feasibility_tol": 1e-3}))
    assert cfg.feasibility_tol == 1e-3
    assert constraint_violations(cfg, _log([45.04, 45.05]))["y"] == 1  # 1e-3 * 45 = 0.045


def test_soft_bound_excursions_are_not_violations(tmp_path):
    cfg = load(_config(tmp_path, soft=True))
    log = _log([0.0, 45 + 1e-12, 45.5, -45.25, 40.0])
    assert constraint_violations(cfg, log)["y"] == 0
    assert soft_bound_excursions(cfg, log) == {"samples_beyond": 2, "max_beyond": 0.5}
    hard = load(_config(tmp_path, name="hard"))
    assert constraint_violations(hard, log)["y"] == 2
    assert soft_bound_excursions(hard, log) == {"samples_beyond": 0, "max_beyond": 0.0}


def test_simulate_reports_soft_excursions_apart(tmp_path):
    """The closed loop of a soft 45 deg bound under a 60 deg reference: the roll passes
    the bound by a few thousandths of a degree, reported as soft-bound excursions; the
    old count (any y beyond a bound, no tolerance) called 291 samples violations."""
    code, out, err = cli(["simulate", str(_config(tmp_path, soft=True)), "--quiet", "--json",
                          str(tmp_path / "s.json")])
    assert code == 0, err
    s = json.loads((tmp_path / "s.json").read_text())
    assert s["constraint_violations"]["total"] == 0 and s["violation_tolerance"] == 1e-9
    sb = s["soft_bounds"]
    assert sb["samples_beyond"] > 100 and 1e-4 < sb["max_beyond"] < 0.05
    assert sb["samples_with_slack"] >= sb["samples_beyond"]
    assert "constraint violations: 0 (u 0, inactive 0, y 0; hard bounds, beyond 1e-09 " in out
    line = next(ln for ln in out.splitlines() if "soft output bounds" in ln)
    assert f"the output is beyond one in {sb['samples_beyond']} samples" in line


def test_simulate_warns_of_time_limited_samples(tmp_path):
    """The soft 45 deg design with the default work budget: samples stop at TIME_LIMIT,
    and simulate says how many and what it means; with no budget it is quiet."""
    path = _config(tmp_path, soft=True)
    data = yaml.safe_load(path.read_text())
    del data["solver"]  # the default budget: half of Ts at 168 MHz
    limited = tmp_path / "limited.yaml"
    limited.write_text(yaml.safe_dump(data, sort_keys=False))
    work = {}
    for config, expect in ((limited, True), (path, False)):
        code, out, err = cli(["simulate", str(config), "--quiet", "--json",
                              str(tmp_path / "s.json")])
        assert code == 0, err
        n = json.loads((tmp_path / "s.json").read_text())["status_counts"].get("time_limit", 0)
        assert (n > 0) == expect
        warned = [ln for ln in out.splitlines() if "stopped at the work budget (TIME_LIMIT)" in ln]
        assert len(warned) == int(expect)
        if expect:
            assert warned[0].strip().startswith(f"warning: {n} of ")
            assert f"non-optimal: {n} (time_limit {n});" in out  # named, not only counted
        work[expect] = json.loads((tmp_path / "s.json").read_text())["work"]
    # the work line says what the design needs: without a budget some samples need more
    # than the default one, which the budgeted run's samples never exceed
    assert work[True]["max"] <= work[True]["budget"] < work[False]["max"]


def test_short_segments_flag_the_settled_error(tmp_path):
    """Perfect tracking with a preview: y follows r exactly but starts each step N
    samples early (the MPC's anticipation).  A segment too short to end its settled
    window N samples before the next step reads the anticipation as error."""
    cfg = load(_config(tmp_path))  # N = 60
    need = shortest_preview_free_segment(cfg.horizon)
    assert need == 201  # [0.7 L, L - 60) is empty up to L = 200
    for length, short in ((150, True), (need, False)):
        r = np.repeat([0.0, 10.0, 20.0], length)
        y = np.concatenate([r[cfg.horizon:], np.full(cfg.horizon, 20.0)])  # anticipates
        s = summarize(cfg, _log(y, r=r))
        flags = [seg["settled_window_includes_preview"] for seg in s["segments"]]
        assert flags == [short, short, False]
        errors = [seg["settled_error"] for seg in s["segments"]]
        if short:
            assert errors[:2] == [10.0, 10.0] and s["max_settled_error"] == 0.0
            assert s["warnings"] == [
                "segments 0-1.5 s, 1.5-3 s shorter than the 2.01 s a settled window needs "
                "with N*Ts = 0.6 s of preview: the settled error there includes the "
                "anticipation of the next step and is left out of the max (lengthen "
                "simulation.reference.segment)"]
        else:
            assert errors == [0.0, 0.0, 0.0] and s["warnings"] == []


def test_simulate_warns_about_short_segments(tmp_path):
    path = _config(tmp_path, name="short", horizon=100,
                   simulation={"reference": {"segment": 1.5, "levels": [0, 10, 20, 10, 0]}})
    data = yaml.safe_load(path.read_text())
    del data["modes"][0]["bounds"]["y_min"], data["modes"][0]["bounds"]["y_max"]
    path.write_text(yaml.safe_dump(data))
    code, out, err = cli(["simulate", str(path), "--quiet"])
    assert code == 0, err
    settled = next(ln for ln in out.splitlines() if "settled |y - r|" in ln)
    values = settled.split(": ")[1].split(" (max ")[0].split(", ")
    assert [v.endswith("*") for v in values] == [True] * 4 + [False]
    assert min(float(v.rstrip("*")) for v in values[:4]) > 1.0  # the anticipation
    assert settled.endswith(f"(max {values[4]})")  # the max is the clean segment's
    assert "  warning: * segments 0-1.5 s, 1.5-3 s, 3-4.5 s, 4.5-6 s shorter than the " \
           "3.34 s a settled window needs" in out
