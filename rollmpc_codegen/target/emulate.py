"""Run functions of a Cortex-M4F image on Unicorn and count instructions and cycles.

Recipe: ``Uc(ARM, THUMB | MCLASS)`` with the
Cortex-M4 CPU model; flash and RAM mapped where the image is linked; every PT_LOAD
segment written at its run address (``.data`` already initialised, ``.bss`` zero); a
``b .`` at a return address in LR; run until PC reaches it.

Counting uses a ``UC_HOOK_BLOCK`` hook only while counting is on: each translated block
is disassembled once with capstone, and its instruction count and summed cycle weight
are cached. A taken branch adds the pipeline refill. ``UC_HOOK_CODE`` is not used: it
skips the instructions of an IT block whose condition fails and is ~4x slower. The cycle
model is the zero-wait-state table of the notes (Cortex-M4 TRM); treat it as +/-20 %.
"""
from __future__ import annotations

import bisect
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .build import FLASH_BASE, RAM_BASE, function_symbols, object_symbols

BRANCH_TAKEN_CYCLES = 2
# Memory the emulator maps (covers every image target.build_target links).
FLASH_MAP_BYTES = 32 * 1024 * 1024
RAM_MAP_BYTES = 32 * 1024 * 1024
RETURN_ADDRESS = FLASH_BASE + FLASH_MAP_BYTES - 0x100
STACK_PAINT = 0xA5


def _reg_words(op_str: str) -> int:
    """32-bit words moved by a register list such as ``{r4, r5, lr}`` or ``{d8-d10}``."""
    inside = op_str[op_str.find("{") + 1: op_str.rfind("}")]
    words = 0
    for item in inside.split(","):
        item = item.strip()
        if not item:
            continue
        per = 2 if item.startswith("d") else 1
        if "-" in item:
            lo, hi = item.split("-")
            words += per * (int(hi.strip()[1:]) - int(lo.strip()[1:]) + 1)
        else:
            words += per
    return words


def instruction_cycles(name: str, op_str: str) -> int:
    """Estimated cycles of one instruction, by capstone's base name (no condition or
    width suffix); the refill of a taken branch is added by the block hook."""
    if name in ("vdiv", "vsqrt"):
        return 14
    if name in ("sdiv", "udiv"):
        return 12
    if name in ("vmla", "vmls", "vfma", "vfms", "vnmla", "vnmls", "vfnma", "vfnms"):
        return 3
    if name in ("ldrd", "strd"):
        return 3
    if name.startswith(("ldr", "str", "vldr", "vstr")):  # ldrb/ldrsh/strh/ldrex/...
        return 2
    if name.startswith(("ldm", "stm", "vldm", "vstm")) or name in ("push", "pop", "vpush", "vpop"):
        return 1 + _reg_words(op_str)
    if name == "vmov":
        core = any(o.strip().startswith(("r", "ip", "lr", "sb", "sl", "fp"))
                   for o in op_str.split(","))
        return 2 if core else 1
    return 1


def _writes_pc(name: str, op_str: str) -> bool:
    if name in ("b", "bl", "blx", "bx", "cbz", "cbnz", "tbb", "tbh"):
        return True
    if name in ("pop", "ldm") and "pc" in op_str:
        return True
    return name in ("ldr", "mov", "add") and op_str.startswith("pc")


class EmulationError(RuntimeError):
    """The emulated code faulted or did not return."""


@dataclass
class Counts:
    """Instructions and estimated cycles of one counted call, total and per function."""

    instructions: int = 0
    cycles: int = 0
    by_function: dict = field(default_factory=dict)  # name -> [instructions, cycles]


class CortexM4:
    """A Cortex-M4F image loaded into Unicorn, with functions callable by name."""

    def __init__(self, elf: Path):
        from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs
        from elftools.elf.elffile import ELFFile
        from unicorn import UC_ARCH_ARM, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
        from unicorn.arm_const import UC_CPU_ARM_CORTEX_M4

        self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        self.uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M4)
        self.uc.mem_map(FLASH_BASE, FLASH_MAP_BYTES)
        self.uc.mem_map(RAM_BASE, RAM_MAP_BYTES)
        with open(elf, "rb") as fh:
            ef = ELFFile(fh)
            for seg in ef.iter_segments():
                if seg["p_type"] != "PT_LOAD" or seg["p_memsz"] == 0:
                    continue
                data = seg.data() + b"\0" * (seg["p_memsz"] - seg["p_filesz"])
                self.uc.mem_write(seg["p_vaddr"], data)
            sections = {s.name: (s["sh_addr"], s["sh_size"]) for s in ef.iter_sections()}
        self.uc.mem_write(RETURN_ADDRESS, b"\xfe\xe7")  # b .
        self.functions = function_symbols(elf)
        self._starts = [a for a, _, _ in self.functions]
        self.objects = object_symbols(elf)
        stack_base, stack_size = sections.get(".stack", (RAM_BASE + RAM_MAP_BYTES - 0x10000,
                                                         0x10000))
        self.stack_base, self.stack_top = stack_base, stack_base + stack_size
        self.uc.mem_write(self.stack_base, bytes([STACK_PAINT]) * stack_size)
        self._cs = Cs(CS_ARCH_ARM, CS_MODE_THUMB | CS_MODE_MCLASS)
        self._blocks: dict[int, tuple] = {}
        self._hits: dict[int, int] = defaultdict(int)
        self._taken: dict[int, int] = defaultdict(int)
        self._prev_end, self._prev_branch, self._prev_key = -1, False, -1
        self._hook = None

    # ------------------------------------------------------------------ memory access
    def address(self, symbol: str) -> int:
        if symbol in self.objects:
            return self.objects[symbol][0]
        for addr, _, name in self.functions:
            if name == symbol:
                return addr
        raise KeyError(symbol)

    def write(self, symbol: str, data: bytes | np.ndarray, offset: int = 0) -> None:
        raw = data.tobytes() if isinstance(data, np.ndarray) else bytes(data)
        self.uc.mem_write(self.address(symbol) + offset, raw)

    def read(self, symbol: str, size: int | None = None, offset: int = 0) -> bytes:
        addr, sym_size = self.objects[symbol]
        return bytes(self.uc.mem_read(addr + offset, sym_size if size is None else size))

    def stack_high_water(self) -> int:
        """Deepest stack use since load (bytes below the top that lost the paint)."""
        raw = bytes(self.uc.mem_read(self.stack_base, self.stack_top - self.stack_base))
        for i, byte in enumerate(raw):
            if byte != STACK_PAINT:
                return self.stack_top - self.stack_base - (i - i % 4)
        return 0

    # ------------------------------------------------------------------ counting
    def function_at(self, addr: int) -> str:
        i = bisect.bisect_right(self._starts, addr) - 1
        if i >= 0:
            start, size, name = self.functions[i]
            if addr < start + size:
                return name
        return "?"

    def _block_info(self, key: int, address: int, size: int) -> tuple:
        code = bytes(self.uc.mem_read(address, size))
        n = cycles = 0
        last = None
        for insn in self._cs.disasm(code, address):
            n += 1
            cycles += instruction_cycles(insn.insn_name(), insn.op_str)
            last = insn
        branch = last is not None and _writes_pc(last.insn_name(), last.op_str)
        info = (n, cycles, address + size, branch, self.function_at(address))
        self._blocks[key] = info
        return info

    def _on_block(self, uc, address, size, _user) -> None:
        key = (address << 16) | size  # a start address may be translated with two sizes
        info = self._blocks.get(key) or self._block_info(key, address, size)
        self._hits[key] += 1
        if self._prev_branch and address != self._prev_end:
            self._taken[self._prev_key] += 1  # the refill is charged to the branching block
        self._prev_end, self._prev_branch, self._prev_key = info[2], info[3], key

    def _collect(self) -> Counts:
        counts = Counts()
        for key, hits in self._hits.items():
            n, cycles, _, _, name = self._blocks[key]
            cyc = hits * cycles + self._taken.get(key, 0) * BRANCH_TAKEN_CYCLES
            counts.instructions += hits * n
            counts.cycles += cyc
            per = counts.by_function.setdefault(name, [0, 0])
            per[0] += hits * n
            per[1] += cyc
        return counts

    # ------------------------------------------------------------------ calls
    def call(self, function: str, args: tuple[int, ...] = (), count: bool = False,
             max_instructions: int = 0) -> tuple[int, Counts | None]:
        """Call ``function`` (AAPCS, up to 4 integer arguments); returns (r0, counts)."""
        from unicorn import UC_HOOK_BLOCK, UcError
        from unicorn.arm_const import (UC_ARM_REG_LR, UC_ARM_REG_PC, UC_ARM_REG_R0,
                                       UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3,
                                       UC_ARM_REG_SP)

        if len(args) > 4:
            raise ValueError("at most 4 register arguments")
        for reg, value in zip((UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3), args):
            self.uc.reg_write(reg, value)
        self.uc.reg_write(UC_ARM_REG_SP, self.stack_top)
        self.uc.reg_write(UC_ARM_REG_LR, RETURN_ADDRESS | 1)
        if count:
            self._hits, self._taken = defaultdict(int), defaultdict(int)
            self._prev_end, self._prev_branch, self._prev_key = -1, False, -1
            self._hook = self.uc.hook_add(UC_HOOK_BLOCK, self._on_block)
            self.uc.ctl_flush_tb()  # blocks translated without the hook would not call it
        try:
            self.uc.emu_start(self.address(function) | 1, RETURN_ADDRESS, count=max_instructions)
        except UcError as exc:
            raise EmulationError(f"{function}: {exc} at pc "
                                 f"{self.uc.reg_read(UC_ARM_REG_PC):#x}") from None
        finally:
            if self._hook is not None:
                self.uc.hook_del(self._hook)
                self._hook = None
                self.uc.ctl_flush_tb()
        if self.uc.reg_read(UC_ARM_REG_PC) & ~1 != RETURN_ADDRESS:
            raise EmulationError(f"{function} did not return (stopped at "
                                 f"{self.uc.reg_read(UC_ARM_REG_PC):#x})")
        return self.uc.reg_read(UC_ARM_REG_R0), (self._collect() if count else None)
