"""The design warnings of ``generate`` (docs/checks.md), collected once for every front
end: :func:`design_warnings` is what ``rollmpc generate`` prints, what
``Design.generate`` returns and what ``simulate`` repeats.

Besides the two older checks (qp/nominal_loop.py: a loop that diverges where no bound
is active; qp/feasibility.py: hard bounds no input meets from rest), the sanity checks a
control engineer runs by eye, each naming the key to change:

* ``sample_time_coarse``: the plant's fastest pole s against the sample time: beyond
  |s| Ts = pi an oscillation is past the Nyquist frequency and a real mode has decayed
  to 4 % within one sample (the buck at Ts = 5 ms: 33.7 rad); the controller can neither
  see nor act on it.  (Far beyond, a wrong unit, it is a config error:
  config/sample_time.py.)
* ``horizon_short``: the slowest mode of the nominal closed loop (qp/nominal_loop.py)
  against N Ts: a time constant more than HORIZON_SHORT_FACTOR horizons long means the
  plans see a sliver of the response (a sample time far too small, e.g. in a wrong unit
  the other way).
* ``output_scale``: what the inputs within their bounds can make an output reach
  (model/reach.py) against the range its bounds and references span: decades below, the
  controller cannot get there (a buck with B off by 1e6 settled with an error equal to
  its reference); decades above within the horizon, B or C is likely in other units.
* ``work_budget_beyond_sample``: an explicit ``solver.work_budget`` that, even at the
  fewest cycles per unit measured, takes longer than a sample period.
"""
from __future__ import annotations

import math

import numpy as np

from ..config import ControllerConfig
from ..config.diagnostics import DesignWarning
from ..config.sample_time import RESOLVED_RAD, fastest_pole, pole_text, seconds_text
from ..config.schema import WORK_BUDGET_AUTO
from ..model.controller import ControllerModel
from ..model.reach import output_reach
from .feasibility import rest_warnings
from .nominal_loop import UNSTABLE_BEYOND, closed_loop_eigenvalues, unstable_law_warnings
from .work import FEWEST_CYCLES_PER_WORK_UNIT

HORIZON_SHORT_FACTOR = 10.0  # the examples' largest ratio is 1.9 (c172_roll)
# reach / expected range beyond which the units are suspect: the examples span 0.049
# (uav_roll's roll in +-270 deg) to 9.7 (quad_attitude) within the horizon
SCALE_BELOW, SCALE_ABOVE = 1e-3, 1e4


def sample_time_warnings(cfg: ControllerConfig) -> list[DesignWarning]:
    """``sample_time_coarse`` (module docstring)."""
    fastest = fastest_pole(cfg.modes)
    if fastest is None:
        return []
    j, s = fastest
    rad = abs(s) * cfg.sample_time
    if rad <= RESOLVED_RAD:
        return []
    what = (f"it turns {abs(s.imag) * cfg.sample_time / (2 * math.pi):.2g} times per sample, "
            "past the Nyquist frequency" if abs(s.imag) > 1e-12 * abs(s) else
            f"it decays to {math.exp(-rad):.2g} within one sample")
    return [DesignWarning(
        "sample_time_coarse", "sample_time",
        f"sample_time {seconds_text(cfg.sample_time)} is {rad:.3g} rad at the plant's fastest "
        f"pole (modes[{j}] {cfg.modes[j].name}: {pole_text(s)}): {what}, so the controller "
        "can neither see nor act on that mode; sample at most "
        f"{seconds_text(RESOLVED_RAD / abs(s))} (|s| Ts = pi), better ten times faster")]


def horizon_warnings(model: ControllerModel) -> list[DesignWarning]:
    """``horizon_short`` (module docstring), one per mode."""
    cfg, found = model.config, []
    span = cfg.horizon * cfg.sample_time
    for j, mode in enumerate(cfg.modes):
        mags = np.abs(closed_loop_eigenvalues(model, j))
        decaying = mags[(mags > 0) & (mags < 1.0 - UNSTABLE_BEYOND)]
        if decaying.size == 0:
            continue
        slowest = float(decaying.max())
        tau = -cfg.sample_time / math.log(slowest)
        if tau > HORIZON_SHORT_FACTOR * span:
            found.append(DesignWarning(
                "horizon_short", "horizon",
                f"modes[{j}] ({mode.name}): the horizon N Ts = {seconds_text(span)} is 1/"
                f"{tau / span:,.0f} of the slowest closed-loop time constant "
                f"({seconds_text(tau)}, z = {slowest:.6g}): the plans see a sliver of the "
                "response; lengthen the horizon or the sample time (is sample_time in "
                "seconds?)"))
    return found


def _expected_span(mode, levels: np.ndarray, a: int) -> float:
    """The span of the hull of 0, output a's finite bounds and its reference levels."""
    values = [0.0, *(b for b in (mode.y_min[a], mode.y_max[a]) if math.isfinite(b)),
              *levels[:, a]]
    return max(values) - min(values)


def scale_warnings(model: ControllerModel) -> list[DesignWarning]:
    """``output_scale`` (module docstring), one per mode and output."""
    cfg, found = model.config, []
    levels = cfg.simulation.levels(cfg.n_outputs)
    units = cfg.units.outputs or ("",) * cfg.n_outputs
    for j, (mode, mm) in enumerate(zip(cfg.modes, model.modes)):
        low, high = output_reach(mm.plant, mode.u_min, mode.u_max, cfg.horizon)
        h_low, h_high = output_reach(mm.plant, mode.u_min, mode.u_max, cfg.horizon, False)
        for a, name in enumerate(cfg.outputs):
            expected = _expected_span(mode, levels, a)
            unit = f" {units[a]}" if units[a] else ""
            if not expected > 0:
                continue
            reach, within = high[a] - low[a], h_high[a] - h_low[a]
            if reach < SCALE_BELOW * expected:
                how = (f"move {name} by at most {reach:.3g}{unit}, {reach / expected:.2g} of "
                       f"the {expected:.3g}{unit} its bounds and references span: the "
                       "controller cannot get there (the error stays about the reference)")
            elif within > SCALE_ABOVE * expected:
                how = (f"move {name} by {within:.3g}{unit} within the horizon, "
                       f"{within / expected:.2g} times the {expected:.3g}{unit} its bounds "
                       "and references span: the commands need a fraction of their range")
            else:
                continue
            found.append(DesignWarning(
                "output_scale", f"modes[{j}].plant",
                f"modes[{j}] ({mode.name}): the inputs within their bounds {how}; are B or C "
                "(plant) in other units than the bounds and the reference?"))
    return found


def budget_warnings(cfg: ControllerConfig) -> list[DesignWarning]:
    """``work_budget_beyond_sample`` (module docstring)."""
    budget = cfg.solver.work_budget
    if budget == WORK_BUDGET_AUTO or not cfg.solver.polish:
        return []
    fewest = int(budget) * FEWEST_CYCLES_PER_WORK_UNIT
    if fewest <= cfg.cycles_per_sample:
        return []
    fits = int(cfg.cycles_per_sample // FEWEST_CYCLES_PER_WORK_UNIT)
    return [DesignWarning(
        "work_budget_beyond_sample", "solver.work_budget",
        f"solver.work_budget {int(budget):,} units take at least {fewest:,.0f} cycles (at "
        f"the fewest {FEWEST_CYCLES_PER_WORK_UNIT:g} cycles per unit measured), "
        f"{fewest / cfg.cycles_per_sample:.2g} sample periods of {cfg.cycles_per_sample:,} "
        f"(Ts = {seconds_text(cfg.sample_time)} at target.cpu_mhz = {cfg.target.cpu_mhz:g}): a "
        f"solve that spends it misses its deadline; use auto (solver.budget_share) or at "
        f"most {fits:,}")]


def design_warnings(model: ControllerModel) -> list[DesignWarning]:
    """Every design warning of ``generate``, in the order it prints them."""
    cfg = model.config
    return [*unstable_law_warnings(model), *rest_warnings(model), *sample_time_warnings(cfg),
            *horizon_warnings(model), *scale_warnings(model), *budget_warnings(cfg)]
