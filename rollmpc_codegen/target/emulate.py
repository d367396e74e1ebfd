"""Run functions of a Cortex-M image on Unicorn and count instructions and cycles.

Recipe: ``Uc(ARM, THUMB)`` with the core's CPU model
(parts.py ``Core.emulator_cpu``); flash and RAM mapped where the image is linked; every
PT_LOAD segment written at its run address (``.data`` already initialised, ``.bss``
zero); a ``b .`` at a return address in LR; run until PC reaches it.  Not
``UC_MODE_MCLASS``: unicorn 2.1.4 then runs its Cortex-M33 whatever model was set
(``arm_cpu_init``), whose FPU is single precision; without it the model set is the one
run, and the M7's executes the double-precision VFP instructions of FPv5-D16.

Counting uses a ``UC_HOOK_BLOCK`` hook only while counting is on: each translated block
is disassembled once with capstone and its instructions and cycles (the core's model,
:mod:`.cycle_models`) are cached; a loop's next trip is counted at the block's ``warm``
cycles. A taken branch adds the refill, or with a predictor (the M7) a mispredicted one
its penalty; the predictor starts cold on every counted call (other firmware runs between
two controller steps). ``UC_HOOK_CODE`` is not used: it skips the instructions of an IT
block whose condition fails and is ~4x slower.
"""
from __future__ import annotations

import bisect
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..parts import CORTEX_M4F, Core
from .build import FLASH_BASE, RAM_BASE, function_symbols, object_symbols
from .cycle_models import MODELS, writes_pc

# Memory the emulator maps (covers every image target.build_target links).
FLASH_MAP_BYTES = 32 * 1024 * 1024
RAM_MAP_BYTES = 32 * 1024 * 1024
RETURN_ADDRESS = FLASH_BASE + FLASH_MAP_BYTES - 0x100
STACK_PAINT = 0xA5


class EmulationError(RuntimeError):
    """The emulated code faulted or did not return."""


@dataclass
class Counts:
    """Instructions and estimated cycles of one counted call, total and per function."""

    instructions: int = 0
    cycles: int = 0
    by_function: dict = field(default_factory=dict)  # name -> [instructions, cycles]


class CortexM:
    """A Cortex-M image of ``core`` loaded into Unicorn, with functions callable by name."""

    def __init__(self, elf: Path, core: Core = CORTEX_M4F):
        from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs
        from elftools.elf.elffile import ELFFile
        from unicorn import UC_ARCH_ARM, UC_MODE_THUMB, Uc, arm_const

        self.core, self.model = core, MODELS[core.cycle_model]
        self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB)
        self.uc.ctl_set_cpu_model(getattr(arm_const, core.emulator_cpu))
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
        self._cs.detail = self.model.detail
        self._blocks: dict[int, tuple] = {}
        self._hook = None
        self._reset_counts()

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

    def _reset_counts(self) -> None:
        self._hits: dict[int, int] = defaultdict(int)  # entered from another block
        self._warm: dict[int, int] = defaultdict(int)  # entered from itself (a loop)
        self._taken: dict[int, int] = defaultdict(int)  # taken (or mispredicted) branches
        self._state: dict[int, int] = {}  # the predictor: 2-bit counter or last target
        self._prev_end, self._prev_branch, self._prev_key = -1, None, -1

    def _block_info(self, key: int, address: int, size: int) -> tuple:
        code = bytes(self.uc.mem_read(address, size))
        insns = list(self._cs.disasm(code, address))
        cold, warm = self.model.block(insns)
        last = insns[-1] if insns else None
        branch = None  # what the predictor keeps of the block's last instruction
        if last is not None and writes_pc(last.insn_name(), last.op_str):
            branch = _branch_kind(last) if self.model.predicts else "taken"
        info = (len(insns), cold, warm, address + size, branch, self.function_at(address))
        self._blocks[key] = info
        return info

    def _on_block(self, uc, address, size, _user) -> None:
        key = (address << 16) | size  # a start address may be translated with two sizes
        info = self._blocks.get(key) or self._block_info(key, address, size)
        if key == self._prev_key:
            self._warm[key] += 1
        else:
            self._hits[key] += 1
        branch, prev = self._prev_branch, self._prev_key
        if branch is not None:
            taken = address != self._prev_end
            if branch == "taken":
                self._taken[prev] += taken  # the refill is charged to the branching block
            elif branch == "indirect":
                self._taken[prev] += self._state.get(prev) != address
                self._state[prev] = address
            elif branch != "direct":  # conditional: "back" or "forward" (its static guess)
                counter = self._state.get(prev, 2 if branch == "back" else 1)
                self._taken[prev] += (counter >= 2) != taken
                self._state[prev] = min(counter + 1, 3) if taken else max(counter - 1, 0)
        self._prev_end, self._prev_branch, self._prev_key = info[3], info[4], key

    def _collect(self) -> Counts:
        counts = Counts()
        penalty = (self.model.mispredict_cycles if self.model.predicts
                   else self.model.taken_cycles)
        for key in set(self._hits) | set(self._warm):
            n, cold, warm, _, _, name = self._blocks[key]
            hits, again = self._hits.get(key, 0), self._warm.get(key, 0)
            cyc = hits * cold + again * warm + self._taken.get(key, 0) * penalty
            counts.instructions += (hits + again) * n
            counts.cycles += cyc
            per = counts.by_function.setdefault(name, [0, 0])
            per[0] += (hits + again) * n
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
            self._reset_counts()
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


def _branch_kind(insn) -> str:
    """How the M7's predictor sees a branch: ``direct`` (unconditional to a fixed target,
    always predicted), ``indirect`` (its target from a register or memory: predicted as
    the last one), or conditional: ``back`` or ``forward`` by its target (the static guess
    of a branch seen for the first time: a backward one is a loop, taken)."""
    name = insn.insn_name()
    direct = name in ("cbz", "cbnz") or (name in ("b", "bl")
                                         and insn.op_str.lstrip().startswith("#"))
    if not direct:
        return "indirect"
    if name not in ("cbz", "cbnz") and insn.cc in (0, 15):  # no condition (or AL)
        return "direct"
    target = int(insn.op_str.split("#")[-1], 0)
    return "back" if target <= insn.address else "forward"
