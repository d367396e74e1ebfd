"""Stage 9 (target): cross-compile a generated controller for its core and size it.

The target build is the generated C plus a template-rendered harness
(``templates/target/harness.c.j2``: a static controller instance, static input/output
buffers and two entry functions) linked with ``templates/target/link.ld.j2``. It is built
with the flags of ``make firmware``: the core's (parts.py, from the context's ``target``:
hard float, single or double precision as its FPU), ``-O2``, ``-ffp-contract=off`` for
bit-exactness with the host build, plus ``-fstack-usage``.

Sizes come from the ELF section headers: flash = everything loaded from flash (code,
constants, the initial values of ``.data``); static RAM = ``.data`` + ``.bss`` (the stack
reservation is reported apart). The worst stack path combines GCC's per-function frames
(``.su`` files) with the call graph read from the machine code (direct ``bl``/``b``
targets), so it covers library routines such as ``memcpy`` too.
"""
from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..host.build import STRICT_WARNINGS, BuildError
from ..parts import CORES, CORTEX_M4F, FLASH_BASE, Core
from ..host.build_cache import private_root, publish, staging, verified
from ..codegen.render import render_sources, render_template
from .state_layout import LAYOUT_WORDS, StateLayout, ctrl_members

CROSS_CC = "arm-none-eabi-gcc"
CROSS_INSTALL_HINT = ("apt-get install -y --no-install-recommends gcc-arm-none-eabi "
                      "libnewlib-arm-none-eabi")
# -ffreestanding implies -fno-builtin, which turns every fabsf/sqrtf into a library call;
# -fbuiltin restores VABS/VSQRT and -fno-math-errno lets sqrtf be VSQRT alone (no libm);
# -ffp-contract=off: no fused multiply-add, so every operation rounds as on the host
TARGET_CFLAGS = ("-O2", "-ffreestanding", "-fbuiltin", "-fno-math-errno", "-ffp-contract=off",
                 "-ffunction-sections", "-fdata-sections", "-fstack-usage")
TARGET_LDFLAGS = ("-nostartfiles", "--specs=nano.specs", "-Wl,--gc-sections")
# What double costs on this part, which has single-precision floating point only (every
# double operation a soft-float library call): the double build's cycles over the float
# build's, from the smaller median-step ratio to the larger worst-step one, rounded
# (`rollmpc report --precision double` and `--precision float`, docs/checks.md:
# tests/data/newuser/ship_heading.yaml 8.2 and 14.6, uav_roll --steps 1000 6.8 and 22.2)
SOFT_DOUBLE_FACTOR = (7, 22)
RAM_BASE = 0x20000000  # of the emulation image (parts.py: the real parts' regions)
# Memory of the emulation image: large enough for any horizon of the sweep; whether a
# build fits a real part is judged from its sizes (see docs/target.md).
EMU_FLASH_KIB = 16 * 1024
EMU_RAM_KIB = 16 * 1024
EMU_STACK_BYTES = 16 * 1024


def cross_compiler() -> str | None:
    """Path of arm-none-eabi-gcc, or None."""
    return shutil.which(CROSS_CC)


def require_cross_compiler() -> str:
    cc = cross_compiler()
    if cc is None:
        raise BuildError(f"{CROSS_CC} not found; install with: {CROSS_INSTALL_HINT}")
    return cc


@dataclass
class TargetBuild:
    """A linked target image of one generated controller."""

    elf: Path
    build_dir: Path
    prefix: str
    core: Core = CORTEX_M4F  # what it was compiled for: the emulator's CPU and cycle model
    su_files: list[Path] = field(default_factory=list)
    members: tuple[str, ...] = ()  # the instance's members, as the harness lists them


def _run(cmd: list[str]) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or proc.stderr.strip():
        raise BuildError(f"{' '.join(cmd)}\n{proc.stderr}")


def core_of(ctx: dict) -> Core:
    """The core a generated controller was generated for (its context's ``target``)."""
    return CORES[ctx["target"]["core"]]


def target_cflags(ctx: dict, extra_cflags: tuple[str, ...] = ()) -> list[str]:
    """Every flag the target build compiles with (what ``rollmpc report`` records)."""
    return [*core_of(ctx).cflags, *TARGET_CFLAGS, *extra_cflags]


def build_target(ctx: dict, build_root: Path, flash_kib: int = EMU_FLASH_KIB,
                 ram_kib: int = EMU_RAM_KIB, stack_bytes: int = EMU_STACK_BYTES,
                 extra_cflags: tuple[str, ...] = ()) -> TargetBuild:
    """Render, cross-compile (warnings are errors) and link the target harness image.

    Cached under ``build_root/target-<hash of sources, flags and memory>``; a cached image
    is reused only if its record verifies (host/build_cache.py).
    """
    root = private_root(build_root)
    cc = require_cross_compiler()
    prefix = ctx["prefix"]
    files = render_sources(ctx)
    members = tuple(ctrl_members(files[f"{prefix}.h"], prefix))
    files[f"{prefix}_target_harness.c"] = render_template(ctx, "target/harness.c.j2",
                                                          members=members)
    files[f"{prefix}_target.ld"] = render_template(
        ctx, "target/link.ld.j2", flash_kib=flash_kib, ram_kib=ram_kib,
        stack_bytes=stack_bytes)
    core = core_of(ctx)
    cflags = [*core.cflags, *TARGET_CFLAGS, *STRICT_WARNINGS, *extra_cflags]
    digest = hashlib.sha256()
    for name in sorted(files):
        digest.update(name.encode())
        digest.update(files[name].encode())
    digest.update(" ".join([cc, *cflags, *TARGET_LDFLAGS]).encode())
    key = digest.hexdigest()
    out, elf_name = root / f"target-{prefix}-{key[:16]}", f"{prefix}_target.elf"
    elf = verified(out, elf_name, key)
    if elf is not None:
        return TargetBuild(elf=elf, build_dir=out, prefix=prefix, core=core,
                           su_files=sorted(out.glob("*.su")), members=members)
    with staging(root, out.name) as tmp:
        for name, text in files.items():
            (tmp / name).write_text(text)
        objs = []
        for src in sorted(tmp.glob("*.c")):
            obj = src.with_suffix(".o")
            _run([cc, *cflags, f"-I{tmp}", "-c", str(src), "-o", str(obj)])
            objs.append(obj)
        _run([cc, *core.cflags, *TARGET_LDFLAGS, "-T", str(tmp / f"{prefix}_target.ld"),
              f"-Wl,-Map={tmp / (prefix + '_target.map')}", "-o", str(tmp / elf_name),
              *map(str, objs), "-lm", "-lgcc"])
        elf = publish(tmp, out, elf_name, key)
    return TargetBuild(elf=elf, build_dir=out, prefix=prefix, core=core,
                       su_files=sorted(out.glob("*.su")), members=members)


# ----------------------------------------------------------------------------- sizes
def image_sizes(elf: Path) -> dict:
    """Flash and static RAM of a linked image, from its section headers.

    Returns ``{"flash_bytes", "ram_bytes", "text_bytes", "data_bytes", "bss_bytes",
    "stack_reserved_bytes"}``; flash = allocated sections in flash + ``.data`` (its load
    image), ram = ``.data`` + ``.bss`` (the stack reservation is not static data).
    """
    from elftools.elf.elffile import ELFFile

    sizes = {"text": 0, "data": 0, "bss": 0, "stack": 0}
    with open(elf, "rb") as fh:
        for sec in ELFFile(fh).iter_sections():
            flags, addr, size = sec["sh_flags"], sec["sh_addr"], sec["sh_size"]
            if not flags & 0x2 or size == 0:  # SHF_ALLOC
                continue
            if sec.name == ".stack":
                sizes["stack"] += size
            elif addr < RAM_BASE:
                sizes["text"] += size
            elif sec["sh_type"] == "SHT_NOBITS":
                sizes["bss"] += size
            else:
                sizes["data"] += size
    return {"flash_bytes": sizes["text"] + sizes["data"], "ram_bytes": sizes["data"] + sizes["bss"],
            "text_bytes": sizes["text"], "data_bytes": sizes["data"], "bss_bytes": sizes["bss"],
            "stack_reserved_bytes": sizes["stack"]}


def function_symbols(elf: Path) -> list[tuple[int, int, str]]:
    """(start address without the Thumb bit, size, name) of every function, sorted."""
    from elftools.elf.elffile import ELFFile

    out = {}
    with open(elf, "rb") as fh:
        symtab = ELFFile(fh).get_section_by_name(".symtab")
        for sym in symtab.iter_symbols():
            if sym["st_info"]["type"] == "STT_FUNC" and sym["st_size"] > 0:
                out[sym["st_value"] & ~1] = (sym["st_value"] & ~1, sym["st_size"], sym.name)
    return sorted(out.values())


def object_symbols(elf: Path) -> dict[str, tuple[int, int]]:
    """name -> (address, size) of every data object."""
    from elftools.elf.elffile import ELFFile

    out = {}
    with open(elf, "rb") as fh:
        symtab = ELFFile(fh).get_section_by_name(".symtab")
        for sym in symtab.iter_symbols():
            if sym["st_info"]["type"] == "STT_OBJECT":
                out[sym.name] = (sym["st_value"], sym["st_size"])
    return out


def read_object(elf: Path, name: str) -> bytes:
    """The initial bytes of the data object ``name`` (a constant of the image)."""
    from elftools.elf.elffile import ELFFile

    address, size = object_symbols(elf)[name]
    with open(elf, "rb") as fh:
        for sec in ELFFile(fh).iter_sections():
            start = sec["sh_addr"]
            if sec["sh_type"] != "SHT_NOBITS" and start <= address < start + sec["sh_size"]:
                return sec.data()[address - start:address - start + size]
    raise KeyError(f"{name}: no initial bytes in {elf}")


def target_layout(build, ctx: dict) -> StateLayout:
    """The :class:`StateLayout` a target image (target.build.TargetBuild) declares."""
    p, names = ctx["prefix"], list(build.members)
    words = np.frombuffer(read_object(build.elf, f"{p}_target_layout"), np.uint32)
    offsets = np.frombuffer(read_object(build.elf, f"{p}_target_members"), np.uint32)
    if len(words) != LAYOUT_WORDS or len(offsets) != len(names):
        raise RuntimeError(f"{build.elf}: a harness of another layout")
    real = np.dtype(np.float32 if ctx["real"] == "float" else np.float64)
    return StateLayout.from_words(words, names, offsets, real)


def largest_symbols(elf: Path, count: int = 10) -> list[dict]:
    """The ``count`` largest functions and data objects: name, bytes, flash or ram."""
    from elftools.elf.elffile import ELFFile

    rows = []
    with open(elf, "rb") as fh:
        symtab = ELFFile(fh).get_section_by_name(".symtab")
        for sym in symtab.iter_symbols():
            if sym["st_info"]["type"] in ("STT_FUNC", "STT_OBJECT") and sym["st_size"] > 0:
                where = "ram" if sym["st_value"] >= RAM_BASE else "flash"
                rows.append({"name": sym.name, "bytes": int(sym["st_size"]), "memory": where})
    rows.sort(key=lambda r: (-r["bytes"], r["name"]))
    return rows[:count]


# ----------------------------------------------------------------------------- stack
def _su_frames(su_files: list[Path]) -> dict[str, tuple[int, str]]:
    """function name -> (frame bytes, qualifier) from GCC's .su files."""
    frames: dict[str, tuple[int, str]] = {}
    for su in su_files:
        for line in su.read_text().splitlines():
            loc, size, qual = line.split("\t")
            name = loc.rsplit(":", 1)[-1]
            if name not in frames or int(size) > frames[name][0]:
                frames[name] = (int(size), qual)
    return frames


def _prologue_frame(insns) -> int:
    """Stack bytes reserved by a function prologue (push/vpush/sub sp/pre-indexed store to
    sp), for code without a .su entry (library routines)."""
    total = 0
    for insn in insns[:8]:
        ops = insn.op_str
        if insn.mnemonic in ("push", "push.w", "stmdb", "stmdb.w") and (
                insn.mnemonic.startswith("push") or ops.startswith("sp!")):
            total += 4 * (ops.count(",") + 1 - (1 if ops.startswith("sp!") else 0))
        elif insn.mnemonic == "vpush":
            regs = ops.strip("{}").split(",")
            words = 0
            for reg in regs:
                reg = reg.strip()
                if "-" in reg:
                    lo, hi = reg.split("-")
                    count = int(hi.strip()[1:]) - int(lo.strip()[1:]) + 1
                else:
                    lo, count = reg, 1
                words += count * (2 if lo.strip().startswith("d") else 1)
            total += 4 * words
        elif insn.mnemonic.startswith("sub") and ops.startswith("sp, sp, #"):
            total += int(ops.split("#")[1], 0)
        elif "[sp, #-" in ops and ops.endswith("]!"):  # str lr, [sp, #-8]! (libgcc)
            total += int(ops.split("#-")[1].rstrip("]!"), 0)
    return total


def _function_code(elf: Path) -> dict[str, tuple[int, bytes]]:
    """name -> (address, machine code) of every function in the image."""
    from elftools.elf.elffile import ELFFile

    with open(elf, "rb") as fh:
        ef = ELFFile(fh)
        blobs = [(s["sh_addr"], s.data()) for s in ef.iter_sections()
                 if s["sh_flags"] & 0x4 and s["sh_size"]]  # SHF_EXECINSTR
    out = {}
    for addr, size, name in function_symbols(elf):
        out[name] = (addr, next((d[addr - b: addr - b + size] for b, d in blobs
                                 if b <= addr < b + len(d)), b""))
    return out


def _disassembler():
    from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs

    md = Cs(CS_ARCH_ARM, CS_MODE_THUMB | CS_MODE_MCLASS)
    md.skipdata = True  # literal pools inside a function would otherwise end the listing
    return md


def call_graph(elf: Path) -> dict[str, set[str]]:
    """Direct calls (bl) and tail calls (b to another function's start) of every function."""
    code = _function_code(elf)
    by_addr = {addr: name for name, (addr, _) in code.items()}
    md = _disassembler()
    graph: dict[str, set[str]] = {}
    for name, (addr, blob) in code.items():
        callees = set()
        for insn in md.disasm(blob, addr):
            if insn.mnemonic.split(".")[0] in ("bl", "b", "blx") and insn.op_str.startswith("#"):
                target = int(insn.op_str[1:], 0) & ~1
                if target in by_addr and not (addr <= target < addr + len(blob)):
                    callees.add(by_addr[target])
        graph[name] = callees
    return graph


def worst_stack(build: TargetBuild, root: str) -> dict:
    """Deepest call path from ``root`` in the linked image: GCC's frames (.su files) where
    they exist, the prologue's otherwise (library routines); the call graph is read from
    the machine code. Returns ``{"bytes", "path", "frames", "dynamic"}`` (dynamic lists
    functions on the path whose .su frame is not static)."""
    from .stack_usage import StackReport

    su = _su_frames(build.su_files)
    md = _disassembler()
    frames, qualifiers = {}, {}
    for name, (addr, blob) in _function_code(build.elf).items():
        gcc_name = name if name in su else re.sub(r"\.\d+$", "", name)  # s_row_dot.isra.0
        if gcc_name in su:
            frames[name], qualifiers[name] = su[gcc_name]
        else:
            frames[name] = _prologue_frame(list(md.disasm(blob, addr)))
            qualifiers[name] = "prologue"
    try:
        total, path = StackReport(frames=frames, qualifiers=qualifiers,
                                  calls=call_graph(build.elf)).worst_path(root)
    except ValueError as exc:  # recursion: the design forbids it
        raise BuildError(f"target image: {exc}") from None
    return {"bytes": total, "path": path, "frames": {n: frames[n] for n in path},
            "dynamic": sorted(n for n in path if "dynamic" in qualifiers[n])}
