"""Step 3 of ``rollmpc bench`` (:mod:`rollmpc_codegen.host.bench`): replay the recorded
QPs, in order, through one row of the table.

* A generated solver variant (:func:`replay_c`), called through ``P_solve_qp``.  Warm
  starts carry over from QP to QP; when the mode changes the controller is re-initialised,
  which is what ``P_step`` does on a switch (the incoming mode starts cold).  Time:
  ``solve_ticks`` measured inside the C around the solve (host monotonic clock, ns).
* A PyPI peer (:func:`replay_peer`, :mod:`rollmpc_codegen.qp.peers`), timed by its own
  in-C timer where it has one.

Every row also gets the wall time around its Python call ("call" columns), so the C
variants can be compared like for like with the Python-called peers.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from .bench_record import QpSequence
from .build import HostController
from ..codegen.context import build_context
from ..config import ControllerConfig
from ..config.schema import WORK_BUDGET_AUTO
from ..model.controller import ControllerModel
from ..pipeline import build_model
from ..status import STATUS_NAMES


@dataclass
class Replay:
    """Per-QP results of one row of the table."""

    status: list  # status names ("optimal", "max_iter", ...)
    u0: np.ndarray  # (Q, nu_max) the first move, NaN-padded for smaller modes
    solver_s: np.ndarray
    call_s: np.ndarray
    iterations: np.ndarray


def variant_context(cfg: ControllerConfig, method: str) -> dict:
    """The context of ``cfg`` with the paper's ``method`` and no polish, and no work budget
    (a budget the config sizes is for its polish; the paper's sweeps stop at max_iterations)."""
    solver = dataclasses.replace(cfg.solver, method=method, polish=False,
                                 work_budget=WORK_BUDGET_AUTO)
    return build_context(build_model(dataclasses.replace(cfg, solver=solver)))


def first_move_sizes(model: ControllerModel) -> tuple[list[int], int]:
    """(inputs of each mode's first move, their maximum)."""
    nus = [mm.qp.nu for mm in model.modes]
    return nus, max(nus)


def _empty_replay(model: ControllerModel, qps: int) -> Replay:
    _, nu_max = first_move_sizes(model)
    return Replay(status=[], u0=np.full((qps, nu_max), np.nan), solver_s=np.zeros(qps),
                  call_s=np.zeros(qps), iterations=np.zeros(qps, int))


def replay_c(controller: HostController, model: ControllerModel, seq: QpSequence,
             idx: np.ndarray, progress=None) -> Replay:
    """The QPs ``seq[idx]`` through ``P_solve_qp`` of ``controller``."""
    nus, _ = first_move_sizes(model)
    dtype = controller.dtype
    out = _empty_replay(model, idx.size)
    controller.init()
    previous = None
    for q, i in enumerate(idx):
        mode = int(seq.mode[i])
        if mode != previous:
            controller.init()  # as P_step on a switch: the incoming mode starts cold
            previous = mode
        x = np.ascontiguousarray(seq.x[i], dtype)
        r = np.ascontiguousarray(seq.r[i], dtype)
        t0 = time.perf_counter_ns()
        status, U, its = controller.solve_qp(mode, x, r)
        t1 = time.perf_counter_ns()
        info = controller.info()
        out.status.append(STATUS_NAMES.get(status, str(status)))
        out.u0[q, :nus[mode]] = U[:nus[mode]]
        out.solver_s[q] = info["solve_ticks"] * 1e-9
        out.call_s[q] = (t1 - t0) * 1e-9
        out.iterations[q] = its
        if progress is not None:
            progress(q)
    controller.init()
    return out


def replay_peer(peer, model: ControllerModel, seq: QpSequence, idx: np.ndarray,
                progress=None) -> Replay:
    """The QPs ``seq[idx]`` through a peer of :mod:`rollmpc_codegen.qp.peers`."""
    nus, _ = first_move_sizes(model)
    out = _empty_replay(model, idx.size)
    for q, i in enumerate(idx):
        mode = int(seq.mode[i])
        t0 = time.perf_counter_ns()
        res = peer.solve(mode, seq.x[i], seq.r[i])
        t1 = time.perf_counter_ns()
        out.status.append(res.status)
        out.u0[q, :nus[mode]] = res.U[:nus[mode]]
        out.call_s[q] = (t1 - t0) * 1e-9
        out.solver_s[q] = res.solver_s if res.solver_s is not None else out.call_s[q]
        out.iterations[q] = res.iterations
        if progress is not None:
            progress(q)
    return out


def fastest_of(runs: list[Replay]) -> Replay:
    """The first of several deterministic replays, with each QP's minimum times."""
    best = runs[0]
    best.solver_s = np.min([r.solver_s for r in runs], axis=0)
    best.call_s = np.min([r.call_s for r in runs], axis=0)
    return best
