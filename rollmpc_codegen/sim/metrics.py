"""Fig. 2 metrics of a closed-loop log (``rollmpc simulate --json``).

Definitions (also in docs/paper-reproduction.md):

* **Segment**: a maximal run of samples with a constant reference (the paper's scenario
  has six of 10 s).
* **Settled window** of a segment: from 70 % of its length to N*Ts (the preview
  horizon) before the next reference step, so the window neither contains the transient
  of its own step nor the controller's anticipation of the next one (with the preview
  the MPC starts to move up to N samples early).  The last segment's window runs to its
  end.  For the paper's scenario: 7 s to 9 s of each 10 s segment (7 s to 10 s for the
  last).  It measures the steady-state offset, not the speed of the tail.
* **Settled error**: max |y - r| over the settled window (in the output's unit: deg for
  the UAV; the config's optional ``units`` only labels it).
* **Settling time**: time from the step after which |y - r| stays within 2 % of the
  step size up to the anticipation cut-off (None if it never does; 0 without a step).
* **Overshoot**: how far y goes past the new reference, in the direction of the step,
  from the step up to the same anticipation cut-off (0 when it never goes past); in
  percent of the step size too.  For the first segment (no step) it is max |y - r|.
* **Constraint violation**: a sample where an active actuator is outside its mode's
  [u_min, u_max], an inactive actuator is not exactly 0, or an output is outside the
  active mode's [y_min, y_max].  No tolerance: the C clamps exactly.
* **Total variation** of each actuator's command: sum over k of |u(k) - u(k-1)| (what
  Δu weighting, ``weights.R_delta``, reduces).
"""
from __future__ import annotations

import numpy as np

from ..config import ControllerConfig
from .simulate import ClosedLoopLog
from ..status import OPTIMAL, STATUS_NAMES


def _time(k, ts: float) -> float:
    """Sample index -> seconds, without the binary noise of k * ts (42.230000000000004)."""
    return round(float(k) * ts, 9)


def reference_segments(r: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of every maximal run of a constant reference (rows of ``r``)."""
    r = np.asarray(r).reshape(len(r), -1)
    change = np.flatnonzero(np.any(np.diff(r, axis=0) != 0, axis=1)) + 1
    bounds = [0, *change.tolist(), len(r)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def settled_window(start: int, end: int, last: bool, horizon: int) -> tuple[int, int]:
    """[lo, hi) of the settled window (see the module docstring)."""
    lo = start + (7 * (end - start)) // 10
    hi = end if last else end - horizon
    if hi <= lo:  # a segment shorter than about 3 horizons: use its last 30 %
        hi = end
    return lo, hi


def _segment_metrics(log: ClosedLoopLog, start: int, end: int, last: bool, horizon: int,
                     ts: float, outputs: tuple[str, ...]) -> dict:
    r_new = log.r[start]
    r_old = log.r[start - 1] if start > 0 else log.r[start]
    lo, hi = settled_window(start, end, last, horizon)
    err = np.abs(log.y[lo:hi] - log.r[lo:hi]).max(axis=0)
    cut = end if last else max(start + 1, end - horizon)
    overs, pcts, settle = [], [], []
    for o in range(len(outputs)):
        step = r_new[o] - r_old[o]
        dev = log.y[start:cut, o] - r_new[o]
        if step == 0:
            over = float(np.abs(dev).max())
            pcts.append(None)
            settle.append(0.0)
        else:
            over = float(max(0.0, (dev * np.sign(step)).max()))
            pcts.append(100.0 * over / abs(step))
            outside = np.flatnonzero(np.abs(dev) > 0.02 * abs(step))
            settle.append(None if outside.size and outside[-1] == dev.size - 1
                          else (_time(outside[-1] + 1, ts) if outside.size else 0.0))
        overs.append(over)
    seg = {"t_start": _time(start, ts), "t_end": _time(end, ts),
           "settled_window_s": [_time(lo, ts), _time(hi, ts)],
           "reference": float(r_new[0]) if len(outputs) == 1 else r_new.tolist(),
           "step": float(r_new[0] - r_old[0]) if len(outputs) == 1 else (r_new - r_old).tolist(),
           "settled_error": float(err.max()),
           "overshoot": float(max(overs)),
           "overshoot_pct": pcts[0] if len(outputs) == 1 else pcts,
           "settling_time_s": (settle[0] if len(outputs) == 1 else
                               (None if None in settle else max(settle)))}
    if len(outputs) > 1:
        seg["settled_error_by_output"] = dict(zip(outputs, map(float, err)))
        seg["overshoot_by_output"] = dict(zip(outputs, overs))
    return seg


def constraint_violations(cfg: ControllerConfig, log: ClosedLoopLog) -> dict:
    """Counts of samples breaking an input or output constraint of the active mode."""
    u_bad = inactive = y_bad = 0
    for j, mode in enumerate(cfg.modes):
        rows = log.mode == j
        if not rows.any():
            continue
        acts = [cfg.actuators.index(a) for a in mode.actuators]
        u = log.u[rows][:, acts]
        u_bad += int(np.any((u < mode.u_min) | (u > mode.u_max), axis=1).sum())
        others = [a for a in range(len(cfg.actuators)) if a not in acts]
        if others:
            inactive += int(np.any(log.u[rows][:, others] != 0, axis=1).sum())
        y = log.y[rows]
        y_bad += int(np.any((y < mode.y_min) | (y > mode.y_max), axis=1).sum())
    return {"u": u_bad, "inactive_actuator_nonzero": inactive, "y": y_bad,
            "total": u_bad + inactive + y_bad}


def _stats(values: np.ndarray) -> dict:
    if values.size == 0:
        return {"median": None, "max": None}
    return {"median": float(np.median(values)), "max": float(values.max())}


def summarize(cfg: ControllerConfig, log: ClosedLoopLog) -> dict:
    """Every metric of the JSON summary (one controller's log)."""
    ts, N = cfg.sample_time, cfg.horizon
    segs = reference_segments(log.r)
    segments = [_segment_metrics(log, a, b, i == len(segs) - 1, N, ts, cfg.outputs)
                for i, (a, b) in enumerate(segs)]
    for i, s in enumerate(segments):
        s["index"] = i
    switch_k = np.flatnonzero(np.diff(log.mode) != 0) + 1
    names = [m.name for m in cfg.modes]
    statuses = {STATUS_NAMES.get(int(s), str(int(s))): int(n)
                for s, n in zip(*np.unique(log.status, return_counts=True))}
    by_mode = {}
    for j, name in enumerate(names):
        rows = log.mode == j
        by_mode[name] = {"samples": int(rows.sum()),
                         "max_iterations": int(log.iterations[rows].max()) if rows.any() else 0,
                         "solve_us": _stats(log.solve_us[rows])}
    soft = (None if log.slack_max is None else  # soft output bounds: slacks of the plans
            {"samples_with_slack": int(np.count_nonzero(log.slack_max > 0)),
             "max_slack": float(log.slack_max.max())})
    return {
        "soft_bounds": soft,
        "samples": int(len(log.t)),
        "duration_s": float(len(log.t) * ts),
        "segments": segments,
        "max_settled_error": max(s["settled_error"] for s in segments),
        "max_overshoot": max(s["overshoot"] for s in segments),
        "switches": int(switch_k.size),
        "switch_times_s": [_time(k, ts) for k in switch_k],
        "max_abs_u": {a: float(np.abs(log.u[:, i]).max()) for i, a in enumerate(cfg.actuators)},
        "total_variation_u": {a: float(np.abs(np.diff(log.u[:, i])).sum())
                              for i, a in enumerate(cfg.actuators)},
        "units": {"outputs": list(cfg.units.outputs), "actuators": list(cfg.units.actuators),
                  "schedule": cfg.units.schedule},
        "constraint_violations": constraint_violations(cfg, log),
        "non_optimal": int(np.count_nonzero(log.status != OPTIMAL)),
        "status_counts": statuses,
        "max_iterations": int(log.iterations.max()) if len(log.t) else 0,
        "solve_us": _stats(log.solve_us),
        "by_mode": by_mode,
    }
