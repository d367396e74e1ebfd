"""The solver's work units and its budget (docs/solver.md, "Work budget").

A work unit is about one multiply-add with its loads.  The generated solver charges the
closed-form cost of each costly function to ``ws->work`` and checks every unit of work
against ``solver.work_budget`` before it starts, with the same formulas as an upper bound
(``templates/solver/work.c.j2``).  This module is their Python side, with the C's names:
the reference (:mod:`rollmpc_codegen.reference`) charges the same numbers at the same
places, and the generator derives the default budget from the sample time and the clock
and checks that a budget leaves room for the unconstrained step.

``m`` below is a mode's stored sizes (:class:`~rollmpc_codegen.qp.storage.ModeData`:
n, m, n_yq, ny, nu, nx, nt).  All arithmetic is on unsigned 32-bit integers in the C; the
generator keeps every bound below 2**31 (:func:`check_work_budget`).
"""
from __future__ import annotations

from ..config.errors import ConfigError
from ..config.schema import WORK_BUDGET_AUTO

# The cycles a work unit costs are the target core's calibration (parts.py
# Core.work_unit_cycles: the auto budget's divisor; the M4F's is 20).
WORK_LIMIT = 2**31  # every count and bound stays below it (uint32 in the C)
UNBOUNDED_WORK = WORK_LIMIT - 1  # the largest budget: in effect none
# rows the dual active set adds per scan of every row (it pays the scan and the corrected
# point once for them); measured on fw_lateral, chain_soft, thermal_zones_rate: 4 cuts
# their largest work per solve by 23 %, 26 %, 39 %, 8 or 16 less
ADD_BATCH = 4


def hq_work(m, factor: int) -> int:
    """One read of H through hq() (``factor`` 2 with Δu rows: differences of reads)."""
    return (m.nt + 4) * factor


# predict_outputs(): one contiguous dot product per output, two outputs at a time, runs
# at 6.5 cycles per multiply-add in its inner loop on the emulated M4F (float, -O2), 7.3-9.3
# per call with its per-stage setup (quad_attitude, chain_runtime_bounds, fw_lateral's
# single bounded output), so it is charged 3/5 of a unit per multiply-add (11.5-14.4
# cycles per unit), and a unit per output. At 1/2 fw_lateral's heavy steps ran at 20.13
# cycles per unit, over the M4F's 20.
PREDICT_UNITS_PER_OP = (3, 5)


def predict_work(m) -> int:
    stages = m.n_yq // m.ny
    return (m.ny_pred * m.nu * stages * (stages + 1) // 2 * PREDICT_UNITS_PER_OP[0]
            // PREDICT_UNITS_PER_OP[1] + m.n_yq)


def scan_work(m) -> int:
    return 3 * m.m + m.n + predict_work(m)


def correct_cost(m, count: int, nin: int, nout: int) -> int:
    """correct() over ``count`` rows whose multipliers reach ``nin`` input and ``nout``
    output quantities: an n-long column each, and the Woodbury term."""
    return count + 2 * m.n + m.n_yq + m.n * (nin + nout + m.nt) + m.nt * nin


def correct_work(m, count: int) -> int:
    """The most correct() can cost over ``count`` rows (what afford() asks for): at most
    min(2 count, n) input and min(count, nyq) output quantities; it charges correct_cost()
    of the quantities it met."""
    return correct_cost(m, count, min(2 * count, m.n), min(count, m.n_yq))


def sweep_work(m, count: int, factor: int) -> int:
    return count * count * hq_work(m, factor) + 8 * count


def finish_work(m) -> int:
    return 2 * m.n + 2 * m.m


# The dense kernels of linalg.c run faster per operation than a unit (H reads, row scans:
# ~14 cycles): on the emulated M4F (float, -O2, orders 10-80) a Cholesky takes 5.3-6.2
# cycles per chol_ops() operation (7.4 at order 5), a forward solve 6.9-7.1 and a back
# solve 9.5-11.5 per tri_ops() one (`python -m rollmpc_codegen.target.kernel_cycles`:
# the kernels called alone on the emulator). Their charges are these fractions of a unit per operation
# (7.6 and 11.4 cycles at the M4F's 20 per unit); checked on whole steps with rollmpc report.
CHOL_UNITS_PER_OP = (2, 5)
TRI_UNITS_PER_OP = (3, 5)
# primal_solve(), in sixths of a unit per operation (one division, so the C's
# intermediates stay integers): its Cholesky at 2/6 (6.3 cycles; the kernel takes 5.3-6.2
# from order 10), its solves for nt + 1 right-hand sides, Schur complement, gathers and
# products at 3/6 (9.5). Fitted on whole steps with rollmpc report: the heavy steps of
# quad_attitude run at <= 17.93 cycles per unit and uav_roll's at <= 13.11; (3/6, 2/6)
# let quad_attitude's step 420 reach 22.31, all at 2/5 21.05.
PRIMAL_SIXTHS_PER_OP = (2, 3)  # (factor, loops)
# each primal_solve() call, beside its operations: the O(n) bookkeeping of the inputs'
# roles and the calls of the products per row and run of bound inputs. Without it the
# heavy steps of the n = 40 examples ran at 21.7 (quadruple_tank) and 21.2 (thermal_zones)
# cycles per unit (docs/solver.md, "Work budget").
PRIMAL_CALL_UNITS = 200
# a call of packed_range_dot() in the free form's product, in operations at 3/6 of a unit
# (2 units, ~40 cycles: its setup and the tail of its unrolled loop)
PRIMAL_CALL_OPS = 4


def chol_ops(n: int) -> int:
    """The operations of a Cholesky factorisation of order n."""
    return n * n * n // 6 + 2 * n * n + 4 * n


def tri_ops(n: int) -> int:
    """The operations of one triangular solve of order n."""
    return n * n // 2 + 4 * n


def chol_work(n: int) -> int:
    return chol_ops(n) * CHOL_UNITS_PER_OP[0] // CHOL_UNITS_PER_OP[1]


def tri_work(n: int) -> int:
    return tri_ops(n) * TRI_UNITS_PER_OP[0] // TRI_UNITS_PER_OP[1]


def rank_one_work(n: int) -> int:
    return 3 * n * n // 2 + 10 * n


def delete_work(k: int, n: int) -> int:
    return (n * n - k * k) // 2 + n + rank_one_work(max(n - 1 - k, 0))


def primal_delete_work(k: int, n: int, nt: int) -> int:
    """chol_delete() of the primal factor's row k from order n, carrying Y's nt columns."""
    return delete_work(k, n) + 4 * nt * (n - k)


def factor_work(m, nw: int, factor: int) -> int:
    return nw * (nw + 1) // 2 * hq_work(m, factor) + chol_work(nw)


def append_work(m, nw: int, factor: int) -> int:
    return (nw + 1) * hq_work(m, factor) + tri_work(nw) + nw


def independent_work(m, nw: int, factor: int) -> int:
    """independent_rows() on nw rows, at most: each appended to all the rows before it."""
    return sum(append_work(m, k, factor) for k in range(nw))


def primal_work(m, nw: int, k: int, start: int = 0, bound_form: bool = True,
                bound_runs: int = 0) -> int:
    """primal_solve() with a factor of order k whose rows (and Y's) from ``start`` are
    factored again (0: a new factor): its Cholesky, its solves for the nt + 1 right-hand
    sides, the terminal Schur complement and its products, at PRIMAL_SIXTHS_PER_OP, and
    PRIMAL_CALL_UNITS. The free form's product -S_FB d_B is what it does: k (n - k)
    multiply-adds, nt (n - k) for V_B d_B, n for the point, and PRIMAL_CALL_OPS per free
    row and run of bound inputs (``bound_runs``: sparse_rows_dot() calls
    packed_range_dot() for each); its multipliers are charged where they are computed
    (multipliers_work()). The bound form pays 2 n (k + nt) and nw (n + nt) for its
    product over the packed S^-1, whose calls per free row and run of bound inputs its
    operations alone undercount (quad_attitude's bound-form steps run at <= 18.6 cycles
    per unit with it)."""
    nt, n = m.nt, m.n
    factor = chol_ops(k) - chol_ops(start) + chol_ops(nt)
    products = (2 * n * (k + nt) if bound_form else
                (k + nt) * (n - k) + n + PRIMAL_CALL_OPS * k * bound_runs)
    loops = ((k * k - start * start) // 2
             + 2 * (nt * (tri_ops(k) - tri_ops(start)) + tri_ops(k)) + nt * nt * k // 2
             + 2 * tri_ops(nt) + 3 * nt * n + products)
    return ((PRIMAL_SIXTHS_PER_OP[0] * factor + PRIMAL_SIXTHS_PER_OP[1] * loops) // 6
            + PRIMAL_CALL_UNITS + (multipliers_work(m, nw) if bound_form else 0))


def multipliers_work(m, nw: int) -> int:
    """free_multipliers() on nw rows, charged when it runs: a free-form polish computes
    them only at a feasible point, not after every correction."""
    return PRIMAL_SIXTHS_PER_OP[1] * nw * (m.n + m.nt) // 6


def primal_reserve(m) -> int:
    """What polish() still spends after a primal solve: its check of every row and
    accept()."""
    return scan_work(m) + m.m


# guess_reversed() samples three rows of a free-form guess of at least this many rows: on
# a smaller one the sample would cost about as much as free_multipliers() itself
GUESS_SAMPLE_MIN = 8


def guess_sample_work(m, rows: int) -> int:
    """guess_reversed() on ``rows`` rows: each multiplier row by row costs about twice one
    from free_multipliers()'s symmetric product on the M4F."""
    return multipliers_work(m, 2 * rows)


def trim_work(m, nw: int) -> int:
    """trim_guess() on a guess of nw rows at most: its scans of the guess (twice) and of
    every row."""
    return m.m + 2 * nw


def add_step_work(nw: int) -> int:
    return 2 * tri_work(nw) + 5 * nw + max(delete_work(0, nw), rank_one_work(nw))


def unconstrained_work(m, summed: int, runs: int, has_outputs: bool) -> int:
    """unconstrained(): ``summed`` stages outside the longest run of equal w, ``runs`` runs."""
    return (m.n_yq * m.ny + m.n * m.nx + m.n * m.ny * (summed + runs + 2)
            + (m.n_yq * m.nx if has_outputs else 0))


def base_work(m, has_outputs: bool) -> int:
    """The most a solve spends before its first check: th0 (every stage its own run), the
    slacks K, the output certificate and prediction, and the final finish()."""
    last = m.n_yq // m.ny - 1
    return (unconstrained_work(m, last, last, has_outputs) + 4 * m.m + m.n + predict_work(m)
            + finish_work(m))


def largest_unit(m, wcap: int, factor: int) -> int:
    """An upper bound of every count the C forms (its intermediates are uint32): the
    cube of the working-set capacity, a factorisation, a sweep over every row."""
    return max(wcap ** 3, factor_work(m, wcap, factor) + append_work(m, wcap, factor),
               independent_work(m, wcap, factor),
               sweep_work(m, m.m, factor) + correct_work(m, m.m) + 2 * scan_work(m),
               CHOL_UNITS_PER_OP[0] * chol_ops(wcap),
               6 * (primal_work(m, m.n, m.n, 0, True) + 1), add_step_work(wcap))


def auto_work_budget(sample_time: float, share: float, cpu_mhz: float,
                     cycles_per_unit: float) -> int:
    """``solver.work_budget: auto``: ``share`` of the sample time at ``cpu_mhz``, in units."""
    return int(sample_time * share * cpu_mhz * 1e6 / cycles_per_unit)


def check_work_budget(cfg, modes, factor: int) -> int:
    """The budget of ``cfg`` (a ControllerConfig) in work units, checked against the
    unconstrained step of every mode (its ModeData in ``modes``): a budget below it could
    not even return the clamped unconstrained optimum."""
    s, target = cfg.solver, cfg.target
    per_unit = target.core_decl.cycles_per_work_unit(cfg.precision)
    budget = int(s.work_budget) if s.work_budget != WORK_BUDGET_AUTO else (
        auto_work_budget(cfg.sample_time, s.budget_share, target.cpu_mhz, per_unit)
        if s.polish else UNBOUNDED_WORK)  # the paper's variants: their sweep cap bounds it
    need = max(base_work(m, m.has_output_rows) for m in modes)
    for m in modes:
        if largest_unit(m, m.w_cap, factor) >= WORK_LIMIT:
            raise ConfigError("solver", f"mode {m.name}: its QP (n = {m.n}, m = {m.m}) is too "
                              f"large to count its work in 32 bits")
    if budget < need or budget >= WORK_LIMIT:
        how = (f"auto: {s.budget_share:g} of Ts = {cfg.sample_time:g} s at {target.cpu_mhz:g} "
               f"MHz, {per_unit:g} cycles per unit on the {target.core_decl.label}"
               if s.work_budget == WORK_BUDGET_AUTO else "given")
        raise ConfigError("solver.work_budget", f"{budget} work units ({how}) must be at least "
                          f"the {need} of the unconstrained step and below {WORK_LIMIT}")
    return budget
