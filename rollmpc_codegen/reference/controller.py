"""NumPy reference of the generated switched controller (``P_step``), op by op.

Mirrors ``templates/controller.c.j2`` (and ``controller/runtime_bounds.c.j2``): the band
scheduler with hysteresis (eq. 3 generalised, :mod:`.scheduler`), the predictor observers
of every mode with their innovations clipped (:func:`observe`), the QP of the active mode
(:class:`SolverRef`), first-move extraction and the inactive actuators at 0.
"""
from __future__ import annotations

import numpy as np

from ..features import runtime_bounds
from .scheduler import scheduled_mode
from ..status import (APPLIED_CLIPPED, BAD_ARGUMENT, MEASUREMENT_CLIPPED, NONFINITE_INPUT,
                      OPTIMAL, UNKNOWN_MESSAGE, Status)
from .linalg import seqsum
from .solver import LastPlan, SolverRef


def observe(md, x, y, u_phys, use_y) -> int:
    """Mirror of observe(): one update, each innovation clipped to +-innovation_limit;
    returns how many were clipped (y - C x may overflow to +-inf, as in the C)."""
    innov = np.zeros(md.ny, md.Kx.dtype)
    clipped = 0
    with np.errstate(over="ignore", invalid="ignore"):
        for a in range(md.ny):
            yh = seqsum(md.C[a] * x)
            if use_y:
                limit = md.innovation_limit[a]
                innov[a] = y[a] - yh
                if innov[a] > limit:
                    innov[a], clipped = limit, clipped + 1
                if innov[a] < -limit:
                    innov[a], clipped = -limit, clipped + 1
        xn = np.empty(md.nx, md.Kx.dtype)
        u_mode = u_phys[md.actuator_index]
        for i in range(md.nx):
            prods = [md.A[i] * x, md.B[i] * u_mode]
            if use_y:
                prods.append(md.L[i] * innov)
            xn[i] = seqsum(np.concatenate(prods))
    x[:] = xn
    return clipped


class ControllerRef:
    def __init__(self, ctx: dict, mode_data: list):
        self.ctx = ctx
        self.md = mode_data
        self.dt = mode_data[0].Kx.dtype.type
        dt = self.dt
        self.last_plan = LastPlan(ctx["horizon"])  # P_ctrl's U, plan_mode, plan_age
        self.solvers = [SolverRef(md, ctx["solver"], j, self.last_plan, ctx["has_rate_rows"])
                        for j, md in enumerate(mode_data)]
        sc = ctx["scheduler"]
        if sc is not None:
            # the C stores each threshold -/+ epsilon as one literal computed in double
            self.below = tuple(dt(v) for v in sc["below"])
            self.above = tuple(dt(v) for v in sc["above"])
        self.init()

    def init(self):
        """Mirror of ``P_init``."""
        self.mode = self.ctx["initial_mode"]
        self.xhat = [np.zeros(md.nx, md.Kx.dtype) for md in self.md]
        for s in self.solvers:
            s.lam[:] = 0
            s.forget_factor()
        self.last_plan.forget()
        self.last_plan.mode = self.mode
        self.u_last = np.zeros(self.ctx["n_actuators"], self.md[0].Kx.dtype)
        self.mode_switches = 0
        self.last = {"status": 0, "iterations": 0, "polish_iterations": 0, "active": 0,
                     "clipped": 0, "work": 0}
        if self.ctx.get("runtime_bounds"):
            self.config_bounds = [runtime_bounds.config_bounds(m, md.Kx.dtype)
                                  for m, md in zip(self.ctx["modes"], self.md)]
            self.bounds = [dict(b) for b in self.config_bounds]
            for j in range(len(self.md)):
                self._apply_bounds(j)

    def _apply_bounds(self, j):
        """Mode j's solver reads the live bounds, as the C's row_const() derives them."""
        md, b, solver = self.md[j], self.bounds[j], self.solvers[j]
        plain = {k: b[k] for k in ("u_min", "u_max", "y_min", "y_max")}
        solver.row_c = runtime_bounds.row_const(md.row_q, md.row_sign, md.n, md.nu, md.ny,
                                                dtype=md.Kx.dtype, **plain)
        if md.has_signal_rows:  # a signal row's constant: its live bound, or baked in
            live = runtime_bounds.signal_row_const(md, b["z_min"], b["z_max"])
            solver.row_c = np.where(md.signal_rows, live, solver.row_c)
        solver.u_min, solver.u_max = b["u_min"], b["u_max"]

    def set_bounds(self, mode, u_min, u_max, y_min, y_max):
        """Mirror of ``P_set_bounds``: returns its status; changes nothing unless OPTIMAL.
        None stands for a NULL pointer; the C reads nu(mode) and ny entries."""
        if not 0 <= mode < len(self.md):
            return BAD_ARGUMENT
        md = self.md[mode]
        sizes = (md.nu, md.nu, md.ny, md.ny)
        new = [None if v is None else np.array(np.atleast_1d(v)[:size], md.Kx.dtype)
               for v, size in zip((u_min, u_max, y_min, y_max), sizes)]
        status = runtime_bounds.check_bounds(self.config_bounds[mode], *new)
        if status != OPTIMAL:
            return status
        self.bounds[mode] = {**self.bounds[mode],
                             **dict(zip(("u_min", "u_max", "y_min", "y_max"), new))}
        self._apply_bounds(mode)
        if mode == self.mode:
            self.hold_for_mode()  # the held command obeys the new input bounds
        return OPTIMAL

    def get_bounds(self, mode):
        """Mirror of ``P_get_bounds``: (status, a copy of the live bounds or None)."""
        if not 0 <= mode < len(self.md):
            return BAD_ARGUMENT, None
        return OPTIMAL, {k: self.bounds[mode][k].copy() for k in ("u_min", "u_max", "y_min",
                                                                   "y_max")}

    def set_signal_bounds(self, mode, z_min, z_max):
        """Mirror of ``P_set_signal_bounds``: its status; changes nothing unless OPTIMAL.
        None stands for a NULL pointer; the C reads nsig_live(mode) entries."""
        if not 0 <= mode < len(self.md):
            return BAD_ARGUMENT
        md = self.md[mode]
        new = [None if v is None else np.array(np.atleast_1d(v)[:md.nsig_live], md.Kx.dtype)
               for v in (z_min, z_max)]
        status = runtime_bounds.check_signal_bounds(self.config_bounds[mode], *new)
        if status != OPTIMAL:
            return status
        self.bounds[mode] = {**self.bounds[mode], "z_min": new[0], "z_max": new[1]}
        self._apply_bounds(mode)
        return OPTIMAL

    def get_signal_bounds(self, mode):
        """Mirror of ``P_get_signal_bounds``: (status, {z_min, z_max} copies or None)."""
        if not 0 <= mode < len(self.md):
            return BAD_ARGUMENT, None
        return OPTIMAL, {k: self.bounds[mode][k].copy() for k in ("z_min", "z_max")}

    def status_message(self, status: int) -> str:
        """Mirror of ``P_status_message``: a code of this build (the run-time bounds' only
        with runtime_bounds), else the unknown code's message."""
        known = {int(s): s.message for s in Status
                 if self.ctx.get("runtime_bounds") or not s.runtime_bounds_only}
        return known.get(int(status), UNKNOWN_MESSAGE)

    def last_info(self) -> dict:
        """Mirror of ``P_last_info``: the diagnostics of the last call (P_info's members the
        reference computes)."""
        return self.last

    def solve_qp(self, mode, x, r):
        """Mirror of ``P_solve_qp``: (status, U, iterations); None stands for a NULL
        pointer."""
        if not 0 <= mode < len(self.md):
            return BAD_ARGUMENT, None, 0
        md = self.md[mode]
        if x is None or r is None or not (np.all(np.isfinite(x)) and np.all(np.isfinite(r))):
            self.last["status"] = BAD_ARGUMENT if x is None or r is None else NONFINITE_INPUT
            return self.last["status"], np.zeros(md.n, md.Kx.dtype), 0
        solver = self.solvers[mode]
        status, U, its, pits, active = solver.solve_mode(x, r)
        self.last.update(status=status, iterations=its, polish_iterations=pits, active=active,
                         work=solver.work)
        return status, U, its

    def hold_for_mode(self):
        """Mirror of hold_for_mode(): u_last made the active mode's (after P_observe()
        switched the mode it may be another's): its actuators clamped into its live input
        bounds, every other actuator 0."""
        md, solver = self.md[self.mode], self.solvers[self.mode]
        held = np.zeros_like(self.u_last)
        v = self.u_last[md.actuator_index]
        held[md.actuator_index] = np.where(v < solver.u_min, solver.u_min,
                                           np.where(v > solver.u_max, solver.u_max, v))
        self.u_last = held

    def schedule(self, s):
        """The mode ``schedule()`` of the C returns for signal ``s`` (no state change)."""
        return scheduled_mode(self.mode, s, self.below, self.above,
                              self.ctx["scheduler"]["band_modes"])

    def follow_schedule(self, sched):
        """``follow_schedule()`` of the C: the incoming mode starts cold."""
        if self.ctx["scheduler"] is not None:
            j = self.schedule(sched[0])
            if j != self.mode:
                self.solvers[j].lam[:] = 0
                self.last_plan.forget()
                self.mode = j
                self.mode_switches += 1

    def observe(self, y, sched, u_applied):
        """Mirror of ``P_observe``: scheduler and observers on the applied command, made
        plausible first."""
        dt = self.md[0].Kx.dtype
        y = np.asarray(y, dt)
        sched = np.asarray(sched if sched is not None else [], dt)
        u = np.asarray(u_applied, dt)
        if not np.all(np.isfinite(u)):
            return NONFINITE_INPUT
        applied_clipped, u = self.plausible_applied(u)
        use_y = bool(np.all(np.isfinite(y)) and np.all(np.isfinite(sched)))
        if use_y:
            self.follow_schedule(sched)
        clipped = sum(observe(md, self.xhat[j], y, u, use_y)
                      for j, md in enumerate(self.md))
        if not use_y:
            return NONFINITE_INPUT
        if applied_clipped:
            return APPLIED_CLIPPED
        return MEASUREMENT_CLIPPED if clipped else OPTIMAL

    def plausible_applied(self, u_applied):
        """Mirror of plausible_applied(): (how many entries were clipped, u_applied clipped
        to each actuator's range, widened by the live input bounds in a runtime build)."""
        lo = np.array(self.ctx["actuator_min"], self.dt)
        hi = np.array(self.ctx["actuator_max"], self.dt)
        if self.ctx.get("runtime_bounds"):
            for md, b in zip(self.md, self.bounds):
                act = md.actuator_index
                lo[act] = np.where(b["u_min"] < lo[act], b["u_min"], lo[act])
                hi[act] = np.where(b["u_max"] > hi[act], b["u_max"], hi[act])
        clipped = int(np.count_nonzero(u_applied > hi) + np.count_nonzero(u_applied < lo))
        return clipped, np.where(u_applied > hi, hi, np.where(u_applied < lo, lo, u_applied))

    def step(self, y, sched, r):
        """Returns (status, u) exactly as ``P_step``."""
        dt = self.md[0].Kx.dtype
        y = np.asarray(y, dt)
        sched = np.asarray(sched if sched is not None else [], dt)
        r = np.asarray(r, dt)
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(sched))
                and np.all(np.isfinite(r))):
            self.hold_for_mode()
            u = self.u_last.copy()
            for j, md in enumerate(self.md):
                observe(md, self.xhat[j], y, u, False)
            self.last = {"status": NONFINITE_INPUT, "iterations": 0,
                         "polish_iterations": self.last["polish_iterations"],
                         "active": self.last["active"], "clipped": 0, "work": 0}
            return NONFINITE_INPUT, u
        self.follow_schedule(sched)
        md = self.md[self.mode]
        status, U, its, pits, active = self.solvers[self.mode].solve_mode(self.xhat[self.mode], r)
        self.U = U
        self.last = {"status": status, "iterations": its, "polish_iterations": pits,
                     "active": active, "work": self.solvers[self.mode].work}
        if self.ctx.get("has_soft_rows"):  # info.slack_max / slack_rows of P_step
            solver = self.solvers[self.mode]
            self.last.update(slack_max=float(solver.slack_max), slack_rows=solver.slack_rows)
        u = np.zeros(self.ctx["n_actuators"], dt)
        u[md.actuator_index] = U[:md.nu]
        clipped = sum(observe(mdj, self.xhat[j], y, u, True)
                      for j, mdj in enumerate(self.md))
        self.u_last = u.copy()
        self.last["clipped"] = clipped
        if status == OPTIMAL and clipped:  # a solver status wins over the report
            status = self.last["status"] = MEASUREMENT_CLIPPED
        return status, u
