"""NumPy reference of the generated QP solver, operation by operation.

It mirrors ``templates/solver.c.j2``, a module per partial of ``templates/solver/``:
:mod:`.signals`, :mod:`.hq`, :mod:`.dot`, :mod:`.unconstrained`, :mod:`.rows` (with
``violated_rows``),
:mod:`.factor_update`, :mod:`.soft_rows`, :mod:`.sweeps`, :mod:`.primal_rows`,
:mod:`.polish_primal`, :mod:`.polish_dual`, :mod:`.kkt`, :mod:`.seeds`, :mod:`.guess`,
:mod:`.polish`,
:mod:`.resume`, :mod:`.active_set`, and this module for ``qp_solve``; ``bounds`` is
:mod:`rollmpc_codegen.features.runtime_bounds`, ``work`` :mod:`rollmpc_codegen.qp.work`
and ``linalg.c.j2`` :mod:`.linalg` (:mod:`.mirror` declares the rule and its exceptions).
Each method is named after the C function it mirrors.
The reference uses the same storage-precision numbers (from :mod:`rollmpc_codegen.qp.storage`),
the same loops in the same order, scalars of the storage dtype (float32 where the C uses
float), and *sequential* sums (:func:`~.linalg.seqsum`, never BLAS or pairwise summation).
The C is compiled with ``-ffp-contract=off`` so that it, too, rounds every product and
every sum.  Agreement is therefore bit for bit, which the tests check.

Where the C skips work that cannot change a result (the output prediction when
``outputs_certified()`` proves no output row can be violated), the reference does the
work anyway: an unsound certificate would then show up as a bit-exactness failure.
"""
from __future__ import annotations

import numpy as np

from ..features.move_blocking import next_input_quantity
from ..features.soft_constraints import multiplier_slack
from ..qp.storage import ModeData
from ..qp.work import (UNIT_CALL_WORK, correct_work, finish_work, predict_work, scan_work,
                       sweep_work)
from ..status import INACCURATE, INFEASIBLE, MAX_ITER, NUMERICAL, OPTIMAL, TIME_LIMIT
from .active_set import ActiveSetMixin
from .hq import hessian_reads
from .guess import GuessMixin
from .polish import PolishMixin
from ..solver_codes import (CHOL_NONE, COLD_START, GUESS_CAPPED, GUESS_HANDED_OVER, LAMBDA_LIMIT,
                            OUT_OF_WORK, OUT_OF_WORK_AT_TH0)
from .polish_dual import DualPolishMixin
from .kkt import KktMixin
from .polish_primal import PrimalPolishMixin
from .resume import ResumeMixin
from .rows import RowsMixin
from .seeds import SeedsMixin
from .signals import SignalsMixin
from .soft_rows import SoftRowsMixin
from .sweeps import SweepsMixin
from .unconstrained import UnconstrainedMixin, output_prediction


class LastPlan:
    """P_ctrl's U, plan_mode and plan_age: the last plan, the mode it was planned for, and
    the samples since it was optimal (the horizon: no plan, as the C's P_HORIZON)."""

    def __init__(self, horizon: int):
        self.U, self.mode, self.none = np.zeros(0), 0, horizon
        self.age = horizon

    def forget(self):
        """P_init(), or a switch of mode: no plan to fall back to."""
        self.age = self.none


class SolverRef(SignalsMixin, UnconstrainedMixin, RowsMixin, SoftRowsMixin, SweepsMixin,
                PrimalPolishMixin, DualPolishMixin, KktMixin, SeedsMixin, GuessMixin, PolishMixin,
                ResumeMixin, ActiveSetMixin):
    """Reference of ``P_qp_solve`` for one mode; holds that mode's warm-start multipliers
    and shares the controller's :class:`LastPlan` with the other modes' solvers.

    The mixins are its parts, one per partial; they share the state set up here."""

    def __init__(self, md: ModeData, solver_ctx: dict, mode: int = 0,
                 last_plan: LastPlan | None = None, build_rate_rows: bool | None = None):
        self.md = md
        # the build's has_rate_rows (some mode has Δu rows): that mode's own, alone
        self.build_rate_rows = md.has_rate_rows if build_rate_rows is None else build_rate_rows
        self.th_solved = None
        self.guess_left = 0  # ws->guess_left: see polish.drop_negative_tracked()
        self.dt = md.Kx.dtype.type
        dt = self.dt
        s = solver_ctx
        self.reduced, self.warm, self.polish_on = s["reduced"], s["warm_start"], s["polish"]
        self.polish_first = s.get("polish_first", False)
        self.omega, self.sigma, self.delta = dt(s["omega"]), dt(s["sigma"]), dt(s["delta"])
        self.tol = dt(s["feasibility_tol"])
        self.max_iter, self.polish_every, self.polish_max = (
            s["max_iterations"], s["polish_every"], s["polish_max"])
        self.limit = dt(LAMBDA_LIMIT)
        self.active_set = s.get("active_set", False)
        self.active_set_max = s.get("active_set_max", 0)
        self.dep_tol = dt(s.get("dependence_tol", 0.0))
        self.Sinv, self.S, self.H, self.Hdiag = hessian_reads(md)
        self.Gam, self.expand = output_prediction(md)
        self.has_out, self.has_rate = md.has_output_rows, md.has_rate_rows
        # rows the C predicts on line (its has_pred(): output or signal rows)
        self.has_pred = md.has_output_rows or md.has_signal_rows
        self.lam = np.zeros(md.m, md.Kx.dtype)
        # the controller's last plan (shared by its modes' solvers, as P_ctrl's U), for a
        # TIME_LIMIT with nothing better than th0 (fallback_point())
        self.stages = md.n_yq // md.ny
        self.mode_index, self.from_plan = mode, False
        self.last_plan = last_plan or LastPlan(self.stages)
        # each input's value one stage later: the rule of the shifted warm start's rows
        blocks = ((1,) * self.stages if md.stage_block is None
                  else tuple(np.bincount(md.stage_block)))
        self.next_input = next_input_quantity(blocks, md.nu)
        self.one, self.zero = dt(1.0), dt(0.0)
        # the bound data: baked (md), or live with runtime_bounds (ControllerRef.set_bounds)
        self.row_c, self.u_min, self.u_max = md.row_c, md.u_min, md.u_max
        # soft output rows (soft_of() per row): w = 1/(2 l2) (0: hard) and l1; the slack
        # states of the working-set rows (ws->slack_on); the working-set capacity
        self.soft_l1, self.soft_w = md.soft_rows()
        self.soft = bool(np.any(self.soft_w > 0))
        self.slack_on = np.zeros(md.m, bool)
        self.wcap = md.w_cap if self.soft else md.n
        # ws->chol and what it holds (polish_dual.CHOL_*), kept across the polish's steps
        # and from one QP of the mode to the next (forget_factor()); chol_set: the rows of a
        # dual factor (the C's wset[0..chol_n)); chol_rows: the rows still valid after a
        # factor from scratch broke down
        self.chol = np.zeros(self.wcap * (self.wcap + 1) // 2, md.Kx.dtype)
        self.chol_set = np.zeros(0, np.int64)
        self.chol_holds, self.chol_rows = CHOL_NONE, 0
        self.slack_max, self.slack_rows = self.zero, 0
        # the work count of the last solve (ws->work; qp/work.py) and its budget
        self.budget, self.hq_factor = s["work_budget"], s["hq_work_factor"]
        self.add_batch = s["add_batch"]
        self.work, self.out_slacks_ok, self.gam_out_min = 0, False, self.limit
        self.work_limit, self.stop = self.budget, None

    def afford(self, need):
        """Mirror of afford(): can the running part still pay ``need`` units and finish()?
        A granted unit pays UNIT_CALL_WORK at once."""
        used = self.work + finish_work(self.md) + UNIT_CALL_WORK
        if used <= self.work_limit and need <= self.work_limit - used:
            self.work += UNIT_CALL_WORK
            return True
        return False

    def fallback_point(self, th0):
        """Mirror of fallback_point(): the last plan shifted one stage while it is younger
        than the horizon (with move blocking, each block from the block of its first stage
        + 1), else th0."""
        plan = self.last_plan
        if plan.mode != self.mode_index or plan.age >= self.stages - 1:
            return th0
        self.from_plan = True
        return plan.U[:self.md.n][self.next_input]

    def inputs_only(self):
        """Mirror of the inputs_only() macro: every row of the mode is an input bound (a
        build with Δu rows: never)."""
        return not self.build_rate_rows and self.md.m_box == self.md.m

    def time_limit_at_th0(self, th0, polished):
        """Mirror of time_limit_at_th0(): TIME_LIMIT at fallback_point() or, with input
        rows only, at this solve's last primal point; lam where a polish stopped."""
        if self.inputs_only() and self.th_solved is not None:
            th = self.th_solved
        else:
            th = self.fallback_point(th0)
        if polished:
            self.keep_progress(self.lam)
        return self.finish(th, th0, TIME_LIMIT)

    def keep_plan(self, status, U):
        """Mirror of keep_plan(): an optimal plan, or the shifted one a TIME_LIMIT fell
        back to (a sample older); any other status leaves none."""
        plan = self.last_plan
        if status == OPTIMAL or (status == TIME_LIMIT and self.from_plan):
            plan.U = U.copy()
            plan.age = 0 if status == OPTIMAL else plan.age + 1
        else:
            plan.age = plan.none
        if status not in (OPTIMAL, TIME_LIMIT):  # no warm start after a failed sample
            self.forget_factor()
        plan.mode = self.mode_index

    def forget_factor(self):
        """Mirror of forget_factor(): no factor of an earlier QP to start from."""
        self.chol_holds, self.factor_rows = CHOL_NONE, None

    def solve_mode(self, x, r):
        """Mirror of solve_mode(): qp_solve() (from the factor the last QP left, if that QP
        was this mode's: the last plan's mode), then keep_plan()."""
        if self.last_plan.mode != self.mode_index:
            self.forget_factor()
        out = self.qp_solve(x, r)
        self.keep_plan(out[0], out[1])
        return out

    def qp_solve(self, x, r):
        """Mirror of P_qp_solve(): returns (status, U, iterations, polish_iterations, active);
        its work is ``work``."""
        md = self.md
        self.from_plan = False
        self.th_solved = None  # ws->th_solved: the last primal solve's point, if any
        x = np.asarray(x, md.Kx.dtype)
        r = np.asarray(r, md.Kx.dtype)
        lam = self.lam
        self.work, self.work_limit = 0, self.budget
        th0, px = self.unconstrained(x, r)
        gam, K = self.slacks(x, th0, px)
        if not np.any(K < 0):
            lam[:] = 0
            return self.finish(th0, th0, OPTIMAL) + (0, 0, 0)
        total, polish_its, active, resume = 0, 0, 0, -1
        if self.polish_on and self.polish_first:
            # the previous active set shifted one stage (a guess, in the dual form on a third
            # of what the budget has left: the dual active set takes over where it stops),
            # then the rows th0 violates (with a warm start, in the primal form only)
            count = 0  # rows of the warm start (-1: more than the working set holds)
            if self.warm:
                if not self.afford(md.m):
                    return self.time_limit_at_th0(th0, False) + (0, polish_its, 0)
                W = self.seed_shifted(lam)
                if isinstance(W, int):  # OUT_OF_WORK: part of its factor, lam the guess
                    return self.time_limit_at_th0(th0, False) + (0, polish_its, 0)
                count = W.size if W.size <= self.wcap else -1
                if self.active_set and not self.box_only(W):
                    self.work_limit = self.work + (self.budget - self.work) // 3
                code, th_p, act, its = self.polish(W, lam, th0, K, gam, True)
                self.work_limit = self.budget
                polish_its += its
                if code == 0:
                    return self.finish(th_p, th0, OPTIMAL) + (0, polish_its, act)
                if code in (OUT_OF_WORK, GUESS_HANDED_OVER):
                    if not self.active_set:
                        return self.time_limit_at_th0(th0, True) + (0, polish_its, 0)
                    resume = self.stop[0].size  # the dual active set takes over from there
                if code == GUESS_CAPPED:
                    resume = COLD_START  # resuming the same guess would repeat it
            if resume < 0:
                if not self.afford(md.m):
                    return self.time_limit_at_th0(th0, False) + (0, polish_its, 0)
                W = self.seed_from_violated(K)
                if count <= 0 or not self.active_set or self.box_only(W):
                    code, th_p, act, its = self.polish(W, lam, th0, K, gam)
                    polish_its += its
                    if code == 0:
                        return self.finish(th_p, th0, OPTIMAL) + (0, polish_its, act)
                    if code == OUT_OF_WORK:  # the dual active set goes on, a row at a time,
                        # unless a mode of input bounds only has its primal point
                        point = self.inputs_only() and self.th_solved is not None
                        if not self.active_set or point:
                            return self.time_limit_at_th0(th0, True) + (0, polish_its, 0)
                        resume = self.stop[0].size
                    if code == -1 and count == 0 and self.active_set:
                        resume = self.violated_resume(K)  # not cold: from the rows th0 violates
        if self.active_set:
            code, th_a, act, its = self.dual_active_set(lam, th0, K, gam, resume)
            polish_its += its
            if code >= 0:
                status, U = self.finish(th_a, th0, OPTIMAL if code == 0 else INFEASIBLE)
                return status, U, 0, polish_its, act
            if code == OUT_OF_WORK:  # at its last point
                return self.finish(th_a, th0, TIME_LIMIT) + (0, polish_its, act)
            if code == OUT_OF_WORK_AT_TH0:  # no point of its own: lam as it left it
                return self.time_limit_at_th0(th0, False) + (0, polish_its, act)
        if not self.afford(3 * md.m + md.n + (0 if self.out_slacks_ok else predict_work(md))):
            return self.time_limit_at_th0(th0, False) + (0, polish_its, active)
        self.output_slacks()
        th = th0
        in_set = (K < self.sigma) if self.reduced else np.ones(md.m, bool)
        if not self.warm:
            lam[:] = 0
        lam[~in_set] = 0
        S = self.build_set(in_set)
        status = MAX_ITER
        while True:
            converged = diverged = out = False
            chunk = self.polish_every if self.polish_on else self.max_iter
            after = correct_work(md, S.size) + (S.size if self.polish_on
                                                else 2 * scan_work(md) + md.m)
            t = 0
            while t < chunk and total < self.max_iter:
                out = not self.afford(sweep_work(md, S.size, self.hq_factor) + after)
                if out:
                    break
                e2, diverged = self.sweep(S, K, lam)
                total += 1
                t += 1
                if diverged:
                    break
                if e2 < self.delta:
                    converged = True
                    break
            if out:
                status = TIME_LIMIT  # at the last corrected point
                break
            if diverged:
                status = INFEASIBLE
                break
            th = self.correct(th0, S, lam[S])
            if self.polish_on:
                code, th_p, act, its = self.polish(self.seed_from_multipliers(lam, S), lam,
                                                   th0, K, gam)
                polish_its += its
                if code == 0:
                    th, active, status = th_p, act, OPTIMAL
                    break
                if code == OUT_OF_WORK or not self.afford(correct_work(md, S.size)
                                                          + 2 * scan_work(md) + 2 * md.m):
                    th, status = self.fallback_point(th0), TIME_LIMIT
                    break
                th = self.correct(th0, S, lam[S])  # the polish overwrote the corrected point
            exc, scale = self.row_excess(th, gam)
            viol = exc > self.tol * scale
            if self.soft:
                self.outputs_to_check(th, gam)  # violated_beyond_slack()'s work
                nviol = self.violated_beyond_slack(exc, scale, lam)
            else:  # violated_outside() over every row (only nviol != 0 matters)
                nviol = self.violated_outside(th, gam, S[:0]).size
            added = 0
            if self.reduced and nviol:
                self.outputs_to_check(th, gam)
                new = viol & ~in_set
                added = int(np.count_nonzero(new))
                in_set |= new
            if converged and nviol == 0:
                status = OPTIMAL
                break
            if total >= self.max_iter:
                status = MAX_ITER
                break
            if converged and added == 0:
                status = INACCURATE
                break
            if added:
                S = self.build_set(in_set)
        if active == 0:
            active = int(np.count_nonzero(lam > 0))
        status, U = self.finish(th, th0, status)
        return status, U, total, polish_its, active

    def finish(self, th, th0, status):
        """Mirror of finish(): clamp th (or th0, or 0 when not finite) into the input
        bounds; keep the warm start only when optimal or out of time; the plan's slacks
        (when optimal). (status, U)."""
        md = self.md
        self.work += finish_work(md)
        src = th
        if not np.all(np.isfinite(th)):
            status = NUMERICAL
            src = th0 if np.all(np.isfinite(th0)) else np.zeros_like(th0)
        lo = np.tile(self.u_min, md.n // md.nu)  # per stage, or per block
        hi = np.tile(self.u_max, md.n // md.nu)
        U = np.where(src < lo, lo, np.where(src > hi, hi, src))
        if status not in (OPTIMAL, TIME_LIMIT):
            self.lam[:] = 0
        if self.soft:  # the plan's slacks (finish()): 0 unless optimal
            sl = (multiplier_slack(self.lam, self.soft_l1, self.soft_w) if status == OPTIMAL
                  else np.zeros(0, md.Kx.dtype))
            self.slack_max = sl.max(initial=self.zero)
            self.slack_rows = int(np.count_nonzero(sl > 0))
        return status, U
