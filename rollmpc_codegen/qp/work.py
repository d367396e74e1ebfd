"""The solver's work units and its budget (the generated README, "Work budget").

A work unit is about one multiply-add with its loads.  The generated solver charges the
closed-form cost of each costly function to ``ws->work`` and checks every unit of work
against ``solver.work_budget`` before it starts, with the same formulas as an upper bound.
Each formula is declared once here (:func:`~.work_formula.formula`): the reference
(:mod:`rollmpc_codegen.reference`) calls it to charge the same numbers at the same places,
and ``templates/solver/work.c.j2`` renders it as the C function of the same name.  The
generator derives the default budget from the sample time and the clock and checks that
a budget leaves room for the unconstrained step (budget.py).

``m`` below is a mode's stored sizes (:class:`~rollmpc_codegen.qp.storage.ModeData`:
n, m, n_yq, ny, nu, nx, nt).  All arithmetic is on unsigned 32-bit integers in the C; the
generator keeps every bound below 2**31 (budget.py, :func:`check_work_budget`).
"""
from __future__ import annotations

from ..config.schema import WORK_BUDGET_AUTO
from .work_formula import either, formula, larger, named, smaller, summed

# The cycles a work unit costs are the target core's calibration (parts.py
# Core.work_unit_cycles: the auto budget's divisor; the M4F's is 20): cycles_per_work_unit().
# The fewest measured on a heavy M4F step (uav_roll's max 12.55, docs/target.md): a budget
# that takes longer than a sample period even at this rate misses its deadline whenever a
# solve spends it (qp/sanity.py warns)
FEWEST_CYCLES_PER_WORK_UNIT = 12.0
WORK_LIMIT = 2**31  # every count and bound stays below it (uint32 in the C)
UNBOUNDED_WORK = WORK_LIMIT - 1  # the largest budget: in effect none
# rows the dual active set adds per scan of every row (it pays the scan and the corrected
# point once for them); measured on fw_lateral, chain_soft, thermal_zones_rate: 4 cuts
# their largest work per solve by 23 %, 26 %, 39 %, 8 or 16 less
ADD_BATCH = 4
# a step's costs outside the solver's count, in units (P_step, the scheduler, the observers,
# the first move: 2,700 cycles on the emulated M4F, footprint.py's fit, 135 of its units):
# the auto budget leaves them out of the share, since at a 50 us sample they are a third
# of it (tests/data/newuser/buck.yaml)
STEP_FIXED_UNITS = 135
# what afford() charges each unit of work it grants, beside the unit's formula: the calls,
# checks, copies and clears around its operations. They are a few hundred cycles a unit on
# the emulated M4F whatever its size, so they dominate a small QP's units.
UNIT_CALL_WORK = 15


@formula(design={"factor": "hq_work_factor"})
def hq_work(m, factor: int) -> int:
    """One read of H through hq(): the Woodbury sum of nt terms, ``factor`` times (2 with
    Δu rows: a Δu quantity is a difference of reads)."""
    return (m.nt + 4) * factor


# predict_outputs(): one contiguous dot product per output, two outputs at a time, runs
# at 6.5 cycles per multiply-add in its inner loop on the emulated M4F (float, -O2), 7.3-9.3
# per call with its per-stage setup (quad_attitude, chain_runtime_bounds, fw_lateral's
# single bounded output), so it is charged 3/5 of a unit per multiply-add (11.5-14.4
# cycles per unit), and a unit per output. At 1/2 fw_lateral's heavy steps ran at 20.13
# cycles per unit, over the M4F's 20.
PREDICT_UNITS_PER_OP = (3, 5)


@formula()
def predict_work(m) -> int:
    """predict_outputs(): the Markov sum of each output with rows over the stages before
    it, at PREDICT_UNITS_PER_OP of a unit per multiply-add, and a unit per output."""
    # (the docstring is the C comment of every design; with general constraints the sum
    # also holds predict_signals()' z_pred_ops multiply-adds and a unit per signal
    # quantity: sizes a design without them lacks read 0 and fold away)
    stages = named("stages", m.n_yq // m.ny)
    return ((m.ny_pred * m.nu * stages * (stages + 1) // 2 + m.z_pred_ops)
            * PREDICT_UNITS_PER_OP[0] // PREDICT_UNITS_PER_OP[1] + m.n_yq + m.nzq)


@formula()
def certificate_read_work(m) -> int:
    """What outputs_certified() charges before it reads a row: th's n values (the ny output
    bounds of the last stage ride with them) and the nzq signal bounds."""
    # (without the nzq a design with signal rows passed its budget by up to 52)
    return m.n + m.nzq


@formula()
def certificate_work(m) -> int:
    """The most outputs_certified() charges: certificate_read_work() and, when the largest
    bound does not clear every row at once, the rows up to the first it cannot clear."""
    return certificate_read_work(m) + m.m


@formula()
def scan_work(m) -> int:
    """A check of every row at a point (violated_outside(), most_violated()): the
    certificate, the prediction it may need, and the rows."""
    return 2 * m.m + certificate_work(m) + predict_work(m)


@formula()
def final_check_work(m) -> int:
    """What the dual active set still spends to accept its final working set at its
    scanned point without polish(): the output certificate and converged()."""
    return certificate_work(m) + m.m


@formula(uint=("nin", "nout"))
def correct_cost(m, count: int, nin: int, nout: int) -> int:
    """correct() over ``count`` rows whose multipliers reach ``nin`` input and ``nout``
    output quantities: an n-long column each, and the Woodbury term."""
    # (nout counts signal quantities too, and their nzq accumulators are cleared)
    n, nt = named("n", m.n), named("nt", m.nt)
    return count + 2 * n + m.n_yq + m.nzq + n * (nin + nout + nt) + nt * nin


@formula()
def correct_work(m, count: int) -> int:
    """The most correct() can cost over ``count`` rows (what afford() asks for): at most
    min(2 count, n) input and min(count, nyq) output quantities; it charges
    correct_cost() of the quantities it met."""
    # (with signal quantities: min(count, nyq + nzq) output and signal quantities)
    nin = named("nin", smaller(2 * count, m.n))
    nout = named("nout", smaller(count, m.n_yq + m.nzq))
    return correct_cost(m, count, nin, nout)


@formula(design={"factor": "hq_work_factor"})
def sweep_work(m, count: int, factor: int) -> int:
    """One Gauss-Seidel sweep over ``count`` rows."""
    return count * count * hq_work(m, factor) + 8 * count


@formula()
def soft_mode(m) -> int:
    """1 in a mode with soft rows (its working set holds their slack rows: w_cap > n), else
    0 (w_cap is absent, 0, in a build without soft rows)."""
    return larger(smaller(m.w_cap, m.n + 1), m.n) - m.n


@formula()
def finish_work(m) -> int:
    """finish(): the finite check and clamp of the plan, the multipliers cleared after a
    failed sample and, in a mode with soft rows, the plan's slacks; always paid, so every
    check reserves it."""
    # (on the emulated M4F the check and clamp take about 25 cycles an input, a cleared
    # multiplier 3 and a row's slack about 18: fw_lateral's finish() 9.4 k cycles at n = 80,
    # m = 400; 2n + 2m before, 4.4 cycles a unit on pmsm_speed's stopped samples)
    return 2 * m.n + m.m // 2 + soft_mode(m) * m.m
# The dense kernels of linalg.c run faster per operation than a unit (H reads, row scans:
# ~14 cycles): on the emulated M4F (float, -O2, orders 10-80) a Cholesky takes 5.3-6.2
# cycles per chol_ops() operation (7.4 at order 5), a forward solve 6.9-7.1 and a back
# solve 9.5-11.5 per tri_ops() one (`python -m rollmpc_codegen.target.kernel_cycles`:
# the kernels called alone on the emulator). Their charges are these fractions of a unit per operation
# (7.6 and 11.4 cycles at the M4F's 20 per unit); checked on whole steps with rollmpc report.
CHOL_UNITS_PER_OP = (2, 5)
TRI_UNITS_PER_OP = (3, 5)
# a forward solve alone (chol_lsolve_from(), 6.9-7.1 cycles per operation): Y's rows in
# the primal solve, at 8 cycles per operation at the M4F's 20 per unit
FORWARD_UNITS_PER_OP = (2, 5)
# primal_solve(), in sixths of a unit per operation (one division, so the C's
# intermediates stay integers): its Cholesky at 2/6 (6.3 cycles; the kernel takes 5.3-6.2
# from order 10), its Schur complement, gathers and products at 3/6 (9.5; gather_dot4()
# runs at 7-8.5 cycles per multiply-add). Checked on whole steps with rollmpc report:
# quad_attitude's counted steps run at <= 16.6 cycles per unit and uav_roll's at <= 13.6
# (at 148a40f); (3/6, 2/6) let quad_attitude's step 420 reach 22.31, all at 2/5 21.05.
PRIMAL_SIXTHS_PER_OP = (2, 3)  # (factor, loops)
# each primal_solve() call, beside its operations: its fixed bookkeeping and, in the free
# form, the calls of the product per row and run of bound inputs. Without it the
# heavy steps of the n = 40 examples ran at 21.7 (quadruple_tank) and 21.2 (thermal_zones)
# cycles per unit (docs/solver.md, "Work budget").
PRIMAL_CALL_UNITS = 200
# and per input, in operations at 3/6 of a unit (4 units an input): the passes over the
# inputs' roles each call makes (mark_bound_inputs(), primal_diff(), primal_order(),
# gather_bound(), the finish of every free input; primal_old_order() and place_tail() when
# they run), 8-14 cycles each on the M4F; c172_roll's step 2911 (n = 100, three calls of
# 6-14 bound inputs) spends about 85 cycles per input and call in them
PRIMAL_INPUT_OPS = 8
# a call of packed_range_dot() in the free form's product, in operations at 3/6 of a unit
# (2 units, ~40 cycles: its setup and the tail of its unrolled loop)
PRIMAL_CALL_OPS = 4


@formula()
def chol_ops(n: int) -> int:
    """The operations of a Cholesky factorisation of order n (n^3/6 multiply-adds, a
    division per entry)."""
    return n * n * n // 6 + 2 * n * n + 4 * n


@formula()
def tri_ops(n: int) -> int:
    """The operations of one triangular solve of order n."""
    return n * n // 2 + 4 * n


@formula()
def chol_work(n: int) -> int:
    """A Cholesky factorisation of order n, at CHOL_UNITS_PER_OP of a unit per operation:
    the dense kernels of linalg.c run faster per operation than a unit."""
    return chol_ops(n) * CHOL_UNITS_PER_OP[0] // CHOL_UNITS_PER_OP[1]


@formula()
def tri_work(n: int) -> int:
    """One triangular solve of order n, at TRI_UNITS_PER_OP of a unit per operation."""
    return tri_ops(n) * TRI_UNITS_PER_OP[0] // TRI_UNITS_PER_OP[1]


@formula()
def rank_one_work(n: int) -> int:
    """chol_rank_one() on a trailing block of order n: a rotation per column."""
    return 3 * n * n // 2 + 10 * n


@formula()
def delete_work(k: int, n: int) -> int:
    """chol_delete() of row k from order n: the rows below move up, then one rank-one
    update."""
    return (n * n - k * k) // 2 + n + rank_one_work(larger(n - 1 - k, 0))


@formula()
def primal_delete_work(k: int, n: int, nt: int) -> int:
    """chol_delete() of the primal factor's row k from order n, carrying Y's nt columns."""
    return delete_work(k, n) + 4 * nt * (n - k)


@formula(design={"factor": "hq_work_factor"})
def factor_work(m, nw: int, factor: int) -> int:
    """factor_working_set() of nw rows: their H entries, then the factorisation."""
    return nw * (nw + 1) // 2 * hq_work(m, factor) + chol_work(nw)


@formula(design={"factor": "hq_work_factor"})
def append_work(m, nw: int, factor: int) -> int:
    """append_row() at position nw: the column H_Wp and its diagonal, a forward solve."""
    return (nw + 1) * hq_work(m, factor) + tri_work(nw) + nw


@formula(design={"factor": "hq_work_factor"})
def independent_work(m, nw: int, factor: int) -> int:
    """independent_rows() on nw rows, at most: each appended to all the rows before it."""
    return summed(nw, lambda k: append_work(m, k, factor))


@formula()
def primal_work(m, k: int, start: int = 0, bound_form: bool = True,
                bound_runs: int = 0) -> int:
    """primal_solve() with a factor of order k whose rows (and Y's) from ``start`` are
    factored again (0: a new factor): its Cholesky at PRIMAL_SIXTHS_PER_OP[0], the nt
    forward solves of Y's new rows at FORWARD_UNITS_PER_OP, the two solves of the
    right-hand side as tri_work(), the rows of A, the terminal Schur complement and its
    solves, the products and PRIMAL_INPUT_OPS per input (the passes over the inputs) at
    PRIMAL_SIXTHS_PER_OP[1], and PRIMAL_CALL_UNITS per call. The free
    form's product -S_FB d_B is what it does: k (n - k) multiply-adds, nt (n - k) for
    V_B d_B, n for the point, and PRIMAL_CALL_OPS per free row and run of bound inputs
    (``bound_runs``: sparse_rows_dot() calls packed_range_dot() for each); its
    multipliers are charged by free_multipliers() (multipliers_work()). The bound form's
    product S^-1_FB beta - Uv_F' nu is what it does too: (k + nt) multiply-adds for each
    free row (up to three rows more: gather_dot4() sums four rows a call, the last
    repeated), 2 n to gather the bound inputs and walk the list, and PRIMAL_CALL_OPS per
    call."""
    n, nt = named("n", m.n), named("nt", m.nt)
    factor = named("factor", chol_ops(k) - chol_ops(start) + chol_ops(m.nt))
    fours = (n - k + 3) // 4
    products = named("products", either(bound_form,
                                        4 * fours * (k + nt) + PRIMAL_CALL_OPS * fours + 2 * n,
                                        (k + nt) * (n - k) + n
                                        + PRIMAL_CALL_OPS * k * bound_runs))
    loops = named("loops", (k * k - start * start) // 2 + nt * nt * k // 2
                  + 2 * tri_ops(m.nt) + 3 * nt * n + products + PRIMAL_INPUT_OPS * n)
    y_rows = named("y_rows", nt * (tri_ops(k) - tri_ops(start)))
    return ((PRIMAL_SIXTHS_PER_OP[0] * factor + PRIMAL_SIXTHS_PER_OP[1] * loops) // 6
            + y_rows * FORWARD_UNITS_PER_OP[0] // FORWARD_UNITS_PER_OP[1]
            + 2 * tri_work(k) + PRIMAL_CALL_UNITS)


@formula()
def multipliers_work(m, nw: int) -> int:
    """free_multipliers() on nw rows, charged when it runs: a free-form polish computes
    them only at a feasible point, not after every correction."""
    return PRIMAL_SIXTHS_PER_OP[1] * nw * (m.n + m.nt) // 6


@formula()
def primal_reserve(m) -> int:
    """What polish() still spends after a primal solve: its check of every row and
    accept()."""
    return scan_work(m) + m.m


# guess_reversed() samples three rows of a free-form guess of at least this many rows: on
# a smaller one the sample would cost about as much as free_multipliers() itself
GUESS_SAMPLE_MIN = 8


@formula()
def guess_sample_work(m, rows: int) -> int:
    """guess_reversed() on ``rows`` rows: each multiplier row by row costs about twice one
    from free_multipliers()'s symmetric product on the M4F."""
    return multipliers_work(m, 2 * rows)


@formula()
def trim_work(m, nw: int) -> int:
    """trim_guess() on a guess of nw rows at most: its scans of the guess (twice) and of
    every row."""
    return m.m + 2 * nw


@formula()
def add_step_work(nw: int) -> int:
    """One step of add_to_set() on nw rows: two triangular solves, then a row leaves,
    switches state or joins."""
    leave = named("leave", delete_work(0, nw))
    flip = named("flip", rank_one_work(nw))
    return 2 * tri_work(nw) + 5 * nw + larger(leave, flip)


def unconstrained_work(m, summed: int, runs: int, has_outputs: bool) -> int:
    """unconstrained(): ``summed`` stages outside the longest run of equal w, ``runs`` runs."""
    return (m.n_yq * m.ny + m.n * m.nx + m.n * m.ny * (summed + runs + 2)
            + (m.n_yq * m.nx if has_outputs else 0))


def free_response_work(m) -> int:
    """signal_free_response(): Zx x, and Zr r where rows follow the reference (0 without
    signal quantities)."""
    return m.nzq * m.nx + (m.nzq * m.ny if m.has_signal_reference else 0)


def base_work(m, has_outputs: bool) -> int:
    """The most a solve spends before its first check: th0 (every stage its own run), the
    signals' free response, the slacks K, the output certificate and prediction, and the
    final finish()."""
    last = m.n_yq // m.ny - 1
    return (unconstrained_work(m, last, last, has_outputs) + free_response_work(m) + 3 * m.m
            + certificate_work(m) + predict_work(m) + finish_work(m))


def largest_unit(m, wcap: int, factor: int) -> int:
    """An upper bound of every count the C forms (its intermediates are uint32): the
    cube of the working-set capacity, a factorisation, a sweep over every row."""
    return max(wcap ** 3, factor_work(m, wcap, factor) + append_work(m, wcap, factor),
               independent_work(m, wcap, factor),
               sweep_work(m, m.m, factor) + correct_work(m, m.m) + 2 * scan_work(m),
               CHOL_UNITS_PER_OP[0] * chol_ops(wcap),
               6 * (primal_work(m, m.n, 0, True) + 1), add_step_work(wcap))


def free_step_work(m, certified: bool = True) -> int:
    """What a solve charges when no bound is active and the reference is held over the
    horizon (the scenario between its steps): th0 in one run, the slacks, the output
    certificate (with output rows: the largest bound clears every row at once) and, when
    that fails, the output prediction, then finish().  The same step that footprint.py
    estimates in cycles: one figure in both (docs/checks.md, "One figure per step");
    base_work() is its worst case."""
    rows = m.has_output_rows
    return (unconstrained_work(m, 0, 1, rows) + 2 * m.m
            + (certificate_read_work(m) if rows else 0)
            + (0 if certified or not rows else m.m + predict_work(m)) + finish_work(m))


def cycles_per_work_unit(cfg) -> float:
    """The estimated cycles of a work unit on ``cfg``'s target core, in the precision its
    FPU runs the design (parts.py Core.work_unit_cycles)."""
    return cfg.target.core_decl.cycles_per_work_unit(cfg.precision)


def auto_work_budget(sample_time: float, share: float, cpu_mhz: float,
                     cycles_per_unit: float) -> int:
    """``solver.work_budget: auto``: ``share`` of the sample time at ``cpu_mhz``, in units,
    less the step's costs outside the solver's count (STEP_FIXED_UNITS)."""
    return max(int(sample_time * share * cpu_mhz * 1e6 / cycles_per_unit) - STEP_FIXED_UNITS, 0)


def work_budget_of(cfg) -> int:
    """The work budget of ``cfg`` (a ControllerConfig) in units: the given one, or auto's
    on its target core (without the polish, the paper's variants: none, their sweep cap
    bounds them)."""
    s = cfg.solver
    if s.work_budget != WORK_BUDGET_AUTO:
        return int(s.work_budget)
    return (auto_work_budget(cfg.sample_time, s.budget_share, cfg.target.cpu_mhz,
                             cycles_per_work_unit(cfg)) if s.polish else UNBOUNDED_WORK)
