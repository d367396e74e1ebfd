"""What the M7's caches would add to one step, which its cycle model leaves out
(zero wait states: target/cycle_models.py): the misses of that step in a cold 16 KiB
4-way instruction cache and a 16 KiB 4-way data cache with 32-byte lines (the STM32F7's
and H7's L1), every other firmware task having evicted the controller since its last
step.  A miss costs a line fill from flash or AXI SRAM: the cycles it adds are the misses
times the penalty of docs/target.md "Parts" (an assumption per part, not measured).

    python -m rollmpc_codegen.target.cache_lines examples/uav_roll.yaml --part stm32h743 \\
        --precision double --step 3071

The run is replayed on the emulator up to the step (not counted), then the step's code
fetches (per executed block) and data reads and writes go through the two simulated
caches.  The data addresses are decoded from each load and store as it is about to run
(:func:`data_accesses`: its base, index and offset registers, or the register list of a
load or store multiple), not taken from a memory hook: with one installed, unicorn 2.x
skipped a 16-bit ``ldr`` after a not-taken ``beq.n`` on fw_lateral's steps 572 and 760,
and the next load read through a stale register.  Data in the controller instance is
cached like the constants: on the H743 it lives in AXI SRAM (parts.py); in DTCM, as on
the F765's first 128 KiB, it would not miss at all.
"""
from __future__ import annotations

import argparse
from collections import OrderedDict
from pathlib import Path

import numpy as np

LINE = 32


class Cache:
    """A set-associative LRU cache that only counts: ``access`` returns whether it missed."""

    def __init__(self, kib: int = 16, ways: int = 4, line: int = LINE):
        self.line, self.ways = line, ways
        self.sets = kib * 1024 // (line * ways)
        self.lines = [OrderedDict() for _ in range(self.sets)]
        self.accesses = self.misses = 0

    def access(self, address: int, size: int = 1) -> None:
        for tag in range(address // self.line, (address + max(size, 1) - 1) // self.line + 1):
            self.accesses += 1
            ways = self.lines[tag % self.sets]
            if tag in ways:
                ways.move_to_end(tag)
                continue
            self.misses += 1
            ways[tag] = True
            if len(ways) > self.ways:
                ways.popitem(last=False)


# the bytes of one element of each load or store, by capstone's base name (d registers
# of the FPU: 8, by the operand); the multiple forms' elements are their listed registers
_ELEMENT = {"ldrb": 1, "ldrsb": 1, "strb": 1, "ldrexb": 1, "strexb": 1, "tbb": 1,
            "ldrh": 2, "ldrsh": 2, "strh": 2, "ldrexh": 2, "strexh": 2, "tbh": 2,
            "ldrd": 8, "strd": 8}
_SINGLE = ("ldr", "str", "vldr", "vstr", "pld", "tbb", "tbh")
_MULTIPLE = {"push": "down_sp", "vpush": "down_sp", "pop": "up_sp", "vpop": "up_sp",
             "ldm": "up", "stm": "up", "vldmia": "up", "vstmia": "up",
             "ldmdb": "down", "stmdb": "down", "vldmdb": "down", "vstmdb": "down"}


def condition_passes(cc: int, flags: int) -> bool:
    """Whether ARM condition ``cc`` (capstone's ARM_CC_*: EQ 1 .. LE 14, AL 15, none 0)
    holds on the APSR ``flags`` (N, Z, C, V in bits 31-28): a conditional load or store in
    an IT block that does not pass touches nothing."""
    n, z, c, v = (bool(flags >> bit & 1) for bit in (31, 30, 29, 28))
    base = {1: z, 3: c, 5: n, 7: v, 9: c and not z, 11: n == v, 13: not z and n == v}
    if cc in (0, 15):
        return True
    return base[cc] if cc % 2 else not base[cc - 1]


def _register_bytes(insn, reg: int) -> int:
    return 8 if insn.reg_name(reg).startswith("d") else 4


def data_accesses(insn, reg) -> list[tuple[int, int]]:
    """The (address, bytes) that a load or store ``insn`` (capstone, with detail) touches
    when it runs with the registers ``reg(name)`` hold now; [] for any other instruction.
    Thumb's pc reads as the instruction's address + 4, word-aligned for a literal."""
    from capstone.arm import ARM_OP_MEM, ARM_OP_REG, ARM_SFT_INVALID

    name = insn.insn_name()

    def value(r: int) -> int:
        rn = insn.reg_name(r)
        return ((insn.address + 4) & ~3) if rn == "pc" else reg(rn)

    if name in _MULTIPLE:
        regs = [o.reg for o in insn.operands if o.type == ARM_OP_REG]
        how = _MULTIPLE[name]
        if how.endswith("_sp"):
            base, listed = reg("sp"), regs
        else:
            base, listed = value(regs[0]), regs[1:]
        sizes = [_register_bytes(insn, r) for r in listed]
        at = base - sum(sizes) if how.startswith("down") else base
        out = []
        for size in sizes:
            out.append((at, size))
            at += size
        return out
    if not name.startswith(_SINGLE):
        return []
    for o in insn.operands:
        if o.type != ARM_OP_MEM:
            continue
        address = value(o.mem.base) + o.mem.disp  # a post-index offset is its own operand
        if o.mem.index:
            shift = o.shift.value if o.shift.type != ARM_SFT_INVALID else o.mem.lshift
            step = value(o.mem.index) << shift
            address += -step if o.subtracted else step
        size = _ELEMENT.get(name, 4)
        if name in ("vldr", "vstr"):
            size = _register_bytes(insn, insn.operands[0].reg)
        return [(address & 0xFFFFFFFF, size)]
    return []


class DataTracer:
    """A per-instruction hook that decodes each load and store (once per address) and
    sends what it touches to ``cache``."""

    def __init__(self, cache: Cache):
        from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs
        from unicorn import arm_const

        self.cache, self._decoded = cache, {}
        self._cs = Cs(CS_ARCH_ARM, CS_MODE_THUMB | CS_MODE_MCLASS)
        self._cs.detail = True
        self._ids = {n[len("UC_ARM_REG_"):].lower(): getattr(arm_const, n)
                     for n in dir(arm_const) if n.startswith("UC_ARM_REG_")}

    def __call__(self, uc, address: int, size: int, _user) -> None:
        insn = self._decoded.get(address)
        if insn is None:
            insn = next(self._cs.disasm(bytes(uc.mem_read(address, size)), address), False)
            self._decoded[address] = insn
        if insn and condition_passes(insn.cc, uc.reg_read(self._ids["apsr"])):
            for at, nbytes in data_accesses(insn, lambda rn: uc.reg_read(self._ids[rn])):
                self.cache.access(at, nbytes)


def emulator_at_step(model, ctx: dict, build_root: Path, step: int):
    """(the emulated target image with steps 0..step-1 of the config's scenario run and
    step's inputs written, the host run's record up to step)."""
    from .build import build_target
    from .emulate import CortexM
    from .replay import record_host_run, write_inputs

    build = build_target(ctx, build_root)
    record = record_host_run(model, ctx, build_root, steps=step + 1, progress=False)
    em, p = CortexM(build.elf, build.core), ctx["prefix"]
    em.call(f"{p}_target_init")
    for k in range(step):
        write_inputs(em, ctx, record, k)
        em.call(f"{p}_target_step")
    write_inputs(em, ctx, record, step)
    return em, record


def run_step_with(em, ctx: dict, hooks: list) -> np.ndarray:
    """Run the prepared step with unicorn ``hooks`` ((type, callback) pairs) installed;
    returns its command."""
    ids = [em.uc.hook_add(kind, callback) for kind, callback in hooks]
    em.uc.ctl_flush_tb()
    try:
        em.call(f"{ctx['prefix']}_target_step")
    finally:
        for h in ids:
            em.uc.hook_del(h)
    return np.frombuffer(em.read(f"{ctx['prefix']}_target_u"),
                         np.float64 if ctx["real"] == "double" else np.float32)


def step_misses(model, ctx: dict, build_root: Path, step: int) -> dict:
    """The cold-cache misses of ``step`` of the config's scenario on its target image."""
    from unicorn import UC_HOOK_BLOCK, UC_HOOK_CODE

    em, record = emulator_at_step(model, ctx, build_root, step)
    code, data = Cache(), Cache()
    out = run_step_with(em, ctx, [(UC_HOOK_BLOCK, lambda uc, a, s, _u: code.access(a, s)),
                                  (UC_HOOK_CODE, DataTracer(data))])
    if out.tobytes() != record.u[step].tobytes():
        raise RuntimeError(f"step {step}: the emulated command differs from the host's")
    return {"step": step, "code_lines": code.accesses, "code_misses": code.misses,
            "data_accesses": data.accesses, "data_misses": data.misses}


def main(argv=None) -> int:
    from ..pipeline import load_model
    from ..host.build_cache import private_root

    ap = argparse.ArgumentParser(prog="python -m rollmpc_codegen.target.cache_lines")
    ap.add_argument("config")
    ap.add_argument("--part", default="stm32h743")
    ap.add_argument("--precision", default=None)
    ap.add_argument("--step", type=int, required=True)
    args = ap.parse_args(argv)
    model, ctx = load_model(args.config, args.precision, args.part)
    r = step_misses(model, ctx, private_root(None), args.step)
    print(f"step {r['step']}: code {r['code_misses']} misses of {r['code_lines']} line "
          f"fetches, data {r['data_misses']} misses of {r['data_accesses']} line accesses "
          "(cold 16 KiB 4-way caches, 32-byte lines)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
