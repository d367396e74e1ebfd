"""The public C API contract (the generated README, "API" and "Statuses"): statuses, bad
inputs, safe outputs."""
from __future__ import annotations

import subprocess

import numpy as np
import pytest

from conftest import Built, variant_config
from rollmpc_codegen.sim.scenario import paper_reference, preview
from rollmpc_codegen.status import BAD_ARGUMENT, MAX_ITER, NONFINITE_INPUT, OPTIMAL, STATUS_NAMES

N = 100


def _saturating_state(uav):
    """Observer state after 100 samples of a steady -20 deg demand from rest."""
    c = uav.fresh_c()
    r = np.full(N, -40.0)
    for _ in range(5):
        c.step([0.0], [0.0], r)
    return c


def test_status_messages_are_distinct_and_total(uav):
    msgs = [uav.c.status_message(s) for s in STATUS_NAMES]
    assert len(set(msgs)) == len(msgs)
    assert uav.c.status_message(99) == "unknown status"


def test_ctrl_size_is_the_struct_size(uav, tmp_path):
    """P_ctrl_size() is sizeof(P_ctrl) as a C compiler sees P.h (firmware allocates that)."""
    from rollmpc_codegen.codegen.render import render_sources

    for name, text in render_sources(uav.ctx).items():
        (tmp_path / name).write_text(text)
    prefix = uav.ctx["prefix"]
    (tmp_path / "size.c").write_text(
        f'#include <stdio.h>\n#include "{prefix}.h"\n'
        f'int main(void) {{ printf("%zu\\n", sizeof({prefix}_ctrl)); return 0; }}\n')
    subprocess.run(["gcc", "-std=c99", f"-I{tmp_path}", str(tmp_path / "size.c"), "-o",
                    str(tmp_path / "size")], check=True)
    size = int(subprocess.run([str(tmp_path / "size")], capture_output=True, text=True,
                              check=True).stdout)
    assert uav.c._fn["ctrl_size"]() == size
    assert uav.c._fn["ctrl_size"]() > 4 * (N * 4 * 2)  # holds warm-start multipliers


def test_inactive_actuator_is_zero_and_limits_hold(uav):
    c = uav.fresh_c()
    st, u = c.step([0.0], [0.0], np.full(N, 40.0))
    assert st == OPTIMAL
    assert u[1] == 0.0 and 0 < u[0] <= 15.0  # inner mode active at rest


def test_bad_mode_index_is_rejected(uav):
    st, U, its = uav.c.solve_qp(7, np.zeros(5), np.zeros(N))
    assert st == BAD_ARGUMENT
    st, U, its = uav.c.solve_qp(-1, np.zeros(5), np.zeros(N))
    assert st == BAD_ARGUMENT


@pytest.mark.parametrize("where", ["y", "sched", "r"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_input_holds_last_command_and_recovers(uav, where, bad):
    c = _saturating_state(uav)
    st, u_good = c.step([0.0], [0.0], np.full(N, -40.0))
    y, s, r = np.array([0.0]), np.array([0.0]), np.full(N, -40.0)
    {"y": y, "sched": s, "r": r}[where][0] = bad
    st, u = c.step(y, s, r)
    assert st == NONFINITE_INPUT
    assert np.array_equal(u, u_good)  # the last command is held
    st, u = c.step([0.0], [0.0], np.full(N, -40.0))
    assert st == OPTIMAL and np.all(np.isfinite(u))


def test_solve_qp_nonfinite_state_gives_safe_zero(uav):
    st, U, its = uav.c.solve_qp(0, np.array([np.nan, 0, 0, 0]), np.zeros(N))
    assert st == NONFINITE_INPUT and np.all(U == 0)


@pytest.mark.parametrize("cap", [1, 2, 5])
def test_iteration_cap_stops_exactly_with_safe_output(tmp_path, build_root, cap):
    cfg = variant_config(tmp_path, max_iterations=cap, polish=False)
    built = Built(cfg, "double", build_root)
    ref = paper_reference(0.01)
    x = np.zeros(4)
    st, U, its = built.c.solve_qp(0, x, preview(ref, 950, N))  # step to -20 deg ahead
    assert st == MAX_ITER and its == cap
    assert np.all(np.isfinite(U)) and np.all(np.abs(U) <= 15.0)


def test_last_info_of_a_null_instance_is_null(uav):
    """P_last_info(NULL) returned &NULL->info (a crash on the first field read)."""
    host = uav.c
    assert host._fn["last_info"](host.ffi.NULL) == host.ffi.NULL
    assert host._fn["last_info"](host.ctrl) != host.ffi.NULL
