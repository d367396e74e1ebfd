"""Fig. 2 metrics of a closed-loop log (``rollmpc simulate --json``).

Definitions (also in docs/paper-reproduction.md):

* **Segment**: a maximal run of samples with a constant reference (the paper's scenario
  has six of 10 s).
* **Settled window** of a segment: from 70 % of its length to N*Ts (the preview
  horizon) before the next reference step, so the window neither contains the transient
  of its own step nor the controller's anticipation of the next one (with the preview
  the MPC starts to move up to N samples early).  The last segment's window runs to its
  end.  For the paper's scenario: 7 s to 9 s of each 10 s segment (7 s to 10 s for the
  last).  It measures the steady-state offset, not the speed of the tail.  A segment
  other than the last that is not longer than N/0.3 samples (:func:`preview_free`) has
  no such window: its window falls back to its last 30 %, which contains the
  anticipation, so its settled error is flagged (``settled_window_includes_preview``),
  left out of ``max_settled_error`` and named in ``warnings``.
* **Settled error**: max |y - r| over the settled window (in the output's unit: deg for
  the UAV; the config's optional ``units`` only labels it), over the *weighted* outputs
  (:func:`weighted_outputs`: Q or P nonzero in some mode): an output the cost ignores is
  tracked by nobody, so its error (a buck's inductor current, Q = 0, against a scalar
  reference level) says nothing of the design; ``settled_error_by_output`` has each.
* **Settling time**: time from the step after which |y - r| stays within 2 % of the
  step size up to the anticipation cut-off (None if it never does; 0 without a step).
* **Overshoot**: how far y goes past the new reference, in the direction of the step,
  from the step up to the same anticipation cut-off (0 when it never goes past); in
  percent of the step size too.  For the first segment (no step) it is max |y - r|.
* **Constraint violation** (hard): a sample where an active actuator is outside its
  mode's [u_min, u_max], an inactive actuator is not exactly 0, or an output is outside a
  *hard* bound of the active mode, by more than the solver's own acceptance,
  ``feasibility_tol * max(1, |bound|)`` (the config's ``solver.feasibility_tol``: 1e-9
  double, 1e-4 float; e.g. 4.5e-8 deg at a 45 deg bound in double).  Roundoff at a bound
  is not a violation.  A constrained signal's hard bound (``constraints.signals`` and
  ``mixed``, read on the simulated plant: sim/signal_bounds.py) counts the same way
  (``z``); ``y_max_beyond`` names how far each output or signal passed one.
* **Soft-bound excursion**: a sample where an output is beyond a *soft* bound by more
  than that tolerance (``soft_bounds.samples_beyond``, largest ``max_beyond``), reported
  beside the plans' slack (``samples_with_slack``, ``max_slack``), never as a violation.
* **Total variation** of each actuator's command: sum over k of |u(k) - u(k-1)| (what
  Δu weighting, ``weights.R_delta``, reduces).
"""
from __future__ import annotations

import numpy as np

from ..config import ControllerConfig
from .signal_bounds import signal_violations
from .simulate import ClosedLoopLog
from ..status import OPTIMAL, STATUS_NAMES, TIME_LIMIT


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


def preview_free(start: int, end: int, last: bool, horizon: int) -> bool:
    """Does the settled window of this segment leave out the anticipation of the next step?"""
    return last or settled_window(start, end, last, horizon)[1] <= end - horizon


def shortest_preview_free_segment(horizon: int) -> int:
    """Samples a segment other than the last needs for a preview-free settled window."""
    return next(n for n in range(horizon, 4 * horizon + 10)
                if preview_free(0, n, False, horizon))


def short_segment_warnings(segments: list[dict], horizon: int, ts: float) -> list[str]:
    """One line naming the segments whose settled error includes the preview, if any."""
    short = [f"{s['t_start']:g}-{s['t_end']:g} s" for s in segments
             if s["settled_window_includes_preview"]]
    if not short:
        return []
    need = _time(shortest_preview_free_segment(horizon), ts)
    return [f"segment{'s' if len(short) > 1 else ''} {', '.join(short)} shorter than the "
            f"{need:g} s a settled window needs with N*Ts = {_time(horizon, ts):g} s of "
            "preview: the settled error there includes the anticipation of the next step "
            "and is left out of the max (lengthen simulation.reference.segment)"]


def weighted_outputs(cfg: ControllerConfig) -> np.ndarray:
    """Per output, whether some mode's cost weights it (a nonzero diagonal entry of Q or
    P); every output when none is (nothing to prefer)."""
    weighted = np.zeros(cfg.n_outputs, bool)
    for mode in cfg.modes:
        weighted |= (np.diag(mode.Q) != 0) | (np.diag(mode.P) != 0)
    return weighted if weighted.any() else np.ones(cfg.n_outputs, bool)


def _segment_metrics(log: ClosedLoopLog, start: int, end: int, last: bool, horizon: int,
                     ts: float, outputs: tuple[str, ...], weighted: np.ndarray) -> dict:
    r_new = log.r[start]
    r_old = log.r[start - 1] if start > 0 else log.r[start]
    lo, hi = settled_window(start, end, last, horizon)
    err = np.abs(log.y[lo:hi] - log.r[lo:hi]).max(axis=0)
    cut = end if last else max(start + 1, end - horizon)
    overs, pcts, settle = [], [], []
    stepped = [r_new[o] != r_old[o] and weighted[o] for o in range(len(outputs))]
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
           "settled_window_includes_preview": not preview_free(start, end, last, horizon),
           "reference": float(r_new[0]) if len(outputs) == 1 else r_new.tolist(),
           "step": float(r_new[0] - r_old[0]) if len(outputs) == 1 else (r_new - r_old).tolist(),
           "settled_error": float(err[weighted].max()),
           # over the weighted outputs whose reference steps here: another output's
           # excursion is in its own units (overshoot_by_output has it)
           "overshoot": float(max(o for o, s in zip(overs, stepped) if s) if any(stepped)
                              else max(o for o, w in zip(overs, weighted) if w)),
           "overshoot_pct": pcts[0] if len(outputs) == 1 else pcts,
           "settling_time_s": (settle[0] if len(outputs) == 1 else
                               (None if None in settle else max(settle)))}
    if len(outputs) > 1:
        seg["settled_error_by_output"] = dict(zip(outputs, map(float, err)))
        seg["overshoot_by_output"] = dict(zip(outputs, overs))
    return seg


def beyond(values: np.ndarray, lower: np.ndarray, upper: np.ndarray, tol: float) -> np.ndarray:
    """How far each value lies outside [lower, upper] (0 inside), counted only where that
    exceeds ``tol * max(1, |bound|)`` (the solver's acceptance of a row)."""
    with np.errstate(invalid="ignore"):  # an infinite value at an absent bound: NaN, not beyond
        low, high = lower - values, values - upper
        low = np.where(low > tol * np.maximum(1.0, np.abs(lower)), low, 0.0)
        high = np.where(high > tol * np.maximum(1.0, np.abs(upper)), high, 0.0)
    return np.maximum(low, high)


def _output_bounds(mode, soft: bool) -> tuple[np.ndarray, np.ndarray]:
    """The mode's hard (``soft`` False) or soft output bounds; the others unbounded."""
    is_soft = (np.zeros((len(mode.y_min), 2), bool) if mode.soft_l2 is None
               else mode.soft_l2 > 0)
    keep = is_soft if soft else ~is_soft
    return (np.where(keep[:, 0], mode.y_min, -np.inf), np.where(keep[:, 1], mode.y_max, np.inf))


def constraint_violations(cfg: ControllerConfig, log: ClosedLoopLog) -> dict:
    """Counts of samples breaking a hard input or output constraint of the active mode by
    more than the solver's tolerance (module docstring)."""
    u_bad = inactive = y_bad = 0
    y_excess = np.zeros(cfg.n_outputs)  # the farthest each output passes a hard bound
    tol = cfg.feasibility_tol
    for j, mode in enumerate(cfg.modes):
        rows = log.mode == j
        if not rows.any():
            continue
        acts = [cfg.actuators.index(a) for a in mode.actuators]
        u = log.u[rows][:, acts]
        u_bad += int(np.any(beyond(u, mode.u_min, mode.u_max, tol) > 0, axis=1).sum())
        others = [a for a in range(len(cfg.actuators)) if a not in acts]
        if others:
            inactive += int(np.any(log.u[rows][:, others] != 0, axis=1).sum())
        out = beyond(log.y[rows], *_output_bounds(mode, False), tol)
        y_bad += int(np.any(out > 0, axis=1).sum())
        y_excess = np.maximum(y_excess, out.max(axis=0))
    z_bad, z_far = (signal_violations(log.signals, log.z, log.mode, tol) if log.signals
                    else (0, {}))
    far = {name: float(v) for name, v in zip(cfg.outputs, y_excess) if v > 0}
    for name, v in z_far.items():
        far[name] = max(far.get(name, 0.0), v)
    return {"u": u_bad, "inactive_actuator_nonzero": inactive, "y": y_bad, "z": z_bad,
            "total": u_bad + inactive + y_bad + z_bad, "y_max_beyond": far}


def soft_bound_excursions(cfg: ControllerConfig, log: ClosedLoopLog) -> dict:
    """Samples whose output is beyond a soft bound of the active mode by more than the
    solver's tolerance, and the largest excursion (output units)."""
    excess = np.zeros(len(log.t))
    for j, mode in enumerate(cfg.modes):
        rows = log.mode == j
        if rows.any():
            excess[rows] = beyond(log.y[rows], *_output_bounds(mode, True),
                                  cfg.feasibility_tol).max(axis=1)
    return {"samples_beyond": int(np.count_nonzero(excess)),
            "max_beyond": float(excess.max()) if excess.size else 0.0}


def _stats(values: np.ndarray) -> dict:
    if values.size == 0:
        return {"median": None, "max": None}
    return {"median": float(np.median(values)), "max": float(values.max())}


def work_stats(work: np.ndarray | None, budget: int) -> dict | None:
    """The solver's work per sample (its deterministic count, qp/work.py) against its
    ``budget``: what a design needs, to size ``solver.budget_share`` (the same count on
    the host and on the MCU; a TIME_LIMIT sample's is where it stopped). None without a
    count (a baseline)."""
    if work is None or work.size == 0:
        return None
    return {"median": float(np.median(work)), "p99": int(np.percentile(work, 99, method="higher")),
            "max": int(work.max()), "budget": int(budget)}


def work_text(stats: dict) -> str:
    """The summary line's figures, e.g. ``median 6,720, p99 72,627, max 334,100 of a budget
    of 42,000``."""
    return (f"median {stats['median']:,.0f}, p99 {stats['p99']:,.0f}, max {stats['max']:,} "
            f"of a budget of {stats['budget']:,}")


def status_counts(statuses) -> dict:
    """How many solves ended with each status, by its name (``optimal``, ``time_limit``...)."""
    return {STATUS_NAMES.get(int(s), str(int(s))): int(n)
            for s, n in zip(*np.unique(np.asarray(statuses, int), return_counts=True))}


def longest_run(statuses, status: int = TIME_LIMIT) -> int:
    """The most consecutive samples that ended with ``status``."""
    longest = run = 0
    for s in np.asarray(statuses, int):
        run = run + 1 if s == status else 0
        longest = max(longest, run)
    return longest


def time_limit_warning(counts: dict, samples: int, longest: int = 0,
                       horizon: int | None = None) -> str | None:
    """What ``simulate`` and ``report`` say when solves stopped at the work budget; with
    the ``longest`` run of them and the ``horizon``, whether a run outlasted the shifted
    plan a TIME_LIMIT sample falls back to (horizon - 1 samples)."""
    limited = counts.get("time_limit", 0)
    if not limited:
        return None
    outlasted = ""
    if horizon is not None and longest > horizon - 1:
        outlasted = (f" The longest run, {longest} samples, outlasted the last plan (it covers "
                     f"{horizon - 1}): past it a TIME_LIMIT sample without a point of its own "
                     f"commands the unconstrained optimum clamped to the input bounds, which "
                     f"ignores the output bounds.")
    return (f"{limited} of {samples} samples ({100 * limited / samples:.1f} %) stopped at the "
            f"work budget (TIME_LIMIT): their commands are the best point found in time, inside "
            f"the input bounds but not necessarily the output bounds.{outlasted} Give the "
            f"solver more of Ts (solver.budget_share, target.cpu_mhz) or a smaller QP "
            f"(docs/solver.md, \"Work budget\"); `rollmpc simulate` of a copy with a large "
            f"solver.work_budget prints the work its samples need")


def summarize(cfg: ControllerConfig, log: ClosedLoopLog) -> dict:
    """Every metric of the JSON summary (one controller's log)."""
    ts, N = cfg.sample_time, cfg.horizon
    segs = reference_segments(log.r)
    weighted = weighted_outputs(cfg)
    segments = [_segment_metrics(log, a, b, i == len(segs) - 1, N, ts, cfg.outputs, weighted)
                for i, (a, b) in enumerate(segs)]
    for i, s in enumerate(segments):
        s["index"] = i
    switch_k = np.flatnonzero(np.diff(log.mode) != 0) + 1
    names = [m.name for m in cfg.modes]
    statuses = status_counts(log.status)
    by_mode = {}
    for j, name in enumerate(names):
        rows = log.mode == j
        by_mode[name] = {"samples": int(rows.sum()),
                         "max_iterations": int(log.iterations[rows].max()) if rows.any() else 0,
                         "solve_us": _stats(log.solve_us[rows])}
    soft = (None if log.slack_max is None else  # soft output bounds: slacks of the plans
            {"samples_with_slack": int(np.count_nonzero(log.slack_max > 0)),
             "max_slack": float(log.slack_max.max()), **soft_bound_excursions(cfg, log)})
    clean = [s["settled_error"] for s in segments if not s["settled_window_includes_preview"]]
    return {
        "soft_bounds": soft,
        "samples": int(len(log.t)),
        "duration_s": float(len(log.t) * ts),
        "segments": segments,
        "max_settled_error": max(clean, default=None),
        "weighted_outputs": [name for name, w in zip(cfg.outputs, weighted) if w],
        "warnings": short_segment_warnings(segments, N, ts),
        "max_overshoot": max(s["overshoot"] for s in segments),
        "switches": int(switch_k.size),
        "switch_times_s": [_time(k, ts) for k in switch_k],
        "max_abs_u": {a: float(np.abs(log.u[:, i]).max()) for i, a in enumerate(cfg.actuators)},
        "total_variation_u": {a: float(np.abs(np.diff(log.u[:, i])).sum())
                              for i, a in enumerate(cfg.actuators)},
        "units": {"outputs": list(cfg.units.outputs), "actuators": list(cfg.units.actuators),
                  "schedule": cfg.units.schedule},
        "constraint_violations": constraint_violations(cfg, log),
        "violation_tolerance": cfg.feasibility_tol,
        "non_optimal": int(np.count_nonzero(log.status != OPTIMAL)),
        "status_counts": statuses,
        "longest_time_limit_run": longest_run(log.status),
        "max_iterations": int(log.iterations.max()) if len(log.t) else 0,
        "solve_us": _stats(log.solve_us),
        "by_mode": by_mode,
    }
