"""``target``: the microcontroller ``rollmpc report`` judges the design on -- its clock
(the cycle budget of a sample is cpu_mhz * 1e6 * sample_time) and, when given, the flash
and static RAM the image must fit.  The generated C never sees it."""
from __future__ import annotations

from .reader import Reader
from .schema import TargetConfig


def parse_target(t: Reader) -> TargetConfig:
    """``target: {cpu_mhz, flash_kib, ram_kib}``: every key optional, the defaults are
    TargetConfig's (an absent flash or RAM size gives no verdict on it)."""
    d = TargetConfig()

    def size(name: str) -> float | None:
        return t.number(name, positive=True) if t.has(name) else getattr(d, name)

    return TargetConfig(cpu_mhz=t.number("cpu_mhz", d.cpu_mhz, positive=True),
                        flash_kib=size("flash_kib"), ram_kib=size("ram_kib"))
