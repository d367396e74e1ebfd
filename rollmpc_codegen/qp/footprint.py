"""What a configuration will cost on its target, predicted from the config alone before
the dense maths, and the verdict ``rollmpc generate`` refuses on unless ``--force-size``.

A horizon of 400 was once generated silently: 71-82 s, 69 MB of files, 6.5 MB of flash
data and a 3 MB controller instance (issue 18).  Now ``generate`` prints the prediction
(before the maths when that maths is slow, :attr:`Footprint.slow`) and refuses a design
beyond its ``target:`` section:

* **The build judged** is the one the target's FPU runs (parts.py
  ``Core.judged_precision``): the generated precision on a double-precision FPU (the
  Cortex-M7), else the float build whatever precision is generated, since the
  single-precision parts (Cortex-M4F, M33) run the float build and the cycle estimate is
  for it.  So on those a config is accepted or refused the same in both precisions; the
  paper's config declares its M4F's 256 KiB, which its float build meets and its double
  reference build (the host's, twice the data) never could.  A double build's own data and
  instance are printed beside.
* **flash** = the stored data (:func:`.sizes.stored_bytes`, exact when nx is) plus the
  core's code allowance (parts.py ``Core.code_bytes``); **RAM** = one ``P_ctrl``
  (:func:`.sizes.struct_bytes`).
* **cycles**: an *estimate* of a step with no active bound (the unconstrained solution,
  the row checks, every observer), which every step costs at least; steps with active
  bounds cost more (the paper config's worst is 19 times its median, quad_attitude's 12
  times: ``rollmpc report`` measures them).  It is stated in the solver's own work units
  too, the count its budget is in (work.free_step_work: exact for a held reference whose
  output rows the cheap bound certifies), and the cycles come from those units:
  :data:`CYCLES_PER_FREE_UNIT` per unit plus :data:`FIXED_STEP_CYCLES` of a step's
  costs outside the solver's count (P_step, the scheduler, the observers, the first
  move), fitted on the median steps measured on the emulated M4F (docs/checks.md, "One
  figure per step"): uav_roll at N = 25, 50, 100, 200, uav_roll_blocked, quad_attitude,
  chain_of_masses' certified steps and the two designs of tests/data/newuser (buck.yaml,
  ship_heading.yaml); each within 13 %.  Not counted: the output rows' prediction when
  the bound cannot certify them (the buck at N = 12 pays it on its median step: the
  estimate is low there).
  On another core the cycles are scaled by its cycles per work unit over the M4F's (the
  same arithmetic, at that core's cost per unit: parts.py).
* **limits**: ``target.flash_kib`` and ``target.ram_kib`` (when absent,
  schema.DEFAULT_FLASH_LIMIT_KIB / DEFAULT_RAM_LIMIT_KIB), and the cycles of one sample
  time at ``target.cpu_mhz``.  The safety limits of :func:`.sizes.check_sizes` come first
  and no flag lifts them.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import ConfigError, ControllerConfig
from ..config.schema import DEFAULT_FLASH_LIMIT_KIB, DEFAULT_RAM_LIMIT_KIB
from ..parts import CORTEX_M4F
from .fits import at_least, what_fits
from .sizes import (ModeSizes, condensing_bytes, largest_mode, mode_sizes, stored_bytes,
                    struct_bytes)
from .work import STEP_FIXED_UNITS, free_step_work, work_budget_of

CYCLES_PER_FREE_UNIT = 11  # per work unit of a step without active bounds (a fit, above)
FIT_CORE = CORTEX_M4F  # the core both were fitted on (another core's scales them)
# per step, outside the solver's count: the units the auto budget leaves for it, in cycles
FIXED_STEP_CYCLES = int(STEP_FIXED_UNITS * FIT_CORE.cycles_per_work_unit("float"))
# dense condensing matrices beyond this take about a second (N = 150 for the paper's
# plant on this machine): the prediction is then printed before the maths, not after
SLOW_MATHS_BYTES = 1 << 20
KIB = 1024


@dataclass(frozen=True)
class Footprint:
    """The prediction of one config (every size in bytes)."""

    target: str  # the part (or core) and clock, for people
    precision: str  # of the build being generated
    judged: str  # the precision of the build the target runs (judged below)
    data_bytes: int  # its stored data
    ctrl_bytes: int  # its P_ctrl instance
    code_bytes: int  # the target core's code allowance (parts.py Core.code_bytes)
    flash_bytes: int  # the judged build: data + code_bytes
    ram_bytes: int  # the judged build's P_ctrl
    step_cycles: int  # estimated unconstrained step of the judged build
    step_units: int  # the same step in the solver's work units (held reference)
    work_budget: int  # the solver's budget in those units
    flash_limit: int
    ram_limit: int
    cycle_budget: int
    flash_declared: bool  # the limits come from target: (else the defaults)
    ram_declared: bool
    largest_mode: str  # the mode with the largest QP, for messages
    slow: bool  # the dense maths will take a second or more

    def summary(self) -> list[str]:
        """The lines ``rollmpc generate`` prints."""
        def of(size: int, limit: int, declared: bool) -> str:
            return (f"{size / KIB:.1f} of {limit / KIB:g} KiB"
                    + ("" if declared else " (default limit)"))

        lines = [f"predicted on {self.target} ({self.judged} build): flash "
                 f"{of(self.flash_bytes, self.flash_limit, self.flash_declared)}, RAM "
                 f"{of(self.ram_bytes, self.ram_limit, self.ram_declared)}, a step without "
                 f"active bounds about {rounded(self.step_cycles):,} of the "
                 f"{self.cycle_budget:,} cycles of a sample and {self.step_units:,} of the "
                 f"solver's {self.work_budget:,} work units (an estimate; active bounds "
                 "cost more)"]
        if self.precision != self.judged:
            lines.append(f"this {self.precision} build: data {self.data_bytes / KIB:.1f} "
                         f"KiB, controller instance {self.ctrl_bytes / KIB:.1f} KiB")
        return lines


def rounded(value: int) -> int:
    """Three significant digits: the estimate is not better."""
    return int(round(value, 2 - len(str(abs(int(value))))))


def step_cycles(sizes: tuple[ModeSizes, ...], scale: float = 1.0) -> int:
    """Estimated cycles of a step without active bounds: the work units of the costliest
    mode's free step (work.free_step_work) at CYCLES_PER_FREE_UNIT, and the step's fixed
    costs (module docstring); ``scale``: the target core's cost per work unit over
    FIT_CORE's."""
    return int(round(scale * (CYCLES_PER_FREE_UNIT * max(free_step_work(s) for s in sizes)
                              + FIXED_STEP_CYCLES)))


def predict(cfg: ControllerConfig) -> Footprint:
    """The footprint of ``cfg`` on its target, from its sizes alone (no plant maths)."""
    sizes = tuple(mode_sizes(cfg, m) for m in cfg.modes)
    target, core = cfg.target, cfg.target.core_decl
    judged = core.judged_precision(cfg.precision)
    scale = core.cycles_per_work_unit(judged) / FIT_CORE.cycles_per_work_unit("float")
    return Footprint(
        target=target.label, precision=cfg.precision, judged=judged,
        data_bytes=stored_bytes(cfg, sizes), ctrl_bytes=struct_bytes(cfg, sizes),
        code_bytes=core.code_bytes,
        flash_bytes=stored_bytes(cfg, sizes, judged) + core.code_bytes,
        ram_bytes=struct_bytes(cfg, sizes, judged), step_cycles=step_cycles(sizes, scale),
        step_units=max(free_step_work(s) for s in sizes), work_budget=work_budget_of(cfg),
        flash_limit=int(KIB * (target.flash_kib or DEFAULT_FLASH_LIMIT_KIB)),
        ram_limit=int(KIB * (target.ram_kib or DEFAULT_RAM_LIMIT_KIB)),
        cycle_budget=cfg.cycles_per_sample, flash_declared=target.flash_kib is not None,
        ram_declared=target.ram_kib is not None, largest_mode=largest_mode(sizes),
        slow=sum(condensing_bytes(s) for s in sizes) > SLOW_MATHS_BYTES)


def _cycles_fit(cfg: ControllerConfig) -> bool:
    return predict(cfg).step_cycles <= cfg.cycles_per_sample


def check_fits(cfg: ControllerConfig, fp: Footprint) -> None:
    """Refuse a design beyond its target (the first of flash, RAM, cycles), one line
    naming the figure and the limit."""
    def limit(key: str, value: int, declared: bool) -> str:
        return (f"target.{key} = {value / KIB:g}" if declared
                else f"the default limit of {value / KIB:g} KiB (set target.{key})")

    why = None
    if fp.flash_bytes > fp.flash_limit:
        why = (f"needs about {fp.flash_bytes / KIB:,.0f} KiB of flash "
               f"({(fp.flash_bytes - fp.code_bytes) / KIB:,.0f} KiB of data + "
               f"{fp.code_bytes // KIB} KiB of code; {fp.largest_mode}), above "
               f"{limit('flash_kib', fp.flash_limit, fp.flash_declared)}")
    elif fp.ram_bytes > fp.ram_limit:
        why = (f"needs about {fp.ram_bytes / KIB:,.0f} KiB of RAM for one controller "
               f"instance ({fp.largest_mode}), above "
               f"{limit('ram_kib', fp.ram_limit, fp.ram_declared)}")
    elif fp.step_cycles > fp.cycle_budget:
        mhz = fp.step_cycles / (cfg.sample_time * 1e6)
        ts = fp.step_cycles / (cfg.target.cpu_mhz * 1e6)
        fits = what_fits(cfg, _cycles_fit, [f"target.cpu_mhz >= {at_least(mhz)}",
                                            f"sample_time >= {at_least(ts)}"])
        why = (f"would take about {rounded(fp.step_cycles):,} cycles ({fp.step_units:,} work "
               f"units) for a step without active bounds (an estimate; {fp.largest_mode}), "
               f"above the {fp.cycle_budget:,} of one sample (sample_time {cfg.sample_time:g} "
               f"s at target.cpu_mhz = {cfg.target.cpu_mhz:g}); {fits}")
    if why is not None:
        raise ConfigError("horizon", f"too large for the target: the {fp.judged} build {why}; "
                          "--force-size generates it anyway")
