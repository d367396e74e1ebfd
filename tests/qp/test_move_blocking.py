"""Control horizon and move blocking (``control_horizon``, ``move_blocking``).

examples/uav_roll_blocked.yaml (the paper's UAV, N = 100, 20 blocks), the chain of masses
with ``control_horizon: 3`` (output rows active: the blocked prediction is exercised) and
thermal_zones with a per-mode pattern and Δu weighting.  Checked: the blocked QP is the
full QP restricted to U = T U_b; P_step bit for bit against the NumPy reference over
closed loops (both precisions); the double QP solutions within 1e-8 of DAQP and of the
extended-precision solution; the bounds met; an unblocked build generates the C of before; config errors name their key.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import (ROOT, Built, config_error, edited_config,
                      sampled_qps_against_independent_solvers)
from lockstep import Lockstep
from rollmpc_codegen.features import move_blocking
from rollmpc_codegen.config import load
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.codegen.render import render_sources
from rollmpc_codegen.sim.scenario import scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import OPTIMAL

UAV_BLOCKED = ROOT / "examples" / "uav_roll_blocked.yaml"
CHAIN = ROOT / "examples" / "chain_of_masses.yaml"
ZONES = ROOT / "examples" / "thermal_zones.yaml"


def _chain_nc3(tmp_path):
    return edited_config(tmp_path, CHAIN, "chain_nc3", lambda d: d.update(control_horizon=3))


def _zones_blocked(tmp_path):
    def edit(d):
        d["modes"][0]["move_blocking"] = [1, 2, 3, d["horizon"] - 6]
    return edited_config(tmp_path, ZONES, "zones_blk", edit)


# --------------------------------------------------------------------------- model
def test_blocked_qp_is_the_full_qp_restricted(tmp_path):
    """E_b = T'ET, f_b = T'f, rows = the full rows of each block's first stage (inputs)
    and all output rows; the controller horizon pattern; row_next; with Δu weighting."""
    for path, blocks in ((UAV_BLOCKED, (1,) * 4 + (2,) * 4 + (4,) * 4 + (6, 6, 8, 8, 10, 10,
                                                                       12, 12)),
                         (_zones_blocked(tmp_path), (1, 2, 3, 14))):
        blocked, _ = load_model(path)
        full, _ = load_model(edited_config(tmp_path, path, "full", lambda d: (
            d.pop("move_blocking", None), d["modes"][0].pop("move_blocking", None))))
        b, f = blocked.modes[0].qp, full.modes[0].qp
        assert b.blocks == blocks and f.blocks is None
        T = move_blocking.expansion(blocks, b.nu)
        assert b.n == len(blocks) * b.nu
        assert np.allclose(b.E, T.T @ f.E @ T, rtol=1e-12, atol=1e-9 * np.abs(f.E).max())
        rng = np.random.default_rng(1)
        x, R = rng.normal(size=b.nx), rng.normal(size=b.N * b.ny)
        assert np.allclose(b.gradient(x, R), T.T @ f.gradient(x, R), rtol=1e-10, atol=1e-9)
        starts = move_blocking.block_starts(blocks)
        keep = [r for r in range(f.m) if f.row_kind[r] == 1
                or f.row_index[r] // f.nu in set(starts.tolist())]
        assert b.m == len(keep)
        assert np.allclose(b.L, f.L[keep] @ T) and np.array_equal(b.c, f.c[keep])
        d = blocked.modes[0].data
        assert np.array_equal(d.stage_block, np.repeat(np.arange(len(blocks)), blocks))
    # row_next: a one-stage block maps to the next block, a longer one to itself
    later = move_blocking.next_input_quantity((1, 1, 3, 5), 2)
    assert later.tolist() == [2, 3, 4, 5, 4, 5, 6, 7]
    assert move_blocking.blocks_of(3, None, 6, "") == (1, 1, 4)


# --------------------------------------------------------------------------- closed loop
@pytest.fixture(scope="module", params=[pytest.param("double", marks=pytest.mark.slow),
                                        "float"])
def uav_run(request, build_root):
    built = Built(UAV_BLOCKED, request.param, build_root)
    lock = Lockstep(built)
    # the first 2000 samples: both modes, saturated inputs (the whole 6000: 34 s, bit
    # exact too, measured in this session)
    log = run_closed_loop(built.model.config, lock, info=lock.info, steps=2000)
    return built, lock, log


def test_uav_step_bit_exact_and_bounds_met(uav_run):
    built, lock, log = uav_run
    assert [m["n"] for m in built.ctx["modes"]] == [20, 20]
    assert [m["m"] for m in built.ctx["modes"]] == [240, 240]
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    assert np.all(log.status == OPTIMAL) and set(log.mode) == {0, 1}
    assert np.any(np.abs(log.u) == 15.0) and np.all(np.abs(log.u) <= 15.0)
    assert np.all(np.abs(log.y) <= 270.0)


def test_uav_double_matches_independent_solvers(uav_run):
    built, lock, _ = uav_run
    if built.ctx["precision"] != "double":
        pytest.skip("the independent check is a double-precision property")
    states = [s for s in lock.states if s[0] == 0]
    saturated, worst_daqp, worst_exact = sampled_qps_against_independent_solvers(
        built, states, scenario_reference(built.model.config), bound=15.0, perturb=20.0,
        seed=5, count=8)
    assert saturated >= 2
    assert worst_daqp <= 1e-8 and worst_exact <= 1e-8, (worst_daqp, worst_exact)


@pytest.mark.parametrize("precision", ["double", "float"])
def test_chain_control_horizon_bit_exact_with_output_rows(tmp_path, build_root, precision):
    built = Built(_chain_nc3(tmp_path), precision, build_root)
    assert built.ctx["modes"][0]["n"] == 12  # 3 moves x 4 inputs instead of 40
    lock = Lockstep(built)
    log = run_closed_loop(built.model.config, lock, info=lock.info)
    assert lock.mismatches == [], lock.mismatches[0]
    assert np.all(log.status == OPTIMAL)
    assert np.any(np.abs(log.u) == 0.5) and np.all(np.abs(log.u) <= 0.5)
    tol = 1e-3 if precision == "float" else 1e-9
    assert np.all(np.abs(log.y) <= 0.6 + tol)
    if precision == "double":
        saturated, worst_daqp, worst_exact = sampled_qps_against_independent_solvers(
            built, lock.states, scenario_reference(built.model.config), bound=0.5,
            perturb=0.3, seed=3, count=6)
        assert saturated >= 2
        assert worst_daqp <= 1e-8 and worst_exact <= 1e-8, (worst_daqp, worst_exact)


def test_blocks_with_delta_weighting_bit_exact(tmp_path, build_root):
    built = Built(_zones_blocked(tmp_path), "double", build_root)
    lock = Lockstep(built)
    log = run_closed_loop(built.model.config, lock, info=lock.info, disturbance=0.3,
                          steps=150)
    assert lock.mismatches == [], lock.mismatches[0]
    assert np.all(log.status == OPTIMAL) and np.all(np.abs(log.u) <= 2.0)


# --------------------------------------------------------------------------- generation
def test_unblocked_build_generates_the_same_c(tmp_path):
    """No blocking: no stage_block in the C; a per-mode control_horizon equal to N under a
    blocked top level leaves that mode unblocked."""
    _, ctx = load_model(CHAIN)
    files = render_sources(ctx)
    assert ctx["move_blocking"] is False
    assert not any("stage_block" in text for text in files.values())
    _, ctx_b = load_model(_chain_nc3(tmp_path))
    files_b = render_sources(ctx_b)
    assert any("stage_block" in text for text in files_b.values())

    def edit(d):
        d["control_horizon"] = 2
        d["modes"][0]["control_horizon"] = d["horizon"]
    cfg = load(edited_config(tmp_path, CHAIN, "override", edit))
    assert cfg.modes[0].blocks is None


@pytest.mark.parametrize("top, mode, key, text", [
    ({"control_horizon": 11}, {}, "control_horizon", "<= horizon (10)"),
    ({"control_horizon": 0}, {}, "control_horizon", ">= 1"),
    ({"control_horizon": 2.5}, {}, "control_horizon", "integer"),
    ({"move_blocking": [2, 2, 2]}, {}, "move_blocking", "sum to the horizon (10), got 6"),
    ({"move_blocking": [5, 6, -1]}, {}, "move_blocking[2]", "positive"),
    ({"move_blocking": []}, {}, "move_blocking", "non-empty list"),
    ({"move_blocking": 5}, {}, "move_blocking", "non-empty list"),
    ({}, {"move_blocking": [4, 0, 6]}, "modes[0].move_blocking[1]", "positive"),
    ({}, {"control_horizon": 3, "move_blocking": [5, 5]}, "modes[0].move_blocking",
     "either control_horizon or move_blocking"),
    ({}, {"control_horizon": 12}, "modes[0].control_horizon", "<= horizon"),
])
def test_config_errors_name_the_key(tmp_path, top, mode, key, text):
    def edit(d):
        d.update(top)
        d["modes"][0].update(mode)
    err = config_error(edited_config(tmp_path, CHAIN, "bad", edit))
    assert err.key == key and text in str(err), str(err)
