"""Run-time bounds (`runtime_bounds: true`): P_set_bounds between samples.

On examples/chain_runtime_bounds.yaml (the chain of masses with the bounds live in the
instance, some output bounds left infinite): the C bit for bit equal to the reference
over a closed loop in which the bounds are tightened, made infeasible and loosened, with
rejected calls in between; the double solutions within 1e-8 of exact_qp.solve_exact on
the QP with the new bounds (and INFEASIBLE exactly where it proves infeasibility); every
command inside the limits of its sample; bad calls rejected with nothing changed; the
held command clamped; P_init restoring the config; and the runtime build, with the
config's bounds, bit for bit equal to the baked build.
"""
from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest
import yaml

from compile_flags import AUTOPILOT, CLANG_HINT, STRICT, compile_objects
from conftest import ROOT, Built, edited_config
from lockstep import Lockstep
from rollmpc_codegen.host.build import build_host_controller
from rollmpc_codegen.config import ConfigError, load, parse
from rollmpc_codegen.qp.exact import qp_data, solve_exact
from rollmpc_codegen.pipeline import generate, load_model
from rollmpc_codegen.features.runtime_bounds import row_const
from rollmpc_codegen.sim.scenario import preview, scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import (BAD_ARGUMENT, BAD_BOUNDS, BOUND_NOT_CONFIGURED, INFEASIBLE,
                                    NONFINITE_INPUT, OPTIMAL)

EXAMPLE = ROOT / "examples" / "chain_runtime_bounds.yaml"
INF = np.inf
CONFIG = {"u_min": [-0.5] * 4, "u_max": [0.5] * 4,
          "y_min": [-0.6] * 4 + [-INF, -INF], "y_max": [0.6] * 5 + [INF]}


def _bounds(u_min=-0.5, u_max=0.5, y_lo=0.6, y_hi=0.6) -> dict:
    return {"u_min": [u_min] * 4, "u_max": [u_max] * 4,
            "y_min": [-y_lo] * 4 + [-INF, -INF], "y_max": [y_hi] * 5 + [INF]}


# sample -> calls before that sample's step: (bounds, expected status)
SCHEDULE = {
    5: [(_bounds(-0.3, 0.2, 0.6, 0.3), OPTIMAL)],             # tighten inputs and outputs
    20: [(dict(_bounds(), u_min=[np.nan] * 4), BAD_BOUNDS),   # rejected: nothing changes
         (dict(_bounds(), y_min=[-0.6] * 5 + [-1.0]), BOUND_NOT_CONFIGURED)],
    30: [(_bounds(-0.3, 0.2, 0.6, 0.05), OPTIMAL)],           # infeasible tightening
    40: [(_bounds(-0.45, 0.45, 0.55, 0.55), OPTIMAL)],        # loosen
    65: [(CONFIG, OPTIMAL)],                                  # back to the config
}
STEPS = 80


def _reference(cfg) -> np.ndarray:
    """The example's scenario from sample 30 on: 0, 0.5 from sample 10, -0.5 from 50."""
    return scenario_reference(cfg)[30:30 + STEPS]


class BoundsLockstep(Lockstep):
    """Lockstep with P_set_bounds calls before some samples; records the limits of each."""

    def __init__(self, built):
        super().__init__(built)
        self.calls = []  # (k, status C, status reference, expected)
        self.limits = []  # (u_min, u_max, y_min, y_max) in force at each sample
        self.current = CONFIG

    def step(self, y, s, r):
        for bounds, expected in SCHEDULE.get(self.k, []):
            st_c = self.c.set_bounds(0, **bounds)
            st_r = self.ref.set_bounds(0, **bounds)
            self.calls.append((self.k, st_c, st_r, expected))
            if expected == OPTIMAL:
                self.current = bounds
        self.limits.append(self.current)
        return super().step(y, s, r)


@pytest.fixture(scope="module", params=[pytest.param("double", marks=pytest.mark.slow), "float"])
def example(request, build_root) -> Built:
    return Built(EXAMPLE, request.param, build_root)


@pytest.fixture(scope="module")
def bounds_run(example):
    lock = BoundsLockstep(example)
    log = run_closed_loop(example.model.config, lock, _reference(example.model.config),
                          info=lock.info)
    return example, lock, log


def test_config_key():
    assert load(EXAMPLE).runtime_bounds is True
    assert load(ROOT / "examples" / "uav_roll.yaml").runtime_bounds is False
    data = yaml.safe_load(EXAMPLE.read_text())
    with pytest.raises(ConfigError, match="runtime_bounds"):
        parse(dict(data, runtime_bounds="yes"))


def test_default_build_reads_the_baked_bounds(tmp_path):
    data = yaml.safe_load(EXAMPLE.read_text())
    path = tmp_path / "baked.yaml"
    path.write_text(yaml.safe_dump(dict(data, runtime_bounds=False)))
    _, ctx = generate(path, tmp_path / "baked", "double")
    text = "".join(p.read_text() for p in (tmp_path / "baked").glob("chain_rb*.[ch]"))
    assert ctx["runtime_bounds"] is False
    for name in ("set_bounds", "get_bounds", "row_const", "chain_rb_bounds", "ws->bounds."):
        assert name not in text, name
    assert "g = md->row_c[r];" in text and "md->u_min[i % md->nu]" in text


@pytest.mark.parametrize("cc,precision", [("gcc", "float"), ("clang", "double")])
def test_compiles_strict_with_autopilot_flags(tmp_path, cc, precision):
    """(The host builds of the fixtures compile with gcc -Werror in both precisions.)"""
    if shutil.which(cc) is None:
        pytest.skip(f"{cc} not found; install with: {CLANG_HINT}")
    generate(EXAMPLE, tmp_path / "src", precision)
    proc = compile_objects(cc, tmp_path / "src", ["-O2", *STRICT, *AUTOPILOT], tmp_path / "obj")
    assert proc.returncode == 0 and not proc.stderr.strip(), proc.stderr


def test_step_bit_exact_while_bounds_change(bounds_run):
    example, lock, log = bounds_run
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    assert [(st_c, st_r) for _, st_c, st_r, _ in lock.calls] == \
        [(exp, exp) for _, _, _, exp in lock.calls]
    # the schedule exercises optimal samples on tightened bounds and proven infeasibility
    assert np.all(log.status[:30] == OPTIMAL) and np.all(log.status[40:] == OPTIMAL)
    assert np.all(log.status[30:40] == INFEASIBLE)  # y_max 0.05 with the masses near 0.3


def test_commands_within_the_current_limits(bounds_run):
    example, lock, log = bounds_run
    dt = example.c.dtype
    lo = np.array([np.asarray(b["u_min"], dt) for b in lock.limits])
    hi = np.array([np.asarray(b["u_max"], dt) for b in lock.limits])
    u = np.array(log.u_raw)
    assert np.all(u >= lo) and np.all(u <= hi)
    # the tightened, then the loosened input bounds are active
    assert np.any(u[5:30] == dt(0.2)) and np.any(u[40:65] == dt(0.45))
    assert np.any(u[40:65] == dt(-0.45))
    # optimal samples keep the next output inside the bounds of their sample
    tol = 1e-9 if dt == np.float64 else 1e-4
    for k in np.flatnonzero(log.status[:-1] == OPTIMAL):
        b = lock.limits[k]
        assert np.all(log.y[k + 1] <= np.asarray(b["y_max"]) + tol), k
        assert np.all(log.y[k + 1] >= np.asarray(b["y_min"]) - tol), k
    assert log.y[5:30, :5].max() > 0.299  # the tightened output bound 0.3 is active
    assert log.y[40:65, :4].min() < -0.549  # and the loosened y_min -0.55


def test_double_matches_exact_solution_with_new_bounds(bounds_run):
    example, lock, log = bounds_run
    if example.ctx["precision"] != "double":
        pytest.skip("the independent check is a double-precision property")
    qp, md = example.model.modes[0].qp, example.model.modes[0].data
    N, ny = example.ctx["horizon"], example.ctx["n_outputs"]
    ref = _reference(example.model.config)
    c = example.fresh_c()
    row_q = np.where(qp.row_kind == 0, qp.row_index, qp.n + qp.row_index)
    worst, checked, infeasible = 0.0, 0, 0
    for k in (3, 12, 25, 30, 35, 44, 52, 57, 63, 70):
        _, x, kk = lock.states[k]
        r = preview(ref, kk, N, ny)
        b = lock.limits[k]
        assert c.set_bounds(0, **b) == OPTIMAL
        st_c, U_c, _ = c.solve_qp(0, x, r)
        # the QP with the new bounds, in double from the config's maths: c = s * bound
        c_new = row_const(row_q, qp.row_sign, qp.n, qp.nu, qp.ny, **b)
        exact = solve_exact(qp_data(dataclasses.replace(qp, c=c_new), x, r))
        assert st_c == log.status[k], k
        if st_c == INFEASIBLE:
            assert exact.status == "infeasible", k
            infeasible += 1
            continue
        assert st_c == OPTIMAL and exact.status == "optimal", k
        worst = max(worst, float(np.abs(U_c - np.asarray(exact.U, float)).max()))
        checked += 1
    assert (checked, infeasible) == (8, 2)
    assert worst <= 1e-8, worst
    # the baked row_c of the config equals the derived constants (one formula)
    assert np.array_equal(row_const(md.row_q, md.row_sign, md.n, md.nu, md.ny, **CONFIG),
                          md.row_c)


BAD_CALLS = [
    ({"u_min": None}, BAD_ARGUMENT),
    ({"y_max": None}, BAD_ARGUMENT),
    ({"u_min": [-0.5, -0.5, INF, -0.5]}, BAD_BOUNDS),
    ({"u_max": [0.5, -INF, 0.5, 0.5]}, BAD_BOUNDS),
    ({"u_min": [0.1, -0.5, -0.5, -0.5]}, BAD_BOUNDS),       # 0 outside the input bounds
    ({"u_max": [0.5, 0.5, -0.1, 0.5]}, BAD_BOUNDS),
    ({"u_min": [-0.5] * 3 + [0.0], "u_max": [0.5] * 3 + [0.0]}, BAD_BOUNDS),  # lo == hi
    ({"y_min": [-0.6, np.nan, -0.6, -0.6, -INF, -INF]}, BAD_BOUNDS),
    ({"y_max": [0.6, 0.6, 0.6, INF, 0.6, INF]}, BAD_BOUNDS),  # a configured bound dropped
    ({"y_min": [-0.6] * 4 + [-INF, INF]}, BAD_BOUNDS),        # the wrong infinity
    ({"y_min": [-0.6, -0.6, 0.7, -0.6, -INF, -INF]}, BAD_BOUNDS),  # y_min > y_max
    ({"y_min": [-0.6] * 4 + [-2.0, -INF]}, BOUND_NOT_CONFIGURED),
    ({"y_max": [0.6] * 6}, BOUND_NOT_CONFIGURED),
]


def test_bad_calls_change_nothing(example):
    c, ref = example.fresh_c(), example.reference()
    new = _bounds(-0.4, 0.3, 0.5, 0.4)
    assert c.set_bounds(0, **new) == OPTIMAL and ref.set_bounds(0, **new) == OPTIMAL
    for change, expected in BAD_CALLS:
        bad = dict(new, **change)
        assert (c.set_bounds(0, **bad), ref.set_bounds(0, **bad)) == (expected, expected), change
        status, live = c.get_bounds(0)
        assert status == OPTIMAL
        for key, values in new.items():
            assert np.array_equal(live[key], np.asarray(values, c.dtype)), (change, key)
            assert np.array_equal(ref.bounds[0][key], live[key]), (change, key)
    assert c.status_message(BAD_BOUNDS) == "bad bounds; nothing changed"
    assert "no constraint rows" in c.status_message(BOUND_NOT_CONFIGURED)


def test_bad_mode_and_init_restores_the_config(example):
    c = example.fresh_c()
    assert c.set_bounds(1, **CONFIG) == BAD_ARGUMENT and c.set_bounds(-1, **CONFIG) == BAD_ARGUMENT
    assert c.get_bounds(1)[0] == BAD_ARGUMENT
    assert c.set_bounds(0, **_bounds(-0.1, 0.1, 0.2, 0.2)) == OPTIMAL
    c.init()
    status, live = c.get_bounds(0)
    assert status == OPTIMAL
    for key, values in CONFIG.items():
        assert np.array_equal(live[key], np.asarray(values, c.dtype)), key


def test_held_command_is_clamped_into_new_bounds(example):
    c, ref = example.fresh_c(), example.reference()
    N, ny = example.ctx["horizon"], example.ctx["n_outputs"]
    r = np.full(N * ny, 0.5)
    y = np.zeros(ny)
    for _ in range(3):
        st_c, u_c = c.step(y, None, r)
        st_r, u_r = ref.step(y, None, r)
    assert st_c == st_r == OPTIMAL and u_c.tobytes() == u_r.tobytes()
    lo, hi = min(float(u_c.min()) / 2, -0.01), max(float(u_c.max()) / 2, 0.01)
    new = _bounds(lo, hi)
    assert c.set_bounds(0, **new) == OPTIMAL and ref.set_bounds(0, **new) == OPTIMAL
    y_bad = np.full(ny, np.nan)
    st_c, u_held = c.step(y_bad, None, r)
    st_r, u_r = ref.step(y_bad, None, r)
    assert st_c == st_r == NONFINITE_INPUT and u_held.tobytes() == u_r.tobytes()
    expected = np.clip(u_c, c.dtype(lo), c.dtype(hi))
    assert np.array_equal(u_held, expected) and not np.array_equal(u_held, u_c)


def test_runtime_build_equals_baked_build(example, tmp_path):
    """With the config's bounds, the live accessor gives the baked numbers exactly (float:
    where a wrong rounding of a derived constant would show first)."""
    if example.ctx["precision"] != "float":
        pytest.skip("checked in float")
    data = yaml.safe_load(EXAMPLE.read_text())
    path = tmp_path / "baked.yaml"
    path.write_text(yaml.safe_dump(dict(data, runtime_bounds=False)))
    _, ctx = load_model(path, example.ctx["precision"])
    baked = build_host_controller(ctx, example.build_root)
    live = example.fresh_c()
    cfg = example.model.config
    log_b = run_closed_loop(cfg, baked, steps=60)
    log_l = run_closed_loop(cfg, live, steps=60)
    assert np.array_equal(log_b.status, log_l.status)
    assert b"".join(u.tobytes() for u in log_b.u_raw) == b"".join(u.tobytes() for u in log_l.u_raw)


def test_simulate_cli_runs_the_example(tmp_path, build_root):
    """`rollmpc simulate` end to end on the example (the config's bounds; no regeneration
    is needed for other bounds, which the firmware sets through P_set_bounds)."""
    from rollmpc_codegen.cli.main import main

    out = tmp_path / "s.json"
    assert main(["simulate", str(EXAMPLE), "--steps", "60", "--quiet", "--json", str(out),
                 "--build-dir", str(build_root)]) == 0
    summary = json.loads(out.read_text())
    assert summary["samples"] == 60 and summary["non_optimal"] == 0
    assert summary["constraint_violations"]["u"] == 0 and summary["constraint_violations"]["y"] == 0


def test_runtime_bounds_with_control_horizon_bit_exact(tmp_path, build_root):
    """P_set_bounds on a blocked chain (row_const(): input q mod nu, per block): the
    schedule above (tighten, infeasible, loosen, reset, bad calls)."""
    path = edited_config(tmp_path, EXAMPLE, "chain_rb_nc3", lambda d: d.update(control_horizon=3))
    built = Built(path, "float", build_root)
    lock = BoundsLockstep(built)
    log = run_closed_loop(built.model.config, lock, _reference(built.model.config),
                          info=lock.info)
    assert len(log.t) == STEPS and built.ctx["modes"][0]["n"] == 12
    assert lock.mismatches == [], lock.mismatches[0]
    assert all(st_c == st_r == exp for _, st_c, st_r, exp in lock.calls)
    dt = built.model.dtype  # the limits as the float build stores them
    for k, (lim, u) in enumerate(zip(lock.limits, log.u)):
        lo, hi = np.asarray(lim["u_min"], dt), np.asarray(lim["u_max"], dt)
        assert np.all(u >= lo) and np.all(u <= hi), k
    assert np.any(log.status == OPTIMAL) and np.any(log.status != OPTIMAL)  # infeasible phase
