"""The work budget against the step it must pay for, and its refusal with what fits.

A solve stops at ``solver.work_budget`` units (work.py); a budget below what the
solver charges before its first check (work.base_work: th0 with every stage its own
reference, the slacks, the output certificate and prediction, finish()) could not even
return the clamped unconstrained optimum, so it is refused.  The refusal states the
same step as generate's prediction (footprint.py): its units with a held reference
(work.free_step_work) and its estimated cycles, beside the worst case the budget must
cover, and what fits (fits.py: a shorter horizon or control horizon; the share or clock
the budget needs).  Why the units look dearer than the cycles: docs/checks.md, "One
figure per step".
"""
from __future__ import annotations

from ..config import ConfigError, ControllerConfig
from ..config.sample_time import seconds_text
from ..config.schema import WORK_BUDGET_AUTO
from .fits import at_least, what_fits
from .footprint import predict, rounded
from .sizes import mode_sizes
from .work import (STEP_FIXED_UNITS, WORK_LIMIT, base_work, cycles_per_work_unit, free_step_work,
                   largest_unit, work_budget_of)


def _need(modes) -> int:
    return max(base_work(m, m.has_output_rows) for m in modes)


def _sizes(cfg: ControllerConfig) -> tuple:
    return tuple(mode_sizes(cfg, m) for m in cfg.modes)


def _scalings(cfg: ControllerConfig, need: int) -> list[str]:
    """The share, clock or budget that pays for ``need`` units."""
    s = cfg.solver
    if s.work_budget != WORK_BUDGET_AUTO:
        return [f"solver.work_budget >= {need:,}"]
    cycles = (need + STEP_FIXED_UNITS) * cycles_per_work_unit(cfg)  # auto_work_budget()
    share = cycles / (cfg.sample_time * cfg.target.cpu_mhz * 1e6)
    mhz = cycles / (s.budget_share * cfg.sample_time * 1e6)
    out = [f"solver.budget_share >= {at_least(share)}"] if share <= 1 else []
    return out + [f"target.cpu_mhz >= {at_least(mhz)}"]


def check_work_budget(cfg: ControllerConfig, modes, factor: int) -> int:
    """The budget of ``cfg`` in work units, checked against every mode's unconstrained
    step (``modes``: each mode's ModeData, or its ModeSizes); refused with what fits."""
    budget = work_budget_of(cfg)
    for m in modes:
        if largest_unit(m, m.w_cap, factor) >= WORK_LIMIT:
            raise ConfigError("solver", f"mode {m.name}: its QP (n = {m.n}, m = {m.m}) is too "
                              f"large to count its work in 32 bits")
    if budget >= WORK_LIMIT:
        raise ConfigError("solver.work_budget", f"{budget} work units must be below {WORK_LIMIT}")
    need = _need(modes)
    if budget >= need:
        return budget
    s = cfg.solver
    how = (f"auto: {s.budget_share:g} of Ts = {seconds_text(cfg.sample_time)} at "
           f"{cfg.target.cpu_mhz:g} MHz, {cycles_per_work_unit(cfg):g} cycles per unit on the "
           f"{cfg.target.core_decl.label}, less {STEP_FIXED_UNITS} for the step outside the solver"
           if s.work_budget == WORK_BUDGET_AUTO else "given")
    sizes = _sizes(cfg)
    held = max(free_step_work(m) for m in sizes)
    fits = what_fits(cfg, lambda c: work_budget_of(c) >= _need(_sizes(c)),
                     _scalings(cfg, need))
    raise ConfigError("solver.work_budget", f"{budget:,} units ({how}) are below the {need:,} "
                      f"a step without active bounds may charge ({held:,} with a held "
                      f"reference, about {rounded(predict(cfg).step_cycles):,} cycles); {fits}")


def what_fits_need(cfg: ControllerConfig, need: int) -> str:
    """What fits a step measured to need ``need`` units (``rollmpc certify``): the share,
    clock or budget that pays for it, and the largest horizon or control horizon whose
    need, scaled as the unconstrained step's charge (base_work) scales, fits the budget:
    an estimate, to be certified again."""
    base = _need(_sizes(cfg))
    return what_fits(cfg, lambda c: work_budget_of(c) * base >= need * _need(_sizes(c)),
                     _scalings(cfg, need))
