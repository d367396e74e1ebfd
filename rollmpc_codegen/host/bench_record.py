"""Steps 1 and 2 of ``rollmpc bench`` (:mod:`rollmpc_codegen.host.bench`): record the QP
sequence of the scenario, then choose the QPs to replay.

1. **Record**: the default controller (the config as given, compiled C through cffi) runs
   the closed loop of ``rollmpc simulate``; every sample contributes (mode, xhat of that
   mode before the solve, reference preview).  The estimate comes from the context's
   observers (:class:`rollmpc_codegen.sim.switched_observer.SwitchedObserver`, double),
   the mode from the C (``P_last_info``).
2. **Select**: samples 1-32 are skipped, as in the paper's Table 2 (its start-up
   transient), unless the transient is included.  A maximum number of QPs keeps evenly
   spread blocks of 20 consecutive QPs (warm starts carry over as in the closed loop inside
   a block; the first QP of a block warm-starts from the end of the previous block).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .build import HostController
from ..model.controller import ControllerModel
from ..sim.simulate import run_closed_loop
from ..sim.switched_observer import SwitchedObserver

TRANSIENT_SAMPLES = 32  # the paper's Table 2 uses samples 33..6000
SAMPLE_BLOCK = 20  # a maximum number of QPs keeps blocks of this many consecutive QPs


@dataclass
class QpSequence:
    """The QPs of one closed loop: sample k solved mode[k] at x[k] with preview r[k]."""

    k: np.ndarray
    mode: np.ndarray
    x: list
    r: np.ndarray
    u_applied: np.ndarray  # (K, n_actuators) what the closed loop applied


def record_qp_sequence(model: ControllerModel, controller: HostController,
                       steps: int | None = None, progress=None) -> QpSequence:
    """Run the scenario with ``controller`` and record every QP it solved."""
    ctx = controller.ctx
    observer = SwitchedObserver(ctx)
    modes, xs, rs = [], [], []

    class Recorder:
        def step(self, y, sched, r):
            before = [x.copy() for x in observer.xhat]
            status, u = controller.step(y, sched, r)
            mode = controller.info()["mode"]
            modes.append(mode)
            xs.append(before[mode])
            rs.append(np.array(r, float))
            observer.observe(y, u)
            return status, u

    controller.init()
    log = run_closed_loop(model.config, Recorder(), steps=steps, progress=progress)
    controller.init()
    return QpSequence(k=np.arange(len(modes)), mode=np.array(modes), x=xs,
                      r=np.array(rs), u_applied=log.u.copy())


def select_qps(seq: QpSequence, include_transient: bool, max_qps: int | None,
               block: int = SAMPLE_BLOCK) -> np.ndarray:
    """Indices into ``seq`` to replay (see the module docstring).

    A sample (``max_qps``) is made of evenly spread blocks of ``block`` consecutive QPs,
    the first block at the start and the last at the end, so that within a block the
    warm starts carry over exactly as in the closed loop.
    """
    idx = seq.k if include_transient else seq.k[TRANSIENT_SAMPLES:]
    if max_qps is None or idx.size <= max_qps:
        return idx
    b = min(block, max_qps)
    starts = np.linspace(0, idx.size - b, max_qps // b).round().astype(int)
    return idx[np.unique((starts[:, None] + np.arange(b)).ravel())]
