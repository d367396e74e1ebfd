"""The dual factor kept by updates, and the hard work budget (TIME_LIMIT).

* The factor updates (templates/solver/factor_update.c.j2, polish_dual.c.j2) are run on
  their own, through a shim library around the generated solver: after every deletion,
  append and rank-one up/downdate the C factor equals the reference's bit for bit, and a
  fresh factorisation of the updated matrix to a stated tolerance.
* With a small budget, the closed loop of fw_lateral (Δu rows, a soft bound: every path of
  the dual side) is bit for bit the reference's, TIME_LIMIT included (status, command,
  sweeps, corrections, active rows, work).
* On a long randomized closed loop (noise, random bank and sideslip references), with the
  small budget and with the default one, no step spends more than the budget and every
  command is finite and within its bounds; with the default budget the status is OPTIMAL
  again within a measured number of samples after a TIME_LIMIT.
No time is measured: work units are deterministic.
"""
from __future__ import annotations

import dataclasses
import subprocess

import numpy as np
import pytest

from conftest import ROOT, Built, config_error, lockstep_closed_loop
from rollmpc_codegen.qp.work import STEP_FIXED_UNITS
from rollmpc_codegen.sim.metrics import longest_run
from rollmpc_codegen.status import OPTIMAL, TIME_LIMIT

FW = ROOT / "examples" / "fw_lateral.yaml"
SMALL_BUDGET = 45000  # work units: about half the default (84,000)
# measured on the randomized run below (3000 samples, seed 3) with the default budget: the
# longest run of TIME_LIMIT samples is 3 (float, 3 of 3000 samples) and 6 (double, 38);
# 3 and 11 (8 and 61 samples) before the output prediction skipped the unbounded sideslip
RECOVERY_SAMPLES = 6
QUAD = ROOT / "examples" / "quad_attitude.yaml"
# quad_attitude's nominal scenario (float) with the default budget: its tilt-saturated
# manoeuvres need about 1.7 times the default share of Ts (docs/solver.md, "Work budget");
# measured with the factors carried from one QP to the next (carry_factor()): 985 of 1050
# samples OPTIMAL, 65 TIME_LIMIT, the longest run 21, the hard 30 deg tilt held (987 and
# 63 before: the carry stops two more samples here, and fewer and shorter runs on the
# heavy fixed-wing and hexacopter designs of tests/data/heavy)
QUAD_OPTIMAL, QUAD_RECOVERY_SAMPLES = 985, 21


def _built(precision: str, build_root, budget) -> Built:
    return _built_from(FW, precision, build_root, budget)


def _built_from(config, precision: str, build_root, budget) -> Built:
    """``config`` built with its work budget replaced by ``budget``."""
    from rollmpc_codegen.pipeline import load_model_from_config

    built = Built(config, precision, build_root)
    cfg = built.model.config
    cfg = dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver, work_budget=budget))
    built.model, built.ctx = load_model_from_config(cfg)
    built.c = built.fresh_c()
    return built


@pytest.fixture(scope="module", params=[pytest.param("double", marks=pytest.mark.slow), "float"])
def fw_small(request, build_root) -> Built:
    return _built(request.param, build_root, SMALL_BUDGET)


@pytest.fixture(scope="module", params=["float", pytest.param("double", marks=pytest.mark.slow)])
def fw_default(request, build_root) -> Built:
    return Built(FW, request.param, build_root)


# ------------------------------------------------------------------ the factor updates
SHIM = """
#include "{p}_solver.c"
static {p}_work shim_ws;
int shim_rank_one({p}_real *l, int from, int n, {p}_real *v, int downdate)
{{
    return chol_rank_one(l, from, n, v, downdate, NULL, 0);
}}
void shim_delete({p}_real *l, int k, int n, {p}_real *v, {p}_real *carry, int ncarry)
{{
    chol_delete(l, k, n, v, carry, ncarry);
}}
int shim_n_max(void)
{{
    return {P}_N_MAX;
}}
int shim_append({p}_real *l, int nw, const {p}_real *h, {p}_real hpp)
{{
    int i;
    {p}_real zeta;
    for (i = 0; i < nw * (nw + 1) / 2; ++i) shim_ws.chol[i] = l[i];
    for (i = 0; i < nw; ++i) shim_ws.rhs[i] = h[i];
    zeta = factor_pivot(&shim_ws, 0, nw, hpp);
    if (!(zeta > {P}_SOLVER_DEPENDENCE_TOL * hpp)) return -1;
    factor_append(&shim_ws, nw, zeta);
    for (i = 0; i < (nw + 1) * (nw + 2) / 2; ++i) l[i] = shim_ws.chol[i];
    return 0;
}}
"""
CDEF = """
int shim_rank_one({r} *l, int from, int n, {r} *v, int downdate);
void shim_delete({r} *l, int k, int n, {r} *v, {r} *carry, int ncarry);
int shim_n_max(void);
int shim_append({r} *l, int nw, const {r} *h, {r} hpp);
"""


def _shim(ctx, tmp_path):
    """The generated solver's update functions, exported by a shim (built with the host
    flags that matter: -O2 -ffp-contract=off)."""
    import cffi

    from rollmpc_codegen.codegen.render import render_sources

    p = ctx["prefix"]
    src = tmp_path / "src"
    src.mkdir()
    for name, text in render_sources(ctx).items():
        (src / name).write_text(text)
    (src / f"{p}_shim.c").write_text(SHIM.format(p=p, P=p.upper()))
    sources = [str(f) for f in sorted(src.glob("*.c")) if f.name != f"{p}_solver.c"]
    lib = tmp_path / "libshim.so"
    subprocess.run(["gcc", "-O2", "-std=c99", "-fPIC", "-shared", "-ffp-contract=off", "-w",
                    f"-I{src}", "-o", str(lib), *sources, "-lm"], check=True)
    ffi = cffi.FFI()
    ffi.cdef(CDEF.format(r=ctx["real"]))
    return ffi, ffi.dlopen(str(lib))


def test_updated_factor_is_the_reference_and_a_fresh_factor(fw_small, tmp_path):
    """60 random updates of a working-set factor of fw_lateral's H (input rows): deletions,
    appends, rank-one updates and downdates of one diagonal entry (a soft row's switch).
    A deletion carries two solves L^-1 b through its rotations (the primal factor's Y):
    they become the solves of b without the deleted entry."""
    from rollmpc_codegen.reference.factor_update import chol_delete, chol_rank_one
    from rollmpc_codegen.reference.linalg import chol_lsolve_from, cholesky_from
    from rollmpc_codegen.reference.solver import SolverRef

    ctx, md = fw_small.ctx, fw_small.model.modes[0].data
    dt = md.Kx.dtype
    ffi, lib = _shim(ctx, tmp_path)
    ref = SolverRef(md, ctx["solver"])
    ptr = lambda a: ffi.cast(f"{ctx['real']} *", ffi.from_buffer(a))  # noqa: E731
    rng = np.random.default_rng(11)
    inputs = np.flatnonzero((md.row_q < md.n) & (md.row_sign > 0))  # one row per input
    W = list(rng.choice(inputs, 30, replace=False))
    extra = {r: dt.type(0.0) for r in W}  # w on the diagonal (a slack soft row)
    A = lambda: ref.H[np.ix_(W, W)].astype(np.float64) + np.diag([float(extra[r]) for r in W])  # noqa: E731
    L = np.concatenate([ref.H[W[i], W[:i + 1]] for i in range(len(W))]).astype(dt)
    assert cholesky_from(L, len(W))
    worst = worst_y = 0.0
    counts = {"delete": 0, "append": 0, "update": 0, "downdate": 0}
    for _ in range(60):
        n = len(W)
        op = rng.choice(["delete", "append", "update", "downdate"])
        Lc = np.zeros(len(inputs) * (len(inputs) + 1) // 2, dt)
        Lc[:L.size] = L
        Lr = Lc.copy()
        if op == "delete" and n > 5:
            k = int(rng.integers(n))
            B = rng.standard_normal((2, n)).astype(dt)
            Yr = B.copy()
            for y in Yr:
                chol_lsolve_from(Lr, n, y)
            nmax = lib.shim_n_max()
            Yc = np.zeros(2 * nmax, dt)
            Yc[:n], Yc[nmax:nmax + n] = Yr
            lib.shim_delete(ptr(Lc), k, n, ptr(np.zeros(n, dt)), ptr(Yc), 2)
            chol_delete(Lr, k, n, np.zeros(n, dt), Yr)
            assert Yc[:n - 1].tobytes() == Yr[0, :n - 1].tobytes()
            assert Yc[nmax:nmax + n - 1].tobytes() == Yr[1, :n - 1].tobytes()
            Ld = np.zeros((n - 1, n - 1))
            for i in range(n - 1):
                Ld[i, :i + 1] = Lr[i * (i + 1) // 2:(i + 1) * (i + 2) // 2]
            for y, b in zip(Yr, B):  # L' y' = b without entry k, to the precision
                b = np.delete(b, k).astype(np.float64)
                err = np.abs(Ld @ y[:n - 1] - b).max() / max(1.0, np.abs(b).max())
                worst_y = max(worst_y, float(err))
            del extra[W.pop(k)]
        elif op == "append":
            p = int(rng.choice([r for r in inputs if r not in extra]))
            h = ref.H[W, p].astype(dt)
            ok_c = lib.shim_append(ptr(Lc), n, ptr(h), ref.Hdiag[p]) == 0
            ref.chol = Lr
            y = h.copy()
            zeta = ref.factor_pivot(y, ref.Hdiag[p])
            ok_r = bool(zeta > ref.dep_tol * ref.Hdiag[p])
            if ok_r:
                ref.factor_append(y, zeta, p)
            assert ok_c == ok_r and ok_c  # input rows are independent
            W.append(p)
            extra[p] = dt.type(0.0)
        elif op in ("update", "downdate"):
            slack = [i for i in range(n) if extra[W[i]] > 0]
            down = op == "downdate" and bool(slack)
            k = int(rng.choice(slack)) if down else int(rng.integers(n))
            w = extra[W[k]] if down else dt.type(rng.uniform(0.1, 2.0) * ref.Hdiag[W[k]])
            v = np.zeros(n, dt)
            v[k] = np.sqrt(w)
            assert lib.shim_rank_one(ptr(Lc), k, n, ptr(v.copy()), int(down)) == 0
            assert chol_rank_one(Lr, k, n, v.copy(), down, ref.dep_tol)
            extra[W[k]] = dt.type(0.0) if down else w
            op = "downdate" if down else "update"
        else:
            continue
        counts[str(op)] += 1
        size = len(W) * (len(W) + 1) // 2
        assert Lc[:size].tobytes() == Lr[:size].tobytes(), op  # bit for bit
        L = Lr[:size].copy()
        fresh = np.linalg.cholesky(A())[np.tril_indices(len(W))]
        worst = max(worst, float(np.abs(L - fresh).max() / np.abs(fresh).max()))
    assert min(counts.values()) >= 5, counts
    # against the fresh factor of the same matrix (entries in the storage precision, the
    # factor in double): measured 6.8e-7 (float), 1.7e-15 (double)
    assert worst <= (1e-5 if ctx["precision"] == "float" else 1e-13), worst
    # the carried solves against their right-hand sides: measured 3.1e-7, 8.6e-16
    assert worst_y <= (1e-5 if ctx["precision"] == "float" else 1e-13), worst_y


# ------------------------------------------------------------------ TIME_LIMIT, bit for bit
def test_time_limit_is_bit_exact_with_the_reference(fw_small):
    budget = fw_small.ctx["solver"]["work_budget"]
    bad, seen = lockstep_closed_loop(fw_small, 700)
    assert bad == []
    statuses = [s for s, _ in seen]
    # enough stops to exercise them: measured 59 TIME_LIMIT and 641 OPTIMAL (float); fewer
    # stops since an optimal resumed working set is accepted without polish
    assert statuses.count(TIME_LIMIT) >= 40 and statuses.count(OPTIMAL) >= 400
    assert max(w for _, w in seen) <= budget


def test_time_limited_random_qps_are_bit_exact(build_root):
    """Far-out random QPs of uav_roll_blocked (double, budget 40,000: 84 of 150 stop at
    TIME_LIMIT) through P_solve_qp: the C's whole plan U, status and work are the
    reference's bit for bit. The C primal solve used to set its bound inputs in ws->th
    before asking for its work, so a polish that then ran out returned that point with
    those inputs moved to their bounds (7 of these QPs, by up to 1e-5)."""
    built = _built_from(ROOT / "examples" / "uav_roll_blocked.yaml", "double", build_root,
                        40000)
    c = built.fresh_c()
    ref = built.reference()  # P_solve_qp's: the modes share the last plan and the work arrays
    rng = np.random.default_rng(1)
    bad, limited = [], 0
    for i in range(150):
        mode = int(rng.integers(len(built.model.modes)))
        md = built.model.modes[mode].data
        x = rng.normal(size=md.nx) * rng.choice([1, 10, 100])
        r = rng.normal(size=md.N * md.ny) * rng.choice([1, 30, 100])
        st_c, U_c, _ = c.solve_qp(mode, x, r)
        st_r, U_r, _ = ref.solve_qp(mode, x, r)
        limited += int(st_r) == TIME_LIMIT
        if (int(st_c), U_c.tobytes(), c.info()["work"]) != (int(st_r), U_r.tobytes(),
                                                              ref.last_info()["work"]):
            bad.append(i)
    assert bad == [] and limited >= 50


# ------------------------------------------------------------------ the randomized loop
def _random_reference(cfg, steps, seed):
    """Bank and sideslip levels held 0.5 to 3 s, within the bank limit and a few degrees of
    sideslip."""
    rng = np.random.default_rng(seed)
    ref, k = np.zeros((steps, 2)), 0
    while k < steps:
        hold = int(rng.uniform(0.5, 3.0) / cfg.sample_time)
        ref[k:k + hold] = (rng.uniform(-40.0, 40.0), rng.uniform(-3.0, 3.0))
        k += hold
    return ref


def _randomized_loop(built):
    """The randomized run: (log, work of every step, budget)."""
    from rollmpc_codegen.sim.simulate import run_closed_loop

    cfg, c = built.model.config, built.fresh_c()
    works = []
    log = run_closed_loop(cfg, c, reference=_random_reference(cfg, 3000, 3), noise_std=0.05,
                          seed=3, info=lambda: works.append(c.info()["work"]) or c.info())
    return log, works, built.ctx["solver"]["work_budget"]


def _assert_safe(log, works, budget, md):
    assert max(works) <= budget
    assert np.all(np.isfinite(log.u))
    assert np.all(log.u >= md.u_min - 1e-6) and np.all(log.u <= md.u_max + 1e-6)
    assert set(np.unique(log.status)) <= {OPTIMAL, TIME_LIMIT}


def test_randomized_loop_stays_within_a_small_budget(fw_small):
    log, works, budget = _randomized_loop(fw_small)
    _assert_safe(log, works, budget, fw_small.model.modes[0].data)
    # the budget binds: measured 32 (float; 150 before an optimal final working set was
    # accepted without polish)
    assert np.count_nonzero(log.status == TIME_LIMIT) >= 20


def test_randomized_loop_recovers_within_the_default_budget(fw_default):
    log, works, budget = _randomized_loop(fw_default)
    _assert_safe(log, works, budget, fw_default.model.modes[0].data)
    # auto: half of Ts = 20 ms at 168 MHz, 20 cycles per unit, less the step outside the solver
    assert budget == 84000 - STEP_FIXED_UNITS
    assert 1 <= np.count_nonzero(log.status == TIME_LIMIT) <= 120  # measured 3 (float), 38
    longest = longest_run(log.status)
    assert longest <= RECOVERY_SAMPLES, longest


def test_quad_attitude_recovers_and_holds_its_tilt_bound(build_root):
    """The design whose hardest steps need more than the default budget: every step within
    it, the TIME_LIMIT runs no longer than measured, the hard tilt bound held through them
    (a TIME_LIMIT before the dual active set has a point commands the shifted plan)."""
    from rollmpc_codegen.sim.simulate import run_closed_loop

    built = Built(QUAD, "float", build_root)
    c, works = built.fresh_c(), []
    log = run_closed_loop(built.model.config, c,
                          info=lambda: works.append(c.info()["work"]) or c.info())
    mode = built.model.config.modes[0]
    _assert_safe(log, works, built.ctx["solver"]["work_budget"], built.model.modes[0].data)
    assert np.count_nonzero(log.status == OPTIMAL) >= QUAD_OPTIMAL
    assert 1 <= longest_run(log.status) <= QUAD_RECOVERY_SAMPLES
    bounded = np.isfinite(mode.y_max)
    assert np.all(log.y[:, bounded] <= mode.y_max[bounded])
    assert np.all(log.y[:, bounded] >= mode.y_min[bounded])


# ------------------------------------------------------------------ config
@pytest.mark.parametrize("solver, key", [
    ({"work_budget": "fast"}, "solver.work_budget"),
    ({"work_budget": 0}, "solver.work_budget"),
    ({"budget_share": 1.5}, "solver.budget_share"),
    ({"budget_share": 0}, "solver.budget_share"),
])
def test_budget_keys_are_checked(solver, key):
    import yaml

    from rollmpc_codegen.config import parse

    data = yaml.safe_load(FW.read_text())
    data["solver"] = solver
    assert config_error(data, parse).key == key


def test_a_budget_below_the_unconstrained_step_is_refused():
    from rollmpc_codegen.config import ConfigError, load
    from rollmpc_codegen.pipeline import load_model_from_config

    cfg = load(FW)
    cfg = dataclasses.replace(cfg, solver=dataclasses.replace(cfg.solver, work_budget=100))
    with pytest.raises(ConfigError) as exc:
        load_model_from_config(cfg)
    assert exc.value.key == "solver.work_budget"
    assert "a step without active bounds may charge" in exc.value.problem  # and what fits:
    assert "; what fits: " in exc.value.problem and "solver.work_budget >= " in exc.value.problem
