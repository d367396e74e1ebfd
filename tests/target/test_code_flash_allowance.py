"""`rollmpc generate`'s flash prediction adds CODE_FLASH_BYTES for the code: it must cover
the text of every generated function of every committed example on the Cortex-M4F at the
report's flags, none dropped by the linker, or the prediction passes designs that do not
fit (it was 18 KiB while the code grew to 32 KB)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from rollmpc_codegen.qp.footprint import CODE_FLASH_BYTES
from rollmpc_codegen.target.build import CORTEX_M4F, CROSS_CC, CROSS_INSTALL_HINT, TARGET_CFLAGS

from conftest import require_tool

GENERATED = Path(__file__).resolve().parents[2] / "generated"
TREES = sorted(p for p in GENERATED.glob("*_f32") if p.is_dir())


def text_bytes(cc: str, tree: Path, out: Path) -> int:
    """The .text sections of the tree's code (every .c but the stored data) at -O2."""
    from elftools.elf.elffile import ELFFile

    total = 0
    for src in sorted(tree.glob("*.c")):
        if src.name.endswith("_data.c"):
            continue
        obj = out / (src.stem + ".o")
        flags = [f for f in TARGET_CFLAGS if f != "-fstack-usage"]
        subprocess.run([cc, *CORTEX_M4F, *flags, "-std=c99", f"-I{tree}", "-c", str(src),
                        "-o", str(obj)], check=True, capture_output=True, text=True)
        with open(obj, "rb") as fh:
            total += sum(sec["sh_size"] for sec in ELFFile(fh).iter_sections()
                         if sec.name.startswith(".text"))
    return total


@pytest.mark.parametrize("tree", TREES, ids=[t.name for t in TREES])
def test_the_code_allowance_covers_every_example(tree, tmp_path):
    cc = require_tool(CROSS_CC, CROSS_INSTALL_HINT)
    pytest.importorskip("elftools", reason="pip install 'rollmpc-codegen[target]'")
    size = text_bytes(cc, tree, tmp_path)
    assert 16 * 1024 < size <= CODE_FLASH_BYTES, size
