"""Any number of modes -- k bands of the scheduling signal with hysteresis
(eq. 3 generalised), on examples/three_drives.yaml (3 modes, 5 bands).

The rule (docs/features.md): the mode becomes band b's mode only when the signal is
inside band b by more than the margin of each of its thresholds; within a margin the
current mode is kept.  Tested here: one-line config errors naming the key; the rule
itself against an independent per-band implementation and, for the two-mode shorthand,
against eq. (3) as printed; the shorthand and its bands form give identical generated C;
P_step bit for bit against the reference over the closed loop (every threshold crossed
both ways, chatter inside the margins) and over a synthetic sweep that hits every margin
edge exactly; every mode engaged with the constraints held; the double QP solutions of
every mode within 1e-8 of DAQP and of exact_qp.solve_exact; strict compilation;
`rollmpc simulate` and `rollmpc bench` on the example.
"""
from __future__ import annotations

import contextlib
import copy
import io
import json
import math

import numpy as np
import pytest
import yaml

from compile_flags import AUTOPILOT, CLANG_HINT, STRICT, compile_objects
from conftest import ROOT, UAV, Built, config_error, require_tool
from lockstep import Lockstep
from rollmpc_codegen.reference.scheduler import scheduled_mode
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.config import parse
from rollmpc_codegen.codegen.context import build_context
from rollmpc_codegen.model.controller import ControllerModel
from rollmpc_codegen.pipeline import build_model
from rollmpc_codegen.qp.exact import qp_data, solve_exact
from rollmpc_codegen.pipeline import generate
from rollmpc_codegen.qp.peers import DaqpPeer
from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.sim.scenario import preview, scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import OPTIMAL

DRIVES = ROOT / "examples" / "three_drives.yaml"
BASE = yaml.safe_load(DRIVES.read_text())


# --------------------------------------------------------------------------- the rule
def expected_mode(current: int, s: float, sc, dtype=np.float64) -> int:
    """The documented rule written per band (independent of band_scheduler's loop):
    band b's mode when t_{b-1} + eps_{b-1} < s < t_b - eps_b (margins rounded to the
    storage precision as the C stores them), else the current mode."""
    lo = [-math.inf] + [dtype(t + e) for t, e in zip(sc.thresholds, sc.epsilons)]
    hi = [dtype(t - e) for t, e in zip(sc.thresholds, sc.epsilons)] + [math.inf]
    firm = [b for b in range(len(sc.band_modes)) if lo[b] < s < hi[b]]
    assert len(firm) <= 1
    return sc.band_modes[firm[0]] if firm else current


def eq3_mode(current: int, rho: float, lower, upper, eps, inside, outside) -> int:
    """Eq. (3) of the paper as printed."""
    if rho < lower - eps or upper + eps < rho:
        return outside
    if lower + eps < rho < upper - eps:
        return inside
    return current


def sweep_signal(sc) -> np.ndarray:
    """Up and down through every band, then at every threshold: the exact margin edges,
    the threshold itself, the next numbers beyond the edges, and chatter inside the
    margin, approached from both sides."""
    lo, hi = sc.thresholds[0] - 5.0, sc.thresholds[-1] + 5.0
    ramp = np.linspace(lo, hi, 301)
    parts = [ramp, ramp[::-1]]
    for t, e in zip(sc.thresholds, sc.epsilons):
        below, above = t - e, t + e
        edges = [below, t, above, np.nextafter(above, np.inf), above, t,
                 below, np.nextafter(below, -np.inf), below]
        chatter = t + 0.8 * e * np.sin(np.arange(24) * 1.3)
        for start in (lo, hi):
            parts += [[start], chatter, edges, chatter[::-1], [start]]
    return np.concatenate([np.asarray(p, float) for p in parts])


def test_rule_matches_independent_per_band_form():
    sc = parse(copy.deepcopy(BASE)).scheduler
    ctx_sc = {"below": sc.below, "above": sc.above, "band_modes": sc.band_modes}
    s_all = np.concatenate([sweep_signal(sc), np.random.default_rng(1).uniform(-8, 8, 4000)])
    mode = got = sc.initial
    kept = 0
    for s in s_all:
        mode = expected_mode(mode, s, sc)
        new = scheduled_mode(got, s, ctx_sc["below"], ctx_sc["above"], ctx_sc["band_modes"])
        kept += new == got and new != sc.band_modes[sc.band_of(s)]
        got = new
        assert got == mode, s
    assert set(np.unique([sc.band_modes[sc.band_of(s)] for s in s_all])) == {0, 1, 2}
    assert kept > 50  # the hysteresis held a mode outside its own band


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_shorthand_is_eq3(dtype):
    """The UAV's lower/upper/inside/outside is the bands (outer, inner, outer): the mode
    sequence equals eq. (3) as printed, with the thresholds rounded as the C stores them."""
    d = yaml.safe_load(UAV.read_text())
    raw = d["scheduler"]
    sc = parse(d).scheduler
    assert sc.thresholds == (-16.0, 16.0) and sc.epsilons == (0.5, 0.5)
    assert sc.band_modes == (1, 0, 1) and sc.initial == 0
    below = [dtype(v) for v in sc.below]
    above = [dtype(v) for v in sc.above]
    rng = np.random.default_rng(2)
    signal = np.concatenate([rng.uniform(-20, 20, 3000), rng.normal(16, 0.6, 1000),
                             rng.normal(-16, 0.6, 1000), [-16.5, -15.5, 15.5, 16.5, -16, 16]])
    mode_eq3 = mode = sc.initial
    lower, upper, eps = dtype(raw["lower"]), dtype(raw["upper"]), dtype(raw["epsilon"])
    for rho in signal.astype(dtype):
        mode_eq3 = eq3_mode(mode_eq3, rho, lower, upper, eps, 0, 1)
        mode = scheduled_mode(mode, rho, below, above, sc.band_modes)
        assert mode == mode_eq3, rho


def test_shorthand_and_bands_form_generate_identical_c():
    """The UAV written with bands renders exactly the same files (same config hash since
    both are parsed from data, without the YAML text)."""
    d = yaml.safe_load(UAV.read_text())
    bands = copy.deepcopy(d)
    bands["scheduler"] = {"signal": "roll_rate", "epsilon": 0.5, "initial": "inner",
                          "bands": [{"mode": "outer", "below": -16}, {"mode": "inner", "below": 16},
                                    {"mode": "outer"}]}
    cfg_a, cfg_b = parse(d), parse(bands)
    assert cfg_a.scheduler == cfg_b.scheduler
    model = build_model(cfg_a)
    files_a = render_sources(build_context(model))
    files_b = render_sources(build_context(ControllerModel(config=cfg_b, modes=model.modes)))
    assert files_a == files_b


def test_default_initial_is_the_band_of_zero():
    d = copy.deepcopy(BASE)
    del d["scheduler"]["initial"]
    assert parse(d).scheduler.initial == 0  # fine: -1.5 <= 0 < 1.5
    d["scheduler"]["bands"][2]["below"] = 0  # 0 is now the first value of band 3 (medium)
    assert parse(d).scheduler.initial == 1


# --------------------------------------------------------------------------- config errors
def _bands(*items):
    def mutate(d):
        d["scheduler"]["bands"] = [dict(zip(("mode", "below"), it)) if it[-1] is not None
                                   else {"mode": it[0]} for it in items]
    return mutate


def _set(path, value):
    def mutate(d):
        node = d["scheduler"]
        *parents, last = path
        for p in parents:
            node = node[p]
        node[last] = value
    return mutate


def _delete(path):
    def mutate(d):
        node = d["scheduler"]
        *parents, last = path
        for p in parents:
            node = node[p]
        del node[last]
    return mutate


ERRORS = [
    pytest.param(_set(("bands", 3, "below"), -2), "scheduler.bands[3].below", "increase",
                 id="thresholds-not-increasing"),
    pytest.param(_set(("epsilon",), 2.0), "scheduler.epsilon", "too big",
                 id="epsilon-too-big-for-a-band"),
    pytest.param(_set(("bands", 2, "epsilon"), 3.5), "scheduler.bands[2].epsilon", "too big",
                 id="per-threshold-epsilon-too-big"),
    pytest.param(_set(("bands", 1, "epsilon"), -0.1), "scheduler.bands[1].epsilon", ">= 0",
                 id="negative-epsilon"),
    pytest.param(_set(("bands", 1, "mode"), "turbo"), "scheduler.bands[1].mode",
                 "unknown mode", id="unknown-mode"),
    pytest.param(_bands(("fine", 0), ("coarse", None)), "scheduler.bands",
                 "'medium' (modes[1]) serves no band", id="mode-never-used"),
    pytest.param(_bands(("fine", 0), ("fine", None)), "scheduler.bands", "same mode",
                 id="one-mode-only"),
    pytest.param(_bands(("coarse", -5), ("coarse", -1.5), ("fine", 1.5), ("medium", None)),
                 "scheduler.bands[1].mode", "merge", id="adjacent-bands-same-mode"),
    pytest.param(_bands(("fine", None)), "scheduler.bands", "at least two", id="one-band"),
    pytest.param(_set(("bands",), {"mode": "fine"}), "scheduler.bands", "at least two",
                 id="bands-not-a-list"),
    pytest.param(_delete(("bands", 1, "below")), "scheduler.bands[1].below", "missing",
                 id="missing-below"),
    pytest.param(_set(("bands", 4, "below"), 9), "scheduler.bands[4].below", "unbounded",
                 id="below-on-last-band"),
    pytest.param(_set(("bands", 4, "epsilon"), 0.1), "scheduler.bands[4].epsilon",
                 "no threshold", id="epsilon-on-last-band"),
    pytest.param(_set(("bands", 0, "above"), 1), "scheduler.bands[0].above", "unknown key",
                 id="unknown-band-key"),
    pytest.param(_set(("lower",), -1), "scheduler.lower", "not both", id="bands-and-shorthand"),
    pytest.param(_delete(("bands",)), "scheduler.bands", "missing", id="no-bands"),
    pytest.param(_set(("initial",), "turbo"), "scheduler.initial", "unknown mode",
                 id="unknown-initial"),
    pytest.param(_set(("bands", 1, "below"), float("nan")), "scheduler.bands[1].below",
                 "finite", id="threshold-nan"),
]


@pytest.mark.parametrize("mutate, key, text", ERRORS)
def test_config_error_names_the_key(mutate, key, text):
    d = copy.deepcopy(BASE)
    mutate(d)
    err = config_error(d, parse)
    assert err.key == key and text in err.problem, str(err)
    assert "\n" not in str(err)


def test_bands_empty_in_float_precision():
    """Distinct in double, one number in float: the middle band would never be chosen."""
    d = copy.deepcopy(BASE)
    d["precision"] = "float"
    d["scheduler"]["epsilon"] = 0.0
    d["scheduler"]["bands"] = [{"mode": "fine", "below": 1.0},
                               {"mode": "medium", "below": 1.00000001}, {"mode": "coarse"}]
    err = config_error(d, parse)
    assert err.key == "scheduler" and "float" in err.problem
    d["precision"] = "double"
    assert parse(d).scheduler.thresholds == (1.0, 1.00000001)


def test_cli_error_is_one_line_exit_2(tmp_path, capsys):
    d = copy.deepcopy(BASE)
    d["scheduler"]["bands"][3]["below"] = -2
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(d))
    rc = main(["generate", str(path), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 2 and not (tmp_path / "out").exists()
    assert err.count("\n") == 1 and err.startswith("rollmpc: error: scheduler.bands[3].below")


# --------------------------------------------------------------------------- the C
@pytest.fixture(scope="module")
def drives(build_root) -> Built:
    return Built(DRIVES, "double", build_root)


@pytest.fixture(scope="module")
def scenario(drives):
    lock = Lockstep(drives)
    log = run_closed_loop(drives.model.config, lock, info=lock.info)
    return lock, log


@pytest.fixture(scope="module")
def noisy(drives):
    """The scenario with noise on the measured position and speed: chatter at the
    thresholds."""
    lock = Lockstep(drives)
    log = run_closed_loop(drives.model.config, lock, info=lock.info, noise_std=0.2, seed=3)
    return lock, log


def _mode_sequence_follows_rule(log, sc, initial, dtype=np.float64):
    mode = initial
    for k, s in enumerate(log.sched[:, 0].astype(dtype)):
        mode = expected_mode(mode, s, sc, dtype)
        assert log.mode[k] == mode, k


@pytest.mark.parametrize("run", ["scenario", "noisy"])
def test_step_bit_exact_and_every_threshold_crossed(drives, run, request):
    lock, log = request.getfixturevalue(run)
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    sc = drives.model.config.scheduler
    _mode_sequence_follows_rule(log, sc, sc.initial)
    s = log.sched[:, 0]
    held = 0
    for i, (t, e) in enumerate(zip(sc.thresholds, sc.epsilons)):
        lower_mode, upper_mode = sc.band_modes[i], sc.band_modes[i + 1]
        prev, cur = log.mode[:-1], log.mode[1:]
        # a switch across threshold i, in each direction
        assert np.any((prev == lower_mode) & (cur == upper_mode) & (s[1:] > t + e)), t
        assert np.any((prev == upper_mode) & (cur == lower_mode) & (s[1:] < t - e)), t
        # the signal crossed the threshold inside its margin without a switch
        inside = (np.abs(s[:-1] - t) <= e) & (np.abs(s[1:] - t) <= e)
        crossed = np.sign(s[:-1] - t) != np.sign(s[1:] - t)
        held += np.count_nonzero(inside & crossed & (prev == cur))
    assert held >= (4 if run == "scenario" else 10)


def test_noise_makes_the_margins_chatter(noisy, scenario):
    _, log_n = noisy
    _, log_s = scenario
    switches = [np.count_nonzero(np.diff(lg.mode)) for lg in (log_s, log_n)]
    assert switches[1] > switches[0] >= 16  # >= 4 per large step: up to coarse and back


def test_closed_loop_every_mode_engaged_constraints_held(drives, scenario):
    _, log = scenario
    cfg = drives.model.config
    assert np.all(log.status == OPTIMAL)
    counts = np.bincount(log.mode, minlength=3)
    assert np.all(counts >= 40), counts
    for j, mode in enumerate(cfg.modes):
        a = cfg.actuators.index(mode.actuators[0])
        active = log.mode == j
        assert np.all(log.u[~active, a] == 0)  # an inactive drive gets 0
        assert np.all(np.abs(log.u[active, a]) <= 1.0)
        assert np.any(np.abs(log.u[active, a]) == 1.0)  # every drive saturates
    assert np.all(np.abs(log.y) <= 10.0) and np.abs(log.y).max() > 7.9
    for k in (170, 270, 370, 470, 570):  # settled before the preview sees the next step
        assert abs(log.y[k, 0] - log.r[k, 0]) < 0.1, k


def test_float_step_bit_exact(build_root):
    drives_f = Built(DRIVES, "float", build_root)
    lock = Lockstep(drives_f)
    log = run_closed_loop(drives_f.model.config, lock, info=lock.info, noise_std=0.2, seed=3)
    assert lock.mismatches == [], lock.mismatches[0]
    sc = drives_f.model.config.scheduler
    _mode_sequence_follows_rule(log, sc, sc.initial, np.float32)
    assert set(np.unique(log.mode)) == {0, 1, 2}


def test_sweep_hits_every_margin_edge(drives):
    """P_step with a synthetic scheduling signal (y = r = 0): ramps through all bands and,
    at every threshold, its exact margin edges and chatter inside the margin."""
    sc = drives.model.config.scheduler
    c, ref = drives.fresh_c(), drives.reference()
    N = drives.ctx["horizon"]
    y, r = np.zeros(1), np.zeros(N)
    mode = sc.initial
    modes = []
    for s in sweep_signal(sc):
        st_c, u_c = c.step(y, [s], r)
        st_r, u_r = ref.step(y, [s], r)
        mode = expected_mode(mode, s, sc)
        assert c.info()["mode"] == ref.mode == mode, s
        assert st_c == st_r == OPTIMAL and u_c.tobytes() == u_r.tobytes()
        modes.append(mode)
    assert c.info()["mode_switches"] == ref.mode_switches == np.count_nonzero(
        np.diff([sc.initial] + modes))
    assert set(modes) == {0, 1, 2}


def test_double_qps_of_every_mode_match_independent_solvers(drives, scenario):
    pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    lock, _ = scenario
    cfg = drives.model.config
    ref = scenario_reference(cfg)
    N = drives.ctx["horizon"]
    rng = np.random.default_rng(4)
    c = drives.fresh_c()
    peer = DaqpPeer([mm.qp for mm in drives.model.modes])
    worst_daqp = worst_exact = 0.0
    saturated = 0
    for j, mm in enumerate(drives.model.modes):
        states = [(x, k) for mode, x, k in lock.states if mode == j]
        picks = rng.choice(len(states), 8, replace=False)
        solver = SolverRef(mm.data, drives.ctx["solver"])
        for p in sorted(picks):
            x, k = states[p]
            for r in (preview(ref, k, N), preview(ref, k, N) + rng.uniform(-6, 6, N)):
                st_c, U_c, its_c = c.solve_qp(j, x, r)
                st_r, U_r, its_r, _, _ = solver.solve_mode(x, r)
                assert st_c == st_r == OPTIMAL and U_c.tobytes() == U_r.tobytes()
                assert its_c == its_r
                peer_result = peer.solve(j, x, r)
                assert peer_result.status == "optimal"
                exact = solve_exact(qp_data(mm.qp, x, r))
                worst_daqp = max(worst_daqp, np.abs(U_c - peer_result.U).max())
                worst_exact = max(worst_exact, np.abs(U_c - np.asarray(exact.U, float)).max())
                saturated += bool(np.any(np.abs(U_c) == 1.0))
    assert saturated >= 12
    assert worst_daqp <= 1e-8, worst_daqp
    assert worst_exact <= 1e-8, worst_exact


# --------------------------------------------------------------------------- build + CLI
@pytest.mark.parametrize("precision", [pytest.param("double", marks=pytest.mark.slow), "float"])
def test_generates_and_compiles_strict(tmp_path, precision):
    _, ctx = generate(DRIVES, tmp_path / "drives", precision)
    assert ctx["n_modes"] == 3 and ctx["scheduler"]["n_bands"] == 5
    assert ctx["scheduler"]["band_modes"] == [2, 1, 0, 1, 2]
    text = (tmp_path / "drives" / "drives_controller.c").read_text()
    assert "sched_mode[DRIVES_N_SCHED_BANDS]" in text
    ccs = ["gcc"] + ([require_tool("clang", CLANG_HINT)] if precision == "double" else [])
    for cc in ccs:
        proc = compile_objects(cc, tmp_path / "drives", ["-O2", "-ffp-contract=off", *STRICT,
                                                         *AUTOPILOT], tmp_path / f"obj-{cc[-5:]}")
        assert proc.returncode == 0 and not proc.stderr.strip(), proc.stderr


def _cli(args: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(args)
    return rc, out.getvalue(), err.getvalue()


def test_simulate_cli_engages_every_mode(tmp_path, build_root):
    rc, out, err = _cli(["simulate", str(DRIVES), "--quiet", "--json", str(tmp_path / "s.json"),
                         "--build-dir", str(build_root)])
    assert rc == 0, err
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["samples"] == 600 and summary["switches"] >= 16
    assert all(summary["by_mode"][m]["samples"] >= 40 for m in ("fine", "medium", "coarse"))
    assert summary["constraint_violations"]["total"] == 0 and summary["non_optimal"] == 0


def test_bench_cli_on_three_modes(tmp_path, build_root):
    pytest.importorskip("quadprog", reason="install with: pip install 'rollmpc-codegen[peers]'")
    pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    rc, out, err = _cli(["bench", str(DRIVES), "--quiet", "--max-qps", "60",
                         "--variants", "default,daqp",
                         "--json", str(tmp_path / "b.json"), "--build-dir", str(build_root)])
    assert rc == 0, err
    result = json.loads((tmp_path / "b.json").read_text())
    assert result["qps"] == 60 and set(result["qps_by_mode"]) == {"fine", "medium", "coarse"}
    rows = {r["key"]: r for r in result["rows"]}
    assert rows["default"]["optimal"] == 60 and rows["default"]["max_abs_err"] <= 1e-8
