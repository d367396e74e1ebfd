"""``target``: the microcontroller ``rollmpc report`` judges the design on and ``rollmpc
generate`` sizes it for -- a declared part (``target.part``, parts.py), or a core with its
figures (``target.core`` and ``cpu_mhz``) -- its clock (the cycle budget of a sample is
cpu_mhz * 1e6 * sample_time, and ``solver.work_budget: auto`` follows it) and, when given,
the flash and static RAM the image must fit."""
from __future__ import annotations

from ..parts import CORES, PARTS
from .errors import ConfigError
from .reader import Reader
from .schema import TargetConfig


def parse_target(t: Reader) -> TargetConfig:
    """``target: {part, core, cpu_mhz, flash_kib, ram_kib}``, every key optional.

    A part gives its core, clock, flash and RAM, each of which a key may override (a core
    other than the part's is refused).  Without a part: the default core and clock
    (TargetConfig's) or the given ones, and no flash or RAM unless given (an absent size
    gives no verdict on it)."""
    d = TargetConfig()
    if t.has("part"):
        name = t.string("part")
        base = part_target(name, t.key("part"))
        if t.has("core") and t.string("core") != base.core:
            raise ConfigError(t.key("core"), f"{name} is a {base.core}, not "
                              f"{t.string('core')!r}; give the part or the core, not both")
    else:
        core = t.string("core", d.core)
        if core not in CORES:
            raise ConfigError(t.key("core"), f"unknown core {core!r}; one of "
                              f"{', '.join(CORES)}")
        base = TargetConfig(core=core)

    def size(name: str) -> float | None:
        return t.number(name, positive=True) if t.has(name) else getattr(base, name)

    return TargetConfig(cpu_mhz=t.number("cpu_mhz", base.cpu_mhz, positive=True),
                        flash_kib=size("flash_kib"), ram_kib=size("ram_kib"),
                        part=base.part, core=base.core)


def part_target(name: str, key: str) -> TargetConfig:
    """The target: section of a declared part, or a config error naming ``key``."""
    if name not in PARTS:
        raise ConfigError(key, f"unknown part {name!r}; one of {', '.join(PARTS)} "
                          "(or give target.core and target.cpu_mhz)")
    p = PARTS[name]
    return TargetConfig(cpu_mhz=p.cpu_mhz, flash_kib=float(p.flash.kib),
                        ram_kib=float(p.ram.kib), part=p.name, core=p.core.name)
