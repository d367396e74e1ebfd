"""The innovation limit: one huge but finite measurement must not wreck the controller.

The observers clip each innovation y - C x̂ to ``modes[].observer.innovation_limit``
(default: ten spans of the output's expected range, docs/features.md "Measurement
plausibility") and P_step reports MEASUREMENT_CLIPPED when its solve was OPTIMAL.
Checked: the defaults of every example and the explicit forms of the key; the C against
the NumPy reference bit for bit through spikes (P_step and P_observe, both precisions, the
limit switched off too); the precedence of a solver status; a single spike of 1e30, 1e308
(double) and 3.4e38 (float) in the closed loop of uav_roll, chain_of_masses and
quadruple_tank: reported at the spike, commands finite and within the limits, recovered
within the samples docs/reliability.md states; the emulated Cortex-M4F through spikes.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT, UAV, Built, config_error, edited_config, require_tool, short_uav_config
from rollmpc_codegen.config import load
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import MAX_ITER, MEASUREMENT_CLIPPED, OPTIMAL
from rollmpc_codegen.verify.spike_recovery import CASES, SPIKES, Spiked, spiked_runs

EXAMPLES = ROOT / "examples"
CHAIN = EXAMPLES / "chain_of_masses.yaml"


def _with_limit(tmp_path, base, limit, name="limit"):
    def edit(data):
        for m in data["modes"]:
            m.setdefault("observer", {})["innovation_limit"] = limit
    return edited_config(tmp_path, base, name, edit)


# --------------------------------------------------------------------------- config
@pytest.mark.parametrize("example, limits", [
    ("uav_roll", [5400.0]),  # bounds ±270 deg
    ("chain_of_masses", [12.0] * 6),  # ±0.6 m
    ("quadruple_tank", [170.0, 170.0]),  # [-10, 7] cm
    ("chain_runtime_bounds", [12.0] * 4 + [11.0, 10.0]),  # one side, then none: the levels
    ("c172_roll", [600.0]),  # unbounded: the scenario's levels ±30 deg
    ("quad_attitude", [600.0, 600.0, 150.0, 10.0]),  # yaw 0..15 deg, climb 0..1 m/s
    ("fw_lateral", [700.0, 180.0]),  # given (sideslip has no range to derive one from)
])
def test_default_limit_is_ten_spans_of_the_expected_range(example, limits):
    for mode in load(EXAMPLES / f"{example}.yaml").modes:
        np.testing.assert_allclose(mode.innovation_limit, limits, rtol=1e-15, atol=0)


@pytest.mark.parametrize("precision", ["double", "float"])
def test_inf_switches_the_clip_off_and_is_stored_finite(tmp_path, precision):
    from rollmpc_codegen.pipeline import load_model

    model, ctx = load_model(_with_limit(tmp_path, CHAIN, [1, 2, 3, 4, 5, np.inf]), precision)
    stored = model.modes[0].data.innovation_limit
    assert stored.dtype == model.dtype
    assert stored[:5].tolist() == [1, 2, 3, 4, 5]
    assert stored[5] == np.finfo(model.dtype).max  # the C literal stays finite
    assert ctx["modes"][0]["innovation_limit"] == stored.tolist()


def test_a_scalar_applies_to_every_output(tmp_path):
    mode = load(_with_limit(tmp_path, CHAIN, 0.25)).modes[0]
    assert mode.innovation_limit.tolist() == [0.25] * 6


def test_float_rejects_a_limit_it_cannot_store(tmp_path):
    err = config_error(_with_limit(tmp_path, UAV, 1e39),
                       lambda p: load(p, precision="float"))
    assert err.key == "modes[0].observer.innovation_limit" and "float" in str(err)


# --------------------------------------------------------------------------- C == NumPy
def _lockstep(built, spikes, steps):
    """P_step of the C and of the reference through the closed loop with ``spikes``;
    returns the C's log and (status, C's clipped, reference's clipped) per sample."""
    c = built.fresh_c()
    ref = built.reference()
    seen = []

    class Both:
        def step(self, y, s, r):
            st_c, u_c = c.step(y, s, r)
            st_r, u_r = ref.step(y, s, r)
            info = c.info()
            assert (st_c, u_c.tobytes(), info["iterations"]) == \
                (st_r, u_r.tobytes(), ref.last["iterations"]), (len(seen), st_c, st_r, u_c, u_r)
            seen.append((st_c, info["clipped"], ref.last["clipped"]))
            return st_c, u_c

    log = run_closed_loop(built.model.config, Spiked(Both(), spikes), steps=steps)
    return log, seen


def _assert_same_estimates(c, ref, ctx):
    """P_ctrl's xhat[N_MODES][NX_MAX] (its member after ``int mode``) equals the
    reference's estimates bit for bit."""
    dt = c.dtype
    nx_max = ctx["sizes"]["nx_max"]
    xhat = np.frombuffer(c.ffi.buffer(c.ctrl), dt, count=len(ref.xhat) * nx_max,
                         offset=max(4, np.dtype(dt).itemsize)).reshape(len(ref.xhat), nx_max)
    for j, x in enumerate(ref.xhat):
        assert xhat[j, :x.size].tobytes() == x.tobytes(), (j, xhat[j], x)


def _spikes(limit: float, precision: str) -> dict[int, float]:
    huge = 3.4e38 if precision == "float" else 1e308
    # far beyond, both signs; half a limit beyond it; half a limit inside (y is ~0 there)
    return {30: 1e30, 60: -huge, 90: huge, 120: 1.5 * limit, 150: -0.5 * limit}


@pytest.mark.parametrize("precision", [pytest.param("double", marks=pytest.mark.slow), "float"])
def test_step_bit_exact_through_spikes_uav(tmp_path, build_root, precision):
    built = Built(short_uav_config(tmp_path), precision, build_root)
    limit = float(built.model.modes[0].data.innovation_limit[0])
    spikes = _spikes(limit, precision)
    log, seen = _lockstep(built, spikes, 200)
    for k, (status, clipped_c, clipped_r) in enumerate(seen):
        assert clipped_c == clipped_r
        if k in spikes and k != 150:  # both observers clip; the solves were optimal
            assert (status, clipped_c) == (MEASUREMENT_CLIPPED, 2), k
        elif k < 30:
            assert (status, clipped_c) == (OPTIMAL, 0), k
    assert seen[150][1] == 0  # inside the limit: not clipped
    assert np.all(np.isfinite(log.u)) and np.all(np.abs(log.u) <= 15.0)


@pytest.mark.parametrize("precision", ["float", pytest.param("double", marks=pytest.mark.slow)])
def test_step_bit_exact_through_spikes_mimo(build_root, precision):
    built = Built(CHAIN, precision, build_root)
    spikes = _spikes(float(built.model.modes[0].data.innovation_limit[0]), precision)
    _, seen = _lockstep(built, spikes, 200)
    assert [clipped for _, clipped, _ in seen] == [clipped for _, _, clipped in seen]
    assert seen[30][:2] == (MEASUREMENT_CLIPPED, 1)
    # later spikes land while the estimate still recovers: a solver status may win
    assert all(seen[k][0] != OPTIMAL and seen[k][1] == 1 for k in (60, 90, 120))


def test_observe_bit_exact_with_the_clip_off(tmp_path, build_root):
    """With ``.inf`` the float build stores FLT_MAX: only an innovation that overflowed to
    ±inf is clipped (and reported), op for op as the reference."""
    built = Built(_with_limit(tmp_path, short_uav_config(tmp_path), np.inf, "off"), "float",
                  build_root)
    c, ref = built.fresh_c(), built.reference()
    u = np.zeros(2)
    statuses = []
    for y in (-3.4e38, 3.4e38, 3.4e38, 1.0):
        statuses.append(c.observe([y], [0.0], u))
        assert ref.observe([y], [0.0], u) == statuses[-1]
        _assert_same_estimates(c, ref, built.ctx)
    assert statuses[0] == OPTIMAL  # FLT_MAX from an estimate near 0: no overflow, no clip
    assert MEASUREMENT_CLIPPED in statuses[1:3]  # from the wrecked estimate it overflows


def test_solve_near_float_overflow_matches_the_reference(tmp_path, build_root):
    """Known failure 7 of docs/reliability.md, fixed by the dual factor updates.
    Found by this file: the float P_solve_qp of a state ~1e37 (the UAV's estimate after
    spikes of ±FLT_MAX with the clip off) says INFEASIBLE, the reference NUMERICAL; on
    main before the clip existed too."""
    from rollmpc_codegen.reference.solver import SolverRef

    built = Built(short_uav_config(tmp_path), "float", build_root)
    x = np.array([1.8468663e36, -6.8513433e35, -2.9638085e35, 1.4385534e37], np.float32)
    r = np.zeros(built.ctx["horizon"], np.float32)
    status_c, U_c, _ = built.fresh_c().solve_qp(0, x, r)
    with np.errstate(all="ignore"):
        status_r, U_r, *_ = SolverRef(built.model.modes[0].data, built.ctx["solver"]).solve_mode(x, r)
    assert status_c == status_r and U_c.tobytes() == U_r.tobytes()


def test_observe_reports_the_clip_bit_exact(build_root):
    """P_observe (another controller flies) clips the same way and says so."""
    built = Built(UAV, "double", build_root)
    c, ref = built.fresh_c(), built.reference()
    u = np.array([2.0, 0.0])
    for k, y in enumerate([0.5, 1e30, 0.7, -1e308, 0.9]):
        expected = MEASUREMENT_CLIPPED if abs(y) > 1e3 else OPTIMAL
        assert c.observe([y], [0.0], u) == ref.observe([y], [0.0], u) == expected, k
        assert c.info()["clipped"] == 0  # diagnostics are P_step's
        _assert_same_estimates(c, ref, built.ctx)
    r = np.zeros(built.ctx["horizon"])
    st_c, u_c = c.step([1.0], [0.0], r)  # the next solve starts from the same estimate
    st_r, u_r = ref.step([1.0], [0.0], r)
    assert st_c == st_r and u_c.tobytes() == u_r.tobytes()


def test_a_solver_status_wins_over_the_clip(tmp_path, build_root):
    """A sweep cap of 1 without polish: MAX_ITER on a -20 deg step. The clip of the same
    sample is counted in P_last_info()->clipped, the status stays the solver's."""
    cfg = short_uav_config(tmp_path, polish=False, max_iterations=1)
    built = Built(cfg, "double", build_root)
    c, ref = built.fresh_c(), built.reference()
    r = np.full(built.ctx["horizon"], -20.0)
    for y in (0.0, 1e30):
        st_c, u_c = c.step([y], [0.0], r)
        st_r, u_r = ref.step([y], [0.0], r)
        assert st_c == st_r == MAX_ITER and u_c.tobytes() == u_r.tobytes()
        assert c.info()["clipped"] == ref.last["clipped"] == (2 if y else 0)
        assert c.info()["status"] == MAX_ITER


# --------------------------------------------------------------------------- closed loop
# samples from the spike until every status is OPTIMAL and every command within 1e-3 of the
# input span of the spike-free run, and samples after the spike that are not OPTIMAL:
# measured (`python -m rollmpc_codegen.verify --only spikes`), stated in
# docs/reliability.md section 11 and the README
RECOVERY = {"uav_roll": (284, 16), "chain_of_masses": (82, 33), "quadruple_tank": (47, 6)}
MODES = {"uav_roll": 2, "chain_of_masses": 1, "quadruple_tank": 1}


@pytest.mark.parametrize("precision", ["float", pytest.param("double", marks=pytest.mark.slow)])
@pytest.mark.parametrize("name, at, steps", CASES, ids=[c[0] for c in CASES])
def test_single_spike_is_reported_and_recovered(build_root, name, at, steps, precision):
    runs = spiked_runs(EXAMPLES / f"{name}.yaml", precision, SPIKES[precision], at, steps,
                       build_root=build_root)
    recovery, not_optimal = RECOVERY[name]
    for run in runs:
        assert run.status_at_spike == MEASUREMENT_CLIPPED, run
        assert run.clipped_at_spike == MODES[name], run  # every mode's observer clipped
        assert run.command_at_spike_unchanged, run  # y(k) enters the commands from k + 1
        assert run.finite and run.within_limits, run
        assert run.recovery is not None and run.recovery <= recovery, run
        assert run.not_optimal_after <= not_optimal, run
    assert max(r.recovery for r in runs) == recovery  # the stated figure is the measured one


def test_without_the_clip_the_spike_still_wrecks_the_flight(tmp_path, build_root):
    """The audit's finding, with ``innovation_limit: .inf``: 1e30 in the roll, and the
    controller is far from the spike-free run for over 500 samples after it (measured: 986)."""
    off = _with_limit(tmp_path, UAV, np.inf, "off")
    (run,) = spiked_runs(off, "double", (1e30,), 1500, 3000, build_root=build_root)
    assert run.status_at_spike == OPTIMAL and run.clipped_at_spike == 0
    assert run.not_optimal_after > 500 and (run.recovery is None or run.recovery > 500)


def test_a_large_push_the_model_does_not_know_is_not_clipped(build_root):
    """The chain pushed by 0.3 N on every force (no disturbance model) runs metres past its
    ±0.6 m bounds with innovations of 4.5 m: real, and below the 12 m default."""
    built = Built(CHAIN, "double", build_root)
    c = built.fresh_c()
    clipped = []

    def info():
        clipped.append(c.info()["clipped"])
        return c.info()

    log = run_closed_loop(built.model.config, c, disturbance=0.3, info=info)
    assert np.abs(log.y).max() > 3.0 and not any(clipped)
    assert not np.any(log.status == MEASUREMENT_CLIPPED)


# --------------------------------------------------------------------------- Cortex-M4F
def test_emulated_m4f_matches_through_spikes(build_root):
    """The float target image replays a spiked closed loop bit for bit (commands, statuses
    and every diagnostic, P_last_info()->clipped included)."""
    require_tool("arm-none-eabi-gcc", "apt-get install -y gcc-arm-none-eabi libnewlib-arm-none-eabi")
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.target.build import build_target
    from rollmpc_codegen.target.replay import record_host_runs, replay_on_target

    model, ctx = load_model(UAV, "float")
    spikes = {100: 3.4e38, 150: -1e30, 200: 6000.0}

    def drive(controller, _progress):
        run_closed_loop(model.config, Spiked(controller, spikes), steps=260)

    record = record_host_runs(ctx, build_root, 260, drive)
    assert [record.info[k]["status"] for k in spikes] == [MEASUREMENT_CLIPPED] * 3
    run = replay_on_target(build_target(ctx, build_root), ctx, record, set())
    assert run.mismatches == [] and run.state_equal
