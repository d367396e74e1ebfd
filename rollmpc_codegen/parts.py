"""Every microcontroller rollmpc judges a design on, each declared once.

A :class:`Core` is what the compiler and the emulator need: its flags, the width of its
FPU, the emulator's CPU and cycle model, the work unit's cost and the code allowance.  A
:class:`Part` is a core on a chip: its clock, its flash and the RAM region the controller
instance lives in.  ``target.part`` (or ``target.core`` with figures, config/target.py)
selects one; the target build, the emulator, the work budget, ``generate``'s footprint,
``report``'s verdict, the generated ``P_target.mk`` of the firmware stub and the tests read
it from here.  Adding a part is one :class:`Part` below (and its tests, docs/target.md
"Parts"); adding a core, one :class:`Core` and its cycle model (target/cycle_models.py).

The compiler flags are the autopilots' own:
* PX4 ``platforms/nuttx/cmake/Platform/Generic-arm-none-eabi-gcc-cortex-m4.cmake``:
  ``-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard`` (fmu-v2/v3), and
  ``...-cortex-m7.cmake``: ``-mcpu=cortex-m7 -mthumb -mfpu=fpv5-d16 -mfloat-abi=hard``
  (fmu-v5, fmu-v6x/v6c: ``CONFIG_BOARD_ARCHITECTURE="cortex-m7"``);
  ``...-cortex-m33.cmake``: ``-mcpu=cortex-m33 -mfloat-abi=hard -mfpu=fpv5-sp-d16`` without
  ``CONFIG_ARCH_DPFPU``.
* ArduPilot ``libraries/AP_HAL_ChibiOS/hwdef/scripts/chibios_hwdef.py``: CPU_FLAGS
  ``-mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard`` for its F7 and H7 boards (Pixhawk4,
  Pixhawk6C: ``HAL_HAVE_HARDWARE_DOUBLE 1``), ``-mfpu=fpv4-sp-d16`` for the F4 ones.
"""
from __future__ import annotations

from dataclasses import dataclass

KIB = 1024


@dataclass(frozen=True)
class Core:
    """A Cortex-M core with its FPU, as the compiler, the emulator and the budget see it."""

    name: str  # the value of target.core
    label: str  # for people: "Cortex-M7 (FPv5-D16)"
    short: str  # in file names: the firmware stub's rollctl_<short>.elf
    cflags: tuple[str, ...]  # -mcpu, -mthumb, -mfpu, -mfloat-abi
    fpu_double: bool  # the FPU computes double in hardware (else libgcc's soft-float)
    emulator_cpu: str  # unicorn's CPU model (unicorn.arm_const.UC_CPU_ARM_<...>)
    cycle_model: str  # target/cycle_models.py MODELS
    cycle_band: str  # the error band of that model, as docs/target.md "Parts" argues it
    # cycles per work unit (qp/work.py), per precision the FPU runs: the largest ratio of a
    # counted step's cycles to its work plus STEP_FIXED_UNITS over the examples, with
    # margin (the current maxima: docs/target.md "Cycles per work unit"); the auto work
    # budget's divisor
    work_unit_cycles: tuple[tuple[str, float], ...]
    code_bytes: int  # the text of every generated function at -O2: the flash allowance

    def judged_precision(self, precision: str) -> str:
        """The precision a design is judged in: its own where the FPU runs it, else float
        (a double tree on a single-precision FPU is the host's reference build)."""
        return precision if precision == "float" or self.fpu_double else "float"

    def cycles_per_work_unit(self, precision: str) -> float:
        return dict(self.work_unit_cycles)[self.judged_precision(precision)]


@dataclass(frozen=True)
class Region:
    """A memory region of a part: where the linker puts flash or the static RAM."""

    name: str
    origin: int
    kib: int


@dataclass(frozen=True)
class Part:
    """A microcontroller: a core at a clock with its memory."""

    name: str  # the value of target.part
    core: Core
    cpu_mhz: float  # the clock the autopilots run it at
    flash: Region
    ram: Region  # the largest contiguous region: the instance is one struct
    boards: str  # who flies it

    @property
    def label(self) -> str:
        return f"{self.name.upper()} ({self.core.label}, {self.cpu_mhz:g} MHz)"


# Cortex-M4 TRM weights (shared/notes/mcu-cycle-counting.md). 20 cycles per unit: `rollmpc
# report --precision float` measured at most 19.23 on the counted steps that spend over
# 30 % of their budget (commit a0d58fb: fw_lateral step 576; quad_attitude 17.93, c172_roll
# 15.54, uav_roll 13.11), with 4 % of margin (docs/solver.md, "Work budget"). Small steps
# ran at 21-24 (fixed costs per call: thermal_zones' largest, <= 11.7 k units, at 20.1-21.2);
# PRIMAL_CALL_UNITS brings them to <= 19.8 (3313d1b). The code: 29,804 to 33,552 B over the
# examples with the four-row back substitution and correct()'s column pairs (29,016 to
# 32,704 at 57967e4; docs/target.md "Before generation"); measure again when the templates
# grow (tests/target/test_code_flash_allowance.py).
CORTEX_M4F = Core(
    name="cortex-m4f", label="Cortex-M4F (FPv4-SP)", short="m4f",
    cflags=("-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"),
    fpu_double=False, emulator_cpu="UC_CPU_ARM_CORTEX_M4", cycle_model="m4",
    cycle_band="+/-20 %", work_unit_cycles=(("float", 20.0),), code_bytes=38 * KIB)

# LLVM's Cortex-M7 scheduling model (dual issue, latencies) with a branch predictor, zero
# wait states (TCM or cache hits): target/cycle_models.py. Cycles per unit: `rollmpc
# report --part stm32h743` measured at most 12.97 in float (fw_lateral step 220; c172_roll
# 9.58, thermal_zones 8.99, quad_attitude 8.34) and 16.23 in double (fw_lateral step 380;
# c172_roll 15.99, quad_attitude 13.41, thermal_zones 12.64) on every counted step, with
# 4 % of margin (docs/target.md "Parts"). Code: 30,216 to 33,748 B in float, 28,856 to
# 32,060 in double (tests/target/test_code_flash_allowance.py).
CORTEX_M7 = Core(
    name="cortex-m7", label="Cortex-M7 (FPv5-D16)", short="m7",
    cflags=("-mcpu=cortex-m7", "-mthumb", "-mfpu=fpv5-d16", "-mfloat-abi=hard"),
    fpu_double=True, emulator_cpu="UC_CPU_ARM_CORTEX_M7", cycle_model="m7",
    cycle_band="-15 %/+40 % (caches not modelled)",
    work_unit_cycles=(("float", 13.5), ("double", 17.0)), code_bytes=39 * KIB)

# the M4's table, neighbouring loads and stores pipelined, a one-cycle branch refill (LLVM
# schedules the M33 with the M4's model): target/cycle_models.py. Cycles per unit: `rollmpc
# report --part stm32l562` measured at most 16.92 (fw_lateral step 220; c172_roll 13.84,
# thermal_zones 12.48), with 4 % of margin. Code: 30,308 to 33,960 B.
CORTEX_M33 = Core(
    name="cortex-m33", label="Cortex-M33 (FPv5-SP)", short="m33",
    cflags=("-mcpu=cortex-m33", "-mthumb", "-mfpu=fpv5-sp-d16", "-mfloat-abi=hard"),
    fpu_double=False, emulator_cpu="UC_CPU_ARM_CORTEX_M33", cycle_model="m33",
    cycle_band="+/-25 %", work_unit_cycles=(("float", 17.6),), code_bytes=38 * KIB)

CORES = {c.name: c for c in (CORTEX_M4F, CORTEX_M7, CORTEX_M33)}

FLASH_BASE = 0x08000000
PARTS = {p.name: p for p in (
    # PX4 runs FMUv2/v3 at 168 MHz (the F427 is rated 180); SRAM1-3 are contiguous, the
    # 64 KiB CCM apart; PX4 builds FMUv2 for the first 1 MiB of flash only
    # the F4 flight controllers of ArduPilot and Betaflight: SRAM1 and SRAM2 contiguous,
    # the 64 KiB CCM apart
    Part("stm32f405", CORTEX_M4F, 168.0, Region("FLASH", FLASH_BASE, 1024),
         Region("SRAM", 0x20000000, 128), "F405 flight controllers (Matek, Omnibus, ...)"),
    Part("stm32f427", CORTEX_M4F, 168.0, Region("FLASH", FLASH_BASE, 2048),
         Region("SRAM", 0x20000000, 192), "Pixhawk 1 (FMUv2), Pixhawk 2/Cube (FMUv3)"),
    # DTCM 128 KiB, SRAM1 368 KiB and SRAM2 16 KiB follow each other from 0x20000000
    Part("stm32f765", CORTEX_M7, 216.0, Region("FLASH", FLASH_BASE, 2048),
         Region("DTCM_SRAM", 0x20000000, 512), "Pixhawk 4 (FMUv5)"),
    # AXI SRAM, the largest region (the 128 KiB DTCM and the D2/D3 SRAMs are apart)
    Part("stm32h743", CORTEX_M7, 480.0, Region("FLASH", FLASH_BASE, 2048),
         Region("AXI_SRAM", 0x24000000, 512), "Pixhawk 6X and 6C (FMUv6X/v6C)"),
    # a common Cortex-M33 with a single-precision FPU (TrustZone off): SRAM1 192 KiB and
    # SRAM2 64 KiB are contiguous
    Part("stm32l562", CORTEX_M33, 110.0, Region("FLASH", FLASH_BASE, 512),
         Region("SRAM", 0x20000000, 256), "STM32L562E-DK, NUCLEO-L552ZE-Q class boards"),
)}
DEFAULT_PART = "stm32f427"  # its core and clock are the defaults of target:


def part(name: str) -> Part:
    return PARTS[name]


def core(name: str) -> Core:
    return CORES[name]
