"""What a configuration will cost on its target, predicted from the config alone before
the dense maths, and the verdict ``rollmpc generate`` refuses on unless ``--force-size``.

A horizon of 400 was once generated silently: 71-82 s, 69 MB of files, 6.5 MB of flash
data and a 3 MB controller instance (issue 18).  Now ``generate`` prints the prediction
(before the maths when that maths is slow, :attr:`Footprint.slow`) and refuses a design
beyond its ``target:`` section:

* **The build judged** is the float build whatever precision is generated: the target is
  the single-precision part ``rollmpc report`` emulates (Cortex-M4F) and firmware_stub
  builds for, and the cycle estimate is for it.  So a config is accepted or refused the
  same in both precisions; the paper's config declares its M4F's 256 KiB, which its float
  build meets and its double reference build (the host's, twice the data) never could.
  A double build's own data and instance are printed beside.
* **flash** = the stored data (:func:`.sizes.stored_bytes`, exact when nx is) plus
  :data:`CODE_FLASH_BYTES`; **RAM** = one ``P_ctrl`` (:func:`.sizes.struct_bytes`).
* **cycles**: an *estimate* of a step with no active bound (the unconstrained solution,
  the row checks, every observer), which every step costs at least; steps with active
  bounds cost more (the paper config's worst is 19 times its median, quad_attitude's 12
  times: ``rollmpc report`` measures them).  :data:`CYCLES_PER_MAC` and
  :data:`CYCLES_PER_ROW` are a fit (least squares, relative, rounded to err high) on the
  median steps measured on the emulated M4F (docs/target.md, "Before generation"):
  uav_roll at N = 25, 50, 100, 200, uav_roll_blocked, quad_attitude, and of
  chain_of_masses the steps whose output rows the cheap bound certifies; each within 9 %.
  Not counted: the output rows' N^2/2 prediction when that bound cannot certify them
  (chain_of_masses' median step pays it: 1.7 times the estimate) and a step's fixed
  calls (uav_roll at N = 25: 8 % low).
* **limits**: ``target.flash_kib`` and ``target.ram_kib`` (when absent,
  schema.DEFAULT_FLASH_LIMIT_KIB / DEFAULT_RAM_LIMIT_KIB), and the cycles of one sample
  time at ``target.cpu_mhz``.  The safety limits of :func:`.sizes.check_sizes` come first
  and no flag lifts them.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import ConfigError, ControllerConfig
from ..config.schema import DEFAULT_FLASH_LIMIT_KIB, DEFAULT_RAM_LIMIT_KIB
from .sizes import (ModeSizes, condensing_bytes, largest_mode, mode_sizes, stored_bytes,
                    struct_bytes)

# the text of every generated function on the M4F at -O2 (-ffunction-sections, none
# dropped): 29,804 to 33,552 B over the examples with the four-row back substitution and
# correct()'s column pairs (29,016 to 32,704 at 57967e4; docs/target.md, "Before
# generation"); the paper config's linked image keeps about 30 KB of it. It was 18 KiB,
# then 32 KiB, until the solver grew past it: measure again when the templates grow
# (tests/target/test_code_flash_allowance.py).
CODE_FLASH_BYTES = 36 * 1024
CYCLES_PER_MAC = 10  # per multiply-add of the step's linear algebra (a fit, see above)
CYCLES_PER_ROW = 60  # per constraint row checked
# dense condensing matrices beyond this take about a second (N = 150 for the paper's
# plant on this machine): the prediction is then printed before the maths, not after
SLOW_MATHS_BYTES = 1 << 20
KIB = 1024


@dataclass(frozen=True)
class Footprint:
    """The prediction of one config (every size in bytes)."""

    precision: str  # of the build being generated
    data_bytes: int  # its stored data
    ctrl_bytes: int  # its P_ctrl instance
    flash_bytes: int  # the float build: data + CODE_FLASH_BYTES
    ram_bytes: int  # the float build's P_ctrl
    step_cycles: int  # estimated unconstrained step of the float build
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

        lines = [f"predicted on the target (float build): flash "
                 f"{of(self.flash_bytes, self.flash_limit, self.flash_declared)}, RAM "
                 f"{of(self.ram_bytes, self.ram_limit, self.ram_declared)}, a step without "
                 f"active bounds about {_rounded(self.step_cycles):,} of the "
                 f"{self.cycle_budget:,} cycles of a sample (an estimate; active bounds "
                 "cost more)"]
        if self.precision != "float":
            lines.append(f"this {self.precision} build: data {self.data_bytes / KIB:.1f} "
                         f"KiB, controller instance {self.ctrl_bytes / KIB:.1f} KiB")
        return lines


def _rounded(value: int) -> int:
    """Three significant digits: the estimate is not better."""
    return int(round(value, 2 - len(str(abs(int(value))))))


def step_cycles(sizes: tuple[ModeSizes, ...]) -> int:
    """Estimated cycles of a step without active bounds: the active mode's unconstrained
    solution (Kx x, the reference terms, the free response Phi x and its weighting) and
    row checks, the largest over the modes, plus every mode's observer update."""
    def qp_work(s: ModeSizes) -> int:
        macs = s.n * s.nx + 2 * s.n * s.ny + s.N * s.ny * (s.nx + s.ny)
        return CYCLES_PER_MAC * macs + CYCLES_PER_ROW * s.m

    observers = sum(s.nx * (s.nx + s.nu + s.ny) for s in sizes)
    return max(qp_work(s) for s in sizes) + CYCLES_PER_MAC * observers


def predict(cfg: ControllerConfig) -> Footprint:
    """The footprint of ``cfg``, from its sizes alone (no plant maths)."""
    sizes = tuple(mode_sizes(cfg, m) for m in cfg.modes)
    target = cfg.target
    return Footprint(
        precision=cfg.precision, data_bytes=stored_bytes(cfg, sizes),
        ctrl_bytes=struct_bytes(cfg, sizes),
        flash_bytes=stored_bytes(cfg, sizes, "float") + CODE_FLASH_BYTES,
        ram_bytes=struct_bytes(cfg, sizes, "float"), step_cycles=step_cycles(sizes),
        flash_limit=int(KIB * (target.flash_kib or DEFAULT_FLASH_LIMIT_KIB)),
        ram_limit=int(KIB * (target.ram_kib or DEFAULT_RAM_LIMIT_KIB)),
        cycle_budget=cfg.cycles_per_sample, flash_declared=target.flash_kib is not None,
        ram_declared=target.ram_kib is not None, largest_mode=largest_mode(sizes),
        slow=sum(condensing_bytes(s) for s in sizes) > SLOW_MATHS_BYTES)


def check_fits(cfg: ControllerConfig, fp: Footprint) -> None:
    """Refuse a design beyond its target (the first of flash, RAM, cycles), one line
    naming the figure and the limit."""
    def limit(key: str, value: int, declared: bool) -> str:
        return (f"target.{key} = {value / KIB:g}" if declared
                else f"the default limit of {value / KIB:g} KiB (set target.{key})")

    why = None
    if fp.flash_bytes > fp.flash_limit:
        why = (f"needs about {fp.flash_bytes / KIB:,.0f} KiB of flash "
               f"({(fp.flash_bytes - CODE_FLASH_BYTES) / KIB:,.0f} KiB of data + "
               f"{CODE_FLASH_BYTES // KIB} KiB of code; {fp.largest_mode}), above "
               f"{limit('flash_kib', fp.flash_limit, fp.flash_declared)}")
    elif fp.ram_bytes > fp.ram_limit:
        why = (f"needs about {fp.ram_bytes / KIB:,.0f} KiB of RAM for one controller "
               f"instance ({fp.largest_mode}), above "
               f"{limit('ram_kib', fp.ram_limit, fp.ram_declared)}")
    elif fp.step_cycles > fp.cycle_budget:
        why = (f"would take about {_rounded(fp.step_cycles):,} cycles for a step without "
               f"active bounds (an estimate; {fp.largest_mode}), above the "
               f"{fp.cycle_budget:,} of one sample (sample_time {cfg.sample_time:g} s at "
               f"target.cpu_mhz = {cfg.target.cpu_mhz:g})")
    if why is not None:
        raise ConfigError("horizon", f"too large for the target: the float build {why}; "
                          "--force-size generates it anyway")
