"""The constraints behind a closed loop's INFEASIBLE samples, by config key (the
diagnosis ``simulate`` adds to its warning: sim/run_checks.py).

The C keeps its state estimate to itself, so the estimate each solve started from is
rebuilt in double by the observers of :mod:`.switched_observer` (the context's A, B, C, L;
the innovation clip left out), fed the logged measurements and commands; each infeasible
sample's QP is then diagnosed by :func:`..qp.infeasibility.violated_keys`.  An
approximation of the C's float or double estimate, so a diagnosis, not a proof.
"""
from __future__ import annotations

from collections import Counter

import numpy as np

from ..qp.infeasibility import violated_keys
from ..status import INFEASIBLE
from .scenario import preview
from .switched_observer import SwitchedObserver

MAX_DIAGNOSED = 12  # infeasible samples whose QP is diagnosed (evenly spread)


def infeasible_keys(model, ctx: dict, log, reference: np.ndarray) -> Counter:
    """How many of the diagnosed INFEASIBLE samples each config key's rows broke."""
    bad = np.flatnonzero(log.status == INFEASIBLE)
    if bad.size == 0:
        return Counter()
    chosen = set(bad[np.linspace(0, bad.size - 1, min(bad.size, MAX_DIAGNOSED)).astype(int)])
    obs = SwitchedObserver(ctx)
    cfg, found = model.config, Counter()
    for k in range(int(bad.max()) + 1):
        j = obs.schedule(log.sched[k]) if cfg.scheduler is not None else obs.mode
        if k in chosen:
            r = preview(reference, k, cfg.horizon, cfg.n_outputs)
            found.update(violated_keys(model.modes[j].qp, j, obs.xhat[j], r))
        obs.observe(log.y[k], log.u[k])
    return found
