"""The emulator's cycle models, one per core (parts.py ``Core.cycle_model``).

The emulator (:mod:`.emulate`) disassembles each translated block once and asks its model
for the block's cycles: ``cold`` (entered from elsewhere) and ``warm`` (entered from
itself: a loop's next trip, whose first instructions overlap the previous trip's
latencies).  Taken branches are charged by the emulator's hook, at the model's refill
(``taken_cycles``) or, for a model with a branch predictor, at its mispredict penalty.
Memory has zero wait states in every model (flash with its accelerator, TCM or cache hits):
docs/target.md "Parts" says what each model leaves out and its error band.

* ``m4``: the Cortex-M4 TRM's weights (shared/notes/mcu-cycle-counting.md), one
  instruction after the other, taken branch +2.
* ``m33``: the same weights (LLVM schedules the Cortex-M33 with its M4 model,
  ``ARMProcessors.td``), neighbouring single loads and stores pipelined, taken branch +1.
  Calibrated on CoreMark: its cycles per iteration on this model over the ``m4`` model's
  are 0.862 (GCC 12 -O2), the published CoreMark/MHz give 3.40 / 4.02 = 0.846.
* ``m7``: in-order dual issue after LLVM's Cortex-M7 scheduling model
  (``llvm/lib/Target/ARM/ARMScheduleM7.td``): two ALUs (one shifter), two load ports, one
  store, MAC, branch and FP pipe, two FP register ports; the result latencies and the
  operands read early (addresses) or late (store data, accumulators) of that file, and
  its best-case load-use latency of 2; a predictor (2-bit counters, last target for
  indirect branches) with the 6-cycle mispredict it gives for forward branches. On
  CoreMark (GCC 12 -O2) its cycles per iteration over the ``m4`` model's are 0.655; the
  published CoreMark/MHz give 3.40 / 5.01 = 0.679.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

BRANCHES = ("b", "bl", "blx", "bx", "cbz", "cbnz", "tbb", "tbh")


def reg_words(op_str: str) -> int:
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
    """Cortex-M4 cycles of one instruction, by capstone's base name (no condition or width
    suffix); the refill of a taken branch is added by the block hook."""
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
        return 1 + reg_words(op_str)
    if name == "vmov":
        core = any(o.strip().startswith(("r", "ip", "lr", "sb", "sl", "fp"))
                   for o in op_str.split(","))
        return 2 if core else 1
    return 1


def writes_pc(name: str, op_str: str) -> bool:
    if name in BRANCHES:
        return True
    if name in ("pop", "ldm") and "pc" in op_str:
        return True
    return name in ("ldr", "mov", "add") and op_str.startswith("pc")


SINGLE_LOADS_STORES = ("ldr", "str", "vldr", "vstr")


@dataclass(frozen=True)
class TableModel:
    """One weight per instruction, in sequence, and a refill per taken branch;
    ``pipelined``: a single load or store that follows one takes a cycle less (the M4
    TRM's note on neighbouring loads and stores, which the M4's own figures leave out)."""

    name: str
    taken_cycles: int
    pipelined: bool = False
    predicts: bool = False
    detail: bool = False  # capstone's operand details are not needed

    def block(self, insns) -> tuple[int, int]:
        cycles, previous = 0, False
        for insn in insns:
            name = insn.insn_name()
            cycles += instruction_cycles(name, insn.op_str)
            single = name.startswith(SINGLE_LOADS_STORES) and name not in ("ldrd", "strd")
            cycles -= self.pipelined and single and previous
            previous = single
        return cycles, cycles


# ----------------------------------------------------------------------------- Cortex-M7
FP_REG = re.compile(r"[sd]\d+")
UNITS = {"alu": 2, "shift": 1, "mac": 1, "load": 2, "store": 1, "branch": 1, "vfp": 1,
         "vport": 2, "simd": 1}
ADDRESS, STORE_DATA, FP_STORE_DATA = -1, 1, 2  # read at ISS, EX3, EX4 (EX2 is 0)
# a load's result, as LLVM's `LoadLatency = 2; // Best case for load-use` (its per-write
# latency of 1 makes CoreMark's M7/M4 cycle ratio 0.569 against the published 0.679; 2
# makes it 0.655); byte and halfword loads a cycle more
LOAD_USE = 2
FP_ALU = ("vadd", "vsub", "vabs", "vneg", "vcvt", "vcvtr", "vcvta", "vcvtn", "vcvtp",
          "vcvtm", "vmaxnm", "vminnm", "vrinta", "vrintn", "vrintp", "vrintm", "vrintr",
          "vrintx", "vrintz", "vsel")
FP_MUL = ("vmul", "vnmul")
FP_MAC = ("vmla", "vmls", "vnmla", "vnmls")
FP_FMA = ("vfma", "vfms", "vfnma", "vfnms")
SIMD = ("uxtb", "uxth", "sxtb", "sxth", "ubfx", "sbfx", "rev", "rev16", "revsh", "rbit",
        "usat", "ssat", "uxtab", "uxtah", "sxtab", "sxtah", "pkhbt", "pkhtb")
MULS = ("mul", "mla", "mls", "smull", "umull", "smlal", "umlal", "smmul", "smmla",
        "smulbb", "smlabb")


@dataclass
class Timing:
    """How one instruction issues on the M7: its units, when its results are ready, which
    operands it reads early or late, and whether it pairs."""

    units: dict = field(default_factory=dict)
    latency: int = 1  # result ready this many cycles after issue (EX2 = 0)
    single: bool = False  # issues alone
    first: bool = False  # only as the first of a pair (LLVM BeginGroup / Slot0Only)
    occupancy: int = 1  # cycles before the next group issues (stalls, multi-cycle issue)
    fp_busy: int = 0  # cycles the FP pipe stays busy for other FP instructions
    offsets: dict = field(default_factory=dict)  # atom -> read offset (default 0)


def _atoms(insn, reg: int) -> tuple:
    """A register as the pieces that alias: d<n> is s<2n> and s<2n+1>."""
    name = insn.reg_name(reg)
    if name.startswith("d") and name[1:].isdigit() and int(name[1:]) < 16:
        n = int(name[1:])
        return (f"s{2 * n}", f"s{2 * n + 1}")
    return ("cpsr",) if name in ("apsr", "apsr_nzcv", "cpsr") else (name,)


def m7_timing(insn) -> Timing:
    """The M7 timing of one capstone instruction (with detail)."""
    from capstone.arm import ARM_OP_MEM, ARM_OP_REG, ARM_SFT_INVALID

    name, ops = insn.insn_name(), insn.operands
    double = any(o.type == ARM_OP_REG and insn.reg_name(o.reg)[0] == "d" for o in ops)
    address = {a for o in ops if o.type == ARM_OP_MEM for r in (o.mem.base, o.mem.index)
               if r for a in _atoms(insn, r)}
    t = Timing(units={"alu": 1})
    if name.startswith(("ldr", "pld")) and not name.startswith("ldrex"):
        t.units = {"load": 1}
        t.latency = LOAD_USE + (name in ("ldrb", "ldrh", "ldrsb", "ldrsh"))
        t.single = name == "ldrd"
    elif name.startswith("str") and not name.startswith("strex"):
        t.units, t.single = {"store": 1}, name == "strd"
        t.offsets = {a: STORE_DATA for o in ops if o.type == ARM_OP_REG
                     for a in _atoms(insn, o.reg)}
    elif name in ("ldm", "ldmdb", "pop", "stm", "stmdb", "push", "vldmia", "vldmdb",
                  "vstmia", "vstmdb", "vpush", "vpop") or name.startswith(("ldrex", "strex")):
        loads = name in ("ldm", "ldmdb", "pop", "vldmia", "vldmdb", "vpop") or \
            name.startswith("ldrex")
        t.units, t.single = {"load" if loads else "store": 1}, True
        words = reg_words(insn.op_str) if "{" in insn.op_str else 1
        t.occupancy = max(1, (words + 1) // 2)  # the 64-bit data path: two words a cycle
    elif name in ("vldr", "vstr"):
        t.units = {"load" if name == "vldr" else "store": 2 if double else 1,
                   "vport": 2 if double else 1}
        t.latency, t.single = LOAD_USE, double
        if name == "vstr":
            t.offsets = {a: FP_STORE_DATA for o in ops if o.type == ARM_OP_REG
                         for a in _atoms(insn, o.reg)}
    elif name in ("sdiv", "udiv"):
        t.latency, t.single, t.occupancy = 7, True, 7
    elif name in MULS:
        t.units, t.latency = {"mac": 1}, 2
    elif name in SIMD:
        t.units, t.first = {"simd": 1, "alu": 1, "shift": 1}, True
    elif name in ("bfc", "bfi", "clz"):
        t.units, t.first = {"alu": 1, "shift": 1}, True
    elif name in BRANCHES:
        t.units, t.single = {"branch": 1}, name in ("tbb", "tbh")
        t.occupancy = 2 if t.single else 1
    elif name in ("vdiv", "vsqrt"):
        t.units = {"vfp": 1, "vport": 2 if double else 1}
        t.latency = 30 if double else 16
        t.fp_busy, t.first = t.latency - 2, double  # the divider iterates in the FP pipe
    elif name in FP_MAC + FP_FMA:
        fused = name in FP_FMA
        t.units = {"vfp": 1, "vport": 2 if double else 1}
        t.latency = 11 if double else (5 if fused else 6)
        acc = _atoms(insn, ops[0].reg)
        t.offsets = {a: 3 if (double or not fused) else 2 for a in acc}
        t.first = double
        t.occupancy = (3 if fused else 4) if double else 1  # a DP MAC stalls what follows
    elif name in FP_MUL:
        t.units = {"vfp": 1, "vport": 2 if double else 1}
        t.latency, t.first, t.fp_busy = (7, True, 2) if double else (3, False, 0)
    elif name in FP_ALU or (name == "vcmp" or name == "vcmpe"):
        t.units = {"vfp": 1, "vport": 2 if double else 1}
        t.latency = 0 if name.startswith("vcmp") else (4 if double else 3)
        t.first = double or name == "vsel"
    elif name == "vmov":
        core = sum(1 for o in ops if o.type == ARM_OP_REG
                   and not FP_REG.fullmatch(insn.reg_name(o.reg)))
        t.units = {"vport": 2 if (double or core > 1) else 1}
        t.latency, t.single, t.first = 3, core > 1, double
    elif name in ("vmrs", "vmsr"):
        t.units, t.single = {"vfp": 1, "vport": 1}, True
    elif name.startswith(("dmb", "dsb", "isb", "mrs", "msr", "svc", "bkpt", "udf")):
        t.single, t.latency = True, 3
    elif any(o.type == ARM_OP_REG and o.shift.type != ARM_SFT_INVALID for o in ops) or \
            name in ("lsl", "lsls", "lsr", "lsrs", "asr", "asrs", "ror", "rors", "rrx"):
        t.units = {"alu": 1, "shift": 1}
        t.latency = 2 if name in ("cmp", "cmn", "tst", "teq") else 1
    for a in address:
        t.offsets[a] = ADDRESS
    return t


def _regs(insn) -> tuple[set, set]:
    try:
        read, written = insn.regs_access()
    except Exception:  # noqa: BLE001 (capstone has no access list for a few system insns)
        return set(), set()
    return ({a for r in read for a in _atoms(insn, r) if a != "pc"},
            {a for r in written for a in _atoms(insn, r) if a != "pc"})


def schedule(ops: list, start: int = 0, ready: dict | None = None) -> tuple[int, dict]:
    """Issue ``ops`` (Timing, reads, writes) in order, two a cycle where they pair; returns
    the cycle the next instruction could issue at and when each register is ready."""
    ready = dict(ready or {})
    group: list = []  # what issues in cycle t
    t, next_free, fp_free = start, start, start
    for timing, reads, writes in ops:
        # a register written before the block is ready whenever it is read
        earliest = max([ready[a] - timing.offsets.get(a, 0) for a in reads if a in ready]
                       + [start])
        if "vfp" in timing.units:
            earliest = max(earliest, fp_free)
        used = {u: sum(g.units.get(u, 0) for g in group) + timing.units.get(u, 0)
                for u in timing.units}
        pairs = (len(group) == 1 and not group[0].single and not timing.single
                 and not timing.first and earliest <= t and next_free <= t + 1
                 and all(n <= UNITS[u] for u, n in used.items()))
        if pairs:
            group.append(timing)
        else:
            t = max(earliest, next_free, t + 1 if group else t)
            group = [timing]
        next_free = max(next_free, t + timing.occupancy)
        if timing.fp_busy:
            fp_free = t + timing.fp_busy
        for a in writes:
            ready[a] = t + timing.latency
    return max(next_free, t + 1 if group else t), ready


@dataclass(frozen=True)
class DualIssueModel:
    """The Cortex-M7: in-order dual issue within a block, a predictor for its branches."""

    name: str = "m7"
    mispredict_cycles: int = 6
    predicts: bool = True
    detail: bool = True

    def block(self, insns) -> tuple[int, int]:
        ops = [(m7_timing(i), *_regs(i)) for i in insns]
        end, ready = schedule(ops)
        again, _ = schedule(ops, end, ready)
        return end, again - end


MODELS = {m.name: m for m in (TableModel("m4", taken_cycles=2),
                              TableModel("m33", taken_cycles=1, pipelined=True),
                              DualIssueModel())}
