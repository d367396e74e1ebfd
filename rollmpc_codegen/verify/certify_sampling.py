"""The samples of a work certificate (certify.py): closed loops of the design as generated,
their every QP's work and status, and the work its hardest QPs need without a budget.

The loops are the random flights of a :class:`~rollmpc_codegen.sim.flight_plan.FlightPlan`
(references inside the scenario's range and pressing the envelope, noise, disturbance,
plant mismatch; the scheduler picks the modes as it does in flight), each from P_init(),
flight i seeded ``seed + i``. The controller is the NumPy reference (``engine
"reference"``: no C compiler needed) or the host C (``"host"``: about 30 times faster);
their work counts agree bit for bit (tests/controller/test_bitexact_scenario.py, tests/host/
test_kernel_variants.py), so either gives the same certificate.

Before each step the controller's state is kept (a copy of the reference, the bytes of the
C's instance) while that step may be among the ``keep`` hardest (by work) or stopped at
TIME_LIMIT; each kept QP is solved again from its state with no budget
(:data:`~rollmpc_codegen.qp.work.UNBOUNDED_WORK`): the work it needs. That path can differ
from the budgeted one (the solver shares what is left of its budget between its phases),
so the needed work is the unbudgeted solver's, from the same state.
"""
from __future__ import annotations

import copy
import heapq
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..qp.work import UNBOUNDED_WORK
from ..sim.flight_plan import FlightPlan
from ..sim.simulate import run_closed_loop, start_phase
from ..status import TIME_LIMIT

ENGINES = ("reference", "host")
KEEP_HARDEST = 10  # QPs solved again without a budget, besides the TIME_LIMIT ones
KEEP_TIME_LIMIT = 50  # at most this many TIME_LIMIT QPs solved again


class ReferenceEngine:
    """The NumPy reference: a state is a copy of the controller (its stored data shared)."""

    def __init__(self, model, ctx: dict, build_dir=None):
        from ..reference.controller import ControllerRef

        self.data = [m.data for m in model.modes]
        self.ctrl = ControllerRef(ctx, self.data)
        self.shared = {id(d): d for d in self.data}
        self.shared[id(ctx)] = ctx

    def init(self):
        self.ctrl.init()

    def step(self, y, s, r):
        return self.ctrl.step(y, s, r)

    def info(self) -> dict:
        return {**self.ctrl.last, "mode": self.ctrl.mode}

    def state(self):
        return copy.deepcopy(self.ctrl, dict(self.shared))

    def solve_from(self, state, y, s, r, budget: int) -> tuple[int, int]:
        """(status, work) of the step from ``state`` with ``budget`` units."""
        ctrl = copy.deepcopy(state, dict(self.shared))
        for solver in ctrl.solvers:
            solver.budget = budget
        status, _u = ctrl.step(y, s, r)
        return int(status), int(ctrl.last["work"])


class HostEngine:
    """The host C: a state is the instance's bytes; a second build has no budget."""

    def __init__(self, model, ctx: dict, build_dir=None):
        from ..host.build import build_host_controller

        self.ctx = ctx
        self.ctrl = build_host_controller(ctx, build_dir)
        self.builds = {int(ctx["solver"]["work_budget"]): self.ctrl}
        self.build_dir = build_dir

    def init(self):
        self.ctrl.init()

    def step(self, y, s, r):
        return self.ctrl.step(y, s, r)

    def info(self) -> dict:
        return self.ctrl.info()

    def state(self):
        return self.ctrl.instance()

    def solve_from(self, state, y, s, r, budget: int) -> tuple[int, int]:
        from ..host.build import build_host_controller

        if budget not in self.builds:
            ctx = {**self.ctx, "solver": {**self.ctx["solver"], "work_budget": budget}}
            self.builds[budget] = build_host_controller(ctx, self.build_dir)
        c = self.builds[budget]
        c.ffi.memmove(c.ctrl, state, len(state))
        status, _u = c.step(y, s, r)
        return int(status), int(c.info()["work"])


@dataclass
class Kept:
    """A QP kept to be solved again: where it was and the state and inputs it had."""

    loop: int
    step: int
    work: int
    status: int
    mode: int
    state: object
    inputs: tuple
    xhat: list
    reference: list
    needed: int | None = None
    needed_status: int | None = None


@dataclass
class Samples:
    """Every sampled QP's work, status and mode, per loop; the kept QPs, hardest first."""

    work: list = field(default_factory=list)  # per loop, int64 arrays
    status: list = field(default_factory=list)
    mode: list = field(default_factory=list)
    kept: list = field(default_factory=list)


class _Recorder:
    """Steps the engine for run_closed_loop and keeps the states of the hardest steps."""

    def __init__(self, engine, loop: int, hardest: "_Hardest", xhat_of):
        self.engine, self.loop, self.hardest, self.k = engine, loop, hardest, 0
        self.xhat_of = xhat_of

    def step(self, y, s, r):
        before = self.engine.state()
        xhat = self.xhat_of()
        status, u = self.engine.step(y, s, r)
        info = self.engine.info()
        entry = Kept(self.loop, self.k, int(info["work"]), int(status), int(info["mode"]),
                     before, (np.array(y), np.array(s), np.array(r)), xhat,
                     np.asarray(r, float)[:len(y)].tolist())
        self.hardest.keep(entry)
        self.k += 1
        return status, u

    def info(self):
        return self.engine.info()


class _Hardest:
    """The ``keep`` hardest QPs by work (the earliest on a tie) and the first TIME_LIMITs."""

    def __init__(self, keep: int, time_limits: int):
        self.heap, self.keep_n, self.stops, self.stops_n, self.count = [], keep, [], time_limits, 0

    def keep(self, e: Kept) -> None:
        self.count += 1
        if e.status == TIME_LIMIT and len(self.stops) < self.stops_n:
            self.stops.append(e)
            return
        item = (e.work, -self.count, e)
        if len(self.heap) < self.keep_n:
            heapq.heappush(self.heap, item)
        elif item[:2] > self.heap[0][:2]:
            heapq.heapreplace(self.heap, item)

    def all(self) -> list[Kept]:
        return self.stops + [e for _w, _c, e in self.heap]


def _xhat_reader(engine):
    """The active mode's state estimate before a step (what its QP is solved for)."""
    if isinstance(engine, ReferenceEngine):
        return lambda: engine.ctrl.xhat[engine.ctrl.mode].astype(float).tolist()
    return lambda: None  # the C's estimate is inside its instance; its QP is named by step


def sample(model, ctx: dict, plan: FlightPlan, steps: int, *, engine: str = "reference",
           build_dir: str | Path | None = None, progress=None) -> Samples:
    """Fly ``plan``'s flights of ``steps`` samples with ``engine`` and solve the kept QPs
    again without a budget (their ``needed`` work), hardest first."""
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    eng = (ReferenceEngine if engine == "reference" else HostEngine)(model, ctx, build_dir)
    out, hardest = Samples(), _Hardest(KEEP_HARDEST, KEEP_TIME_LIMIT)
    flights = plan.plan(model.config, steps)
    for flight in flights:
        eng.init()
        rec = _Recorder(eng, flight.index, hardest, _xhat_reader(eng))
        log = run_closed_loop(model.config, rec, steps=steps, info=rec.info,
                              progress=start_phase(progress, steps, f"certify: loop "
                                                   f"{flight.index + 1} of {len(flights)}"),
                              **plan.loop_options(flight))
        out.work.append(np.asarray(log.work, np.int64))
        out.status.append(np.asarray(log.status, int))
        out.mode.append(np.asarray(log.mode, int))
    for e in hardest.all():
        e.needed_status, e.needed = eng.solve_from(e.state, *e.inputs, UNBOUNDED_WORK)
        e.state = None  # the copies are large; the figures stay
    out.kept = sorted(hardest.all(), key=lambda e: (-e.needed, e.loop, e.step))
    return out
