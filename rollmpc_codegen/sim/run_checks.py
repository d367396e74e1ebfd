"""The warnings of a run (``simulate``, ``simulate --flights``, ``report``) as
DesignWarnings (docs/checks.md): what the CLI prints under its summary and what the
library returns on ``.warnings`` (and in the JSON as ``checks``).

* ``short_segment``: a segment too short for a settled window without the preview
  (metrics.short_segment_warnings);
* ``time_limit``: samples stopped at the work budget (metrics.time_limit_warning);
* ``infeasible_samples``: samples whose QP was INFEASIBLE (without any, but with an
  output past a hard bound: ``hard_bound_passed``, which sends a run with TIME_LIMIT
  samples to the unbudgeted copy first: a new user's converter, nominal, passed its
  current bound by 10 times its value only where the budget stopped it).  Hard output bounds under
  noise, a disturbance or a mismatched plant: a drone whose vertical speed is bounded hard
  flew 135 of 500 samples INFEASIBLE and 3.99 m/s past the bound with only the TIME_LIMIT
  warning.  An INFEASIBLE command keeps the input bounds only; soft bounds
  (``bounds.soft``) keep the QP feasible and name the excursion instead.
"""
from __future__ import annotations

import numpy as np

from ..config import ControllerConfig
from ..config.diagnostics import DesignWarning
from ..status import INFEASIBLE, STATUS_NAMES, TIME_LIMIT
from .metrics import time_limit_warning

INFEASIBLE_NAME = STATUS_NAMES[INFEASIBLE]


def time_limit_check(counts: dict, samples: int, longest: int,
                     horizon: int) -> list[DesignWarning]:
    text = time_limit_warning(counts, samples, longest, horizon)
    return [] if text is None else [DesignWarning("time_limit", "solver.budget_share", text)]


def _soft_hint(cfg: ControllerConfig, j: int) -> str:
    """``modes[j].bounds.soft: {y_max: {l1: 0, l2: 1000}}`` for the mode's hard finite sides."""
    mode = cfg.modes[j]
    soft = np.zeros((cfg.n_outputs, 2), bool) if mode.soft_l2 is None else mode.soft_l2 > 0
    sides = [name for side, (name, bound) in enumerate((("y_min", mode.y_min),
                                                        ("y_max", mode.y_max)))
             if np.any(np.isfinite(bound) & ~soft[:, side])]
    inner = ", ".join(f"{s}: {{l1: 0, l2: 1000}}" for s in sides)
    return f"modes[{j}].bounds.soft: {{{inner}}}"


def output_units(cfg: ControllerConfig) -> dict:
    """Each output's unit ("" without ``units``; a constrained signal has none)."""
    return dict(zip(cfg.outputs, cfg.units.outputs or ("",) * cfg.n_outputs))


def beyond_text(cfg: ControllerConfig, y_beyond: dict) -> str:
    """How far each output or signal passed a hard bound, with its unit, e.g. ``roll 23.5
    deg, iq 16.2``."""
    unit = output_units(cfg)
    return ", ".join(f"{name} {v:.3g}{' ' + unit[name] if unit.get(name) else ''}"
                     for name, v in y_beyond.items())


def _signal_hint(cfg: ControllerConfig, names) -> tuple[str, str] | None:
    """(key, text) of the first constrained signal among ``names``: where to make it soft."""
    for mode in cfg.modes:
        for s in mode.signals:
            if s.name in names:
                return s.key, f"{s.key}.soft: {{l1: 0, l2: 1000}}"
    return None


def infeasible_check(cfg: ControllerConfig, statuses: np.ndarray, modes: np.ndarray,
                     y_beyond: dict, keys=None) -> list[DesignWarning]:
    """``infeasible_samples``, or without them ``hard_bound_passed`` (module docstring):
    ``statuses`` and ``modes`` per sample, ``y_beyond`` how far each output passed a hard
    bound (metrics.constraint_violations); ``keys`` (a Counter, sim/infeasible_rows.py):
    the constraints the infeasible samples' QPs could not meet, by config key."""
    bad = np.asarray(statuses) == INFEASIBLE
    far = beyond_text(cfg, y_beyond)
    if not bad.any():
        if not far:
            return []
        j = int(np.bincount(np.asarray(modes), minlength=len(cfg.modes)).argmax())
        outputs = [name for name in y_beyond if name in cfg.outputs]
        signal = _signal_hint(cfg, [name for name in y_beyond if name not in outputs])
        key, hint, doc = (f"modes[{j}].bounds.soft", _soft_hint(cfg, j), "Soft output bounds")
        if signal and not outputs:
            (key, hint), doc = signal, "General constraints"
        stopped = int(np.count_nonzero(np.asarray(statuses) == TIME_LIMIT))
        first = (f" With {stopped} samples stopped at the work budget, first see whether the "
                 "bound holds without it: `rollmpc simulate` of a copy with a large "
                 "solver.work_budget (--against-unbudgeted with --flights); if it does, the "
                 "stops cost it: give the solver more of Ts or a smaller QP. Else tighten"
                 if stopped else " Tighten")
        return [DesignWarning(
            "hard_bound_passed", key,
            f"the {'outputs' if not signal else 'signals' if not outputs else 'outputs and signals'}"
            f" passed a hard bound by up to {far}: a plan keeps the bounds on the "
            "model (a TIME_LIMIT one not even there), not on a plant that noise, disturbance "
            f"or mismatch take elsewhere.{first} the bound by that margin or make it soft, e.g. "
            f"{hint} (docs/features.md, \"{doc}\")")]
    counts = np.bincount(np.asarray(modes)[bad], minlength=len(cfg.modes))
    j = int(counts.argmax())
    passed = f", and the outputs passed them by up to {far}" if far else ""
    keys = keys or {}
    signal = [k for k in keys if ".constraints." in k]
    if signal:  # a constraint beyond the bounds: soften it where it is declared
        return [DesignWarning(
            "infeasible_samples", max(signal, key=keys.get),
            f"{int(bad.sum())} of {bad.size} samples ({100 * bad.mean():.1f} %) were "
            f"INFEASIBLE{passed}: no input within its bounds met {_named(keys)}; an "
            "INFEASIBLE command keeps the input bounds only. Make it soft (soft: {l1, l2}), "
            "or start it where the input reaches it (stages) (docs/features.md, \"General "
            "constraints\")")]
    which = f" (the QPs could not meet {_named(keys)})" if keys else ""
    return [DesignWarning(
        "infeasible_samples", f"modes[{j}].bounds.soft",
        f"{int(bad.sum())} of {bad.size} samples ({100 * bad.mean():.1f} %) were INFEASIBLE "
        f"(most in modes[{j}] {cfg.modes[j].name}): no input within its bounds met the hard "
        f"output bounds from where noise, disturbance or mismatch took the plant{passed}"
        f"{which}; an INFEASIBLE command keeps the input bounds only. Make the output bounds "
        f"soft, e.g. {_soft_hint(cfg, j)} (docs/features.md, \"Soft output bounds\")")]


def _named(keys) -> str:
    """``a (5 of the diagnosed samples), b (2)``: the keys, most often broken first."""
    items = sorted(keys.items(), key=lambda kv: (-kv[1], kv[0]))
    return ", ".join(f"{k} ({n} of the diagnosed samples)" if i == 0 else f"{k} ({n})"
                     for i, (k, n) in enumerate(items))


def scenario_checks(cfg: ControllerConfig, summary: dict, statuses: np.ndarray,
                    modes: np.ndarray, design: list[DesignWarning],
                    infeasible_keys=None) -> list[DesignWarning]:
    """Every warning of one closed loop (``summary``: metrics.summarize's), then the
    design's (qp/sanity.py); ``infeasible_keys``: infeasible_check's ``keys``."""
    found = [DesignWarning("short_segment", "simulation.reference.segment", text)
             for text in summary["warnings"]]
    found += time_limit_check(summary["status_counts"], summary["samples"],
                              summary["longest_time_limit_run"], cfg.horizon)
    found += infeasible_check(cfg, statuses, modes,
                              summary["constraint_violations"]["y_max_beyond"],
                              infeasible_keys)
    return found + list(design)
