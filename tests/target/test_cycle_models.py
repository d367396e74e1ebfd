"""The emulator's cycle models (target/cycle_models.py) on assembled instruction
sequences: the M7's pairs, latencies and single-issue rules after LLVM's Cortex-M7
model, the M33's pipelined loads, and the predictor against a taken-branch refill."""
from __future__ import annotations

import subprocess

import pytest

from conftest import require_tool

ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"


def insns(tmp_path, text: str, cpu: str = "cortex-m7", fpu: str = "fpv5-d16"):
    """Assemble Thumb ``text`` and disassemble it with the details the models read."""
    require_tool("arm-none-eabi-as", ARM_HINT)
    capstone = pytest.importorskip("capstone", reason="pip install 'rollmpc-codegen[target]'")
    src, obj, raw = tmp_path / "a.s", tmp_path / "a.o", tmp_path / "a.bin"
    src.write_text(f".syntax unified\n.thumb\n{text}\n")
    subprocess.run(["arm-none-eabi-as", f"-mcpu={cpu}", f"-mfpu={fpu}", "-o", str(obj),
                    str(src)], check=True)
    subprocess.run(["arm-none-eabi-objcopy", "-O", "binary", "-j", ".text", str(obj),
                    str(raw)], check=True)
    md = capstone.Cs(capstone.CS_ARCH_ARM, capstone.CS_MODE_THUMB | capstone.CS_MODE_MCLASS)
    md.detail = True
    return list(md.disasm(raw.read_bytes(), 0))


def m7(tmp_path, text: str) -> tuple[int, int]:
    from rollmpc_codegen.target.cycle_models import MODELS

    return MODELS["m7"].block(insns(tmp_path, text))


@pytest.mark.parametrize("text, cold", [
    ("adds r0, r1, #1\nadds r2, r3, #1", 1),  # two independent ALU ops dual issue
    ("adds r0, r1, #1\nadds r2, r0, #1", 2),  # a dependent one waits a cycle
    ("ldr r0, [r1]\nldr r2, [r3]", 1),  # two load ports
    ("ldr r0, [r1]\nadds r2, r0, #1", 3),  # load-use latency 2
    ("ldr r0, [r1]\nldr r2, [r0]", 4),  # an address is read a cycle early
    ("str r0, [r1]\nstr r2, [r3]", 2),  # one store port
    ("vldr d0, [r1]\nadds r2, r3, #1", 2),  # a double load issues alone
    ("vldr s0, [r1]\nvldr s1, [r2]", 1),  # two single loads, two FP register ports
    ("vadd.f32 s0, s1, s2\nvadd.f32 s3, s0, s2", 4),  # FP latency 3
    ("vadd.f64 d0, d1, d2\nvadd.f64 d3, d0, d2", 5),  # 4 in double
    ("vdiv.f32 s0, s1, s2\nvadd.f32 s3, s0, s2", 17),  # the divide's 16
    ("vdiv.f64 d0, d1, d2\nvadd.f64 d3, d0, d2", 31),
    ("vmla.f32 s0, s1, s2\nvmla.f32 s0, s3, s4", 4),  # chained: the accumulator read late
    ("push {r4, r5, r6, r7}\nadds r0, r1, #1", 3),  # two words a cycle, alone
])
def test_m7_issue_rules(tmp_path, text, cold):
    assert m7(tmp_path, text)[0] == cold


def test_m7_loop_trip_waits_for_the_previous_one(tmp_path):
    """A loop's next trip (warm) waits for what the last trip's long latencies produce:
    a chained divide pays its 16 cycles a trip, which a cold start does not see; a dot
    product's trip stays at its cold cost (the accumulator is read 3 cycles late)."""
    assert m7(tmp_path, "vdiv.f32 s0, s0, s1\nsubs r0, #1\nbne .-6") == (2, 16)
    cold, warm = m7(tmp_path, "vldr s14, [r0]\nvldr s15, [r1]\nvmla.f32 s0, s14, s15\n"
                              "adds r0, #4\nadds r1, #4\ncmp r0, r2\nbne .-12")
    assert cold == warm == 5


def test_m33_pipelines_neighbouring_loads_and_m4_does_not(tmp_path):
    from rollmpc_codegen.target.cycle_models import MODELS

    code = insns(tmp_path, "ldr r0, [r1]\nldr r2, [r3]\nvldr s0, [r1]", "cortex-m33",
                 "fpv5-sp-d16")
    assert MODELS["m4"].block(code) == (6, 6) and MODELS["m33"].block(code) == (4, 4)


def test_the_m7_predicts_a_loop_and_the_m4_pays_each_trip(tmp_path):
    """A 100-trip loop: on the M4 every taken branch refills (+2), on the M7 only the exit
    is mispredicted (a backward branch is guessed taken the first time)."""
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    pytest.importorskip("unicorn", reason="pip install 'rollmpc-codegen[target]'")
    from rollmpc_codegen.parts import CORTEX_M4F, CORTEX_M7
    from rollmpc_codegen.target.emulate import CortexM

    src, elf, ld = tmp_path / "loop.c", tmp_path / "loop.elf", tmp_path / "l.ld"
    src.write_text("unsigned loop(unsigned n) { unsigned s = 0; while (n--) "
                   "{ __asm__ volatile (\"\"); s += n; } return s; }\n")
    ld.write_text("MEMORY { FLASH (rx) : ORIGIN = 0x08000000, LENGTH = 64K RAM (rwx) : "
                  "ORIGIN = 0x20000000, LENGTH = 64K }\nSECTIONS { .text : { *(.text*) } "
                  "> FLASH .stack (NOLOAD) : { . = . + 0x1000; } > RAM }\n")
    counts = {}
    for core in (CORTEX_M4F, CORTEX_M7):
        subprocess.run(["arm-none-eabi-gcc", *core.cflags, "-O1", "-nostdlib", "-T", str(ld),
                        "-o", str(elf), str(src)], check=True)
        em = CortexM(elf, core)
        counts[core.name] = [em.call("loop", (n,), count=True) for n in (100, 200)]
    for name, ((r100, c100), (r200, c200)) in counts.items():
        assert (r100, r200) == (4950, 19900)
    m4 = counts["cortex-m4f"]
    m7 = counts["cortex-m7"]
    per_trip_m4 = (m4[1][1].cycles - m4[0][1].cycles) / 100
    per_trip_m7 = (m7[1][1].cycles - m7[0][1].cycles) / 100
    assert per_trip_m7 < per_trip_m4 - 2  # the refill the predicted branch does not pay


def test_the_cache_estimate_counts_lru_misses():
    """target/cache_lines.py's caches: a line hits once loaded, a set keeps its four most
    recent lines, and an access across a line boundary touches both."""
    from rollmpc_codegen.target.cache_lines import Cache

    c = Cache(kib=16, ways=4, line=32)
    stride = 32 * c.sets  # addresses of the same set
    for a in (0, 4, 28):
        c.access(a, 4)
    assert (c.accesses, c.misses) == (3, 1)
    for k in range(1, 5):
        c.access(k * stride)  # four more lines in set 0: line 0 is evicted
    c.access(0)
    c.access(30, 4)  # lines 0 and 1
    assert c.misses == 1 + 4 + 1 + 1


REGS = {"r1": 0x1000, "r2": 3, "r4": 0x2000, "sp": 0x3000}


@pytest.mark.parametrize("text, touched", [
    ("ldr r0, [r1], #4", [(0x1000, 4)]),  # post-index: the base, then the write-back
    ("ldr r0, [r1, #-4]!", [(0x0ffc, 4)]),  # pre-index
    ("ldr.w r0, [r1, r2, lsl #2]", [(0x100c, 4)]),
    ("ldrd r0, r1, [r1, #-8]", [(0x0ff8, 8)]),
    ("ldr r0, [pc, #16]", [(0x14, 4)]),  # pc + 4, word-aligned
    ("vldr d0, [r1, #16]", [(0x1010, 8)]),
    ("vldmia r1!, {d0-d1}", [(0x1000, 8), (0x1008, 8)]),
    ("push {r4, r5, lr}", [(0x2ff4, 4), (0x2ff8, 4), (0x2ffc, 4)]),
    ("ldmdb r1, {r2, r3}", [(0x0ff8, 4), (0x0ffc, 4)]),
    ("ldrsh r3, [r4, r2]", [(0x2003, 2)]),
    ("adds r0, r1, #1", []),
])
def test_the_cache_tool_decodes_what_a_load_or_store_touches(tmp_path, text, touched):
    """cache_lines.data_accesses(): the bytes an instruction reads or writes, from its
    operands and the registers before it runs (no memory hook: unicorn 2.x skipped a
    16-bit load with one installed)."""
    from rollmpc_codegen.target.cache_lines import data_accesses

    (insn,) = insns(tmp_path, text)
    assert data_accesses(insn, REGS.__getitem__) == touched


@pytest.mark.parametrize("cc, flags, passes", [
    (1, 0x4000_0000, True), (2, 0x4000_0000, False),  # EQ, NE with Z
    (9, 0x2000_0000, True), (10, 0x6000_0000, True),  # HI: C and not Z; LS: Z
    (11, 0x9000_0000, True), (12, 0x8000_0000, True),  # GE: N == V; LT: N != V
    (13, 0x0000_0000, True), (14, 0x4000_0000, True), (15, 0, True), (0, 0, True),
])
def test_a_conditional_access_counts_only_when_its_condition_passes(cc, flags, passes):
    from rollmpc_codegen.target.cache_lines import condition_passes

    assert condition_passes(cc, flags) is passes
