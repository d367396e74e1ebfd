"""`rollmpc generate`'s flash prediction adds the core's code allowance (parts.py
``Core.code_bytes``): it must cover the text of every generated function of every
committed example on each core at the report's flags, in the precisions it runs, none
dropped by the linker, or the prediction passes designs that do not fit (it was 18 KiB
while the code grew to 32 KB)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from rollmpc_codegen.parts import CORES
from rollmpc_codegen.target.build import CROSS_CC, CROSS_INSTALL_HINT, TARGET_CFLAGS

from conftest import require_tool

GENERATED = Path(__file__).resolve().parents[2] / "generated"
TREES = sorted(p for p in GENERATED.glob("*_f32") if p.is_dir())
# the double trees too, on the cores that run them (the M7). In make test the largest
# (fw_lateral's) on every core, and on the default core the trees of the other solver
# features (k modes and soft rows, Δu rows, many inputs); every tree in check-long.
LARGEST = "fw_lateral"
DEFAULT_CORE_TREES = {"uav_roll_f32", "quad_attitude_f32", "thermal_zones_rate_f32",
                      "chain_soft_f32"}
CASES = [pytest.param(core, tree, id=f"{core}-{tree.name}",
                      marks=() if tree.name.startswith(LARGEST) or (
                          core == "cortex-m4f" and tree.name in DEFAULT_CORE_TREES)
                      else pytest.mark.slow)
         for core in sorted(CORES) for tree in
         TREES + ([t.with_name(t.name[:-4]) for t in TREES] if CORES[core].fpu_double else [])]


def text_bytes(cc: str, cflags: tuple[str, ...], tree: Path, out: Path) -> int:
    """The .text sections of the tree's code (every .c but the stored data) at -O2."""
    from elftools.elf.elffile import ELFFile

    total = 0
    for src in sorted(tree.glob("*.c")):
        if src.name.endswith("_data.c"):
            continue
        obj = out / (src.stem + ".o")
        flags = [f for f in TARGET_CFLAGS if f != "-fstack-usage"]
        subprocess.run([cc, *cflags, *flags, "-std=c99", f"-I{tree}", "-c", str(src),
                        "-o", str(obj)], check=True, capture_output=True, text=True)
        with open(obj, "rb") as fh:
            total += sum(sec["sh_size"] for sec in ELFFile(fh).iter_sections()
                         if sec.name.startswith(".text"))
    return total


@pytest.mark.parametrize("core, tree", CASES)
def test_the_code_allowance_covers_every_example(core, tree, tmp_path):
    cc = require_tool(CROSS_CC, CROSS_INSTALL_HINT)
    pytest.importorskip("elftools", reason="pip install 'rollmpc-codegen[target]'")
    size = text_bytes(cc, CORES[core].cflags, tree, tmp_path)
    assert 16 * 1024 < size <= CORES[core].code_bytes, size
