"""Non-finite run-time inputs, at the optimisation levels users build with.

NaN, +Inf and -Inf in *every* element of every input of ``P_step`` (y, sched, each of
the N reference values) and of ``P_solve_qp`` (each state and reference value), one at a
time, on host libraries built with -O2 and with -Os (GCC may not fold the isfinite()
checks away).  The controller is the UAV's with N = 20: the same plants and templates
(the checks do not depend on N) with small data, so the four builds stay quick.  Each gives NONFINITE_INPUT, a finite in-limit command (the last command
held; ``P_solve_qp``: zeros), and the next good sample recovers exactly: its output is
bit-identical to what it would have been -- for ``P_step`` the observers ran open loop
for one sample, which the NumPy reference mirrors.  NULL pointers give BAD_ARGUMENT.
-ffast-math is unsupported; the last test shows why.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import short_uav_config
from rollmpc_codegen.host.build import build_host_controller
from rollmpc_codegen.reference.controller import ControllerRef
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.verify.qp_campaign import restore_state, snapshot_state
from rollmpc_codegen.status import BAD_ARGUMENT, NONFINITE_INPUT, OPTIMAL

N = 20
BAD = [np.nan, np.inf, -np.inf]


@pytest.fixture(scope="module", params=[("double", "-O2"), ("double", "-Os"),
                                        ("float", "-O2"), ("float", "-Os")],
                ids=lambda p: f"{p[0]}{p[1]}")
def built(request, build_root, tmp_path_factory):
    precision, opt = request.param
    model, ctx = load_model(short_uav_config(tmp_path_factory.mktemp("cfg"), N), precision)
    return model, ctx, build_host_controller(ctx, build_root, opt=opt)


def _warm_up(c, ref=None):
    """Five samples of a -40 deg demand from rest: the inner pair saturates."""
    r = np.full(N, -40.0)
    for k in range(5):
        c.step([-0.1 * k], [0.0], r)
        if ref is not None:
            ref.step([-0.1 * k], [0.0], r)
    return r


def _cases():
    yield from ((name, i, bad) for name, size in (("y", 1), ("sched", 1), ("r", N))
                for i in range(size) for bad in BAD)


def test_step_rejects_every_nonfinite_element_and_recovers(built):
    model, ctx, c = built
    c.init()
    ref = ControllerRef(ctx, [m.data for m in model.modes])
    r = _warm_up(c, ref)
    st, u_good = c.step([-0.5], [-1.0], r)
    ref.step([-0.5], [-1.0], r)
    assert st == OPTIMAL and u_good[0] == -15.0
    before = snapshot_state(c)
    # the expected pair (fault sample, recovery sample) from the NumPy reference
    y_bad, s, rr = np.array([np.nan]), np.array([-1.0]), r.copy()
    st_ref, u_ref = ref.step(y_bad, s, rr)
    st_ref2, u_ref2 = ref.step([-0.6], [-1.2], r)
    assert (st_ref, st_ref2) == (NONFINITE_INPUT, OPTIMAL)
    checked = 0
    for name, i, bad in _cases():
        restore_state(c, before)
        y, s, rr = np.array([-0.6]), np.array([-1.2]), r.copy()
        {"y": y, "sched": s, "r": rr}[name][i] = bad
        st, u = c.step(y, s, rr)
        assert st == NONFINITE_INPUT, (name, i, bad)
        assert u.tobytes() == u_good.tobytes(), (name, i, bad)  # last command held
        assert c.info()["iterations"] == 0
        st2, u2 = c.step([-0.6], [-1.2], r)
        assert st2 == OPTIMAL and u2.tobytes() == u_ref2.tobytes(), (name, i, bad)
        checked += 1
    assert checked == 3 * (N + 2)


def test_solve_qp_rejects_every_nonfinite_element_and_recovers(built):
    model, ctx, c = built
    for mode, mm in enumerate(model.modes):
        nx = mm.data.nx
        x_good = np.linspace(-1.0, 2.0, nx)
        r = np.full(N, 30.0)
        c.init()
        st, U_a, _ = c.solve_qp(mode, x_good, r)
        assert st == OPTIMAL
        before = snapshot_state(c)
        st, U_b, its_b = c.solve_qp(mode, 0.5 * x_good, r)  # the sample after, undisturbed
        assert st == OPTIMAL
        for name, size in (("x", nx), ("r", N)):
            for i in range(size):
                for bad in BAD:
                    restore_state(c, before)
                    x, rr = x_good.copy(), r.copy()
                    {"x": x, "r": rr}[name][i] = bad
                    st, U, its = c.solve_qp(mode, x, rr)
                    assert st == NONFINITE_INPUT and its == 0, (mode, name, i, bad)
                    assert np.all(U == 0.0)
                    st, U, its = c.solve_qp(mode, 0.5 * x_good, r)
                    assert st == OPTIMAL and its == its_b and U.tobytes() == U_b.tobytes()


def test_null_pointers_are_bad_arguments_and_harmless(built):
    model, ctx, c = built
    ffi, fn = c.ffi, c._fn
    c.init()
    r_arr = _warm_up(c)
    st, u_good = c.step([0.0], [0.0], r_arr)
    assert st == OPTIMAL
    y = np.zeros(1, c.dtype)
    s = np.zeros(1, c.dtype)
    r = np.ascontiguousarray(r_arr, c.dtype)
    u = np.full(2, 7.0, c.dtype)
    P = c._ptr
    for args in ((ffi.NULL, P(s), P(r)), (P(y), ffi.NULL, P(r)), (P(y), P(s), ffi.NULL)):
        assert fn["step"](c.ctrl, *args, P(u)) == BAD_ARGUMENT
        assert u.tobytes() == u_good.tobytes()  # the last command held
    assert fn["step"](c.ctrl, P(y), P(s), P(r), ffi.NULL) == BAD_ARGUMENT
    assert fn["step"](ffi.NULL, P(y), P(s), P(r), P(u)) == BAD_ARGUMENT
    U = np.full(N, 7.0, c.dtype)
    x = np.zeros(4, c.dtype)
    its = ffi.new("int *", 5)
    for xa, ra in ((ffi.NULL, P(r)), (P(x), ffi.NULL)):
        assert fn["solve_qp"](c.ctrl, 0, xa, ra, P(U), its) == BAD_ARGUMENT
        assert np.all(U == 0.0) and its[0] == 0
    assert fn["solve_qp"](c.ctrl, 0, P(x), P(r), ffi.NULL, its) == BAD_ARGUMENT
    assert fn["solve_qp"](ffi.NULL, 0, P(x), P(r), P(U), its) == BAD_ARGUMENT
    assert fn["solve_qp"](c.ctrl, 0, P(x), P(r), P(U), ffi.NULL) == OPTIMAL  # its optional
    st, u2 = c.step([0.0], [0.0], r_arr)
    assert st == OPTIMAL and np.all(np.isfinite(u2))


def test_fast_math_is_refused_at_compile_time(build_root, tmp_path):
    """-ffast-math lets GCC assume no NaN/Inf and drop the checks this file tests (a NaN
    state was reported as solved): the config header stops such a build with its reason."""
    from rollmpc_codegen.host.build import BuildError

    model, ctx = load_model(short_uav_config(tmp_path, N), "double")
    with pytest.raises(BuildError) as exc:
        build_host_controller(ctx, build_root, opt="-O2", extra=("-ffast-math",))
    assert "-ffast-math is not supported" in str(exc.value)


def test_measurement_beyond_the_float_range_is_nonfinite_without_a_numpy_warning(built):
    """A diverging plant's 1e40 is +inf in float: the C says NONFINITE_INPUT and holds a
    finite command; the cast says nothing (numpy's overflow warning leaked to the user of
    `simulate` on an unstable design)."""
    import warnings

    _, ctx, c = built
    c.init()
    r = _warm_up(c)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        status, u = c.step([1e40], [0.0], r)
    if ctx["precision"] == "float":
        assert status == NONFINITE_INPUT
    assert np.all(np.isfinite(u))
