"""The generated config header refuses the flags that break the guarantees
(rollmpc_codegen/codegen/build_flags.py) with a one-line #error naming the flag, and
lets the flags of every build through."""
from __future__ import annotations

import subprocess

import pytest

from conftest import ROOT, require_tool
from rollmpc_codegen.codegen.build_flags import EXACT_MATH, REFUSED_FLAGS, STRICT_WARNINGS

TREES = ["uav_roll", "uav_roll_f32"]


def _compile(cc: str, tree: str, flags: list[str]) -> subprocess.CompletedProcess:
    """Syntax-check the tree's controller (which includes the config header) under flags."""
    src = ROOT / "generated" / tree
    return subprocess.run([cc, "-fsyntax-only", *flags, f"-I{src}",
                           str(next(src.glob("*_controller.c")))],
                          capture_output=True, text=True)


@pytest.mark.parametrize("tree", TREES)
@pytest.mark.parametrize("refused", REFUSED_FLAGS, ids=lambda f: f.flag)
def test_a_refused_flag_stops_the_build_with_its_message(tree, refused):
    """One message, the flag's own (-ffast-math implies the others: its is the first)."""
    gcc = require_tool("gcc", "apt-get install -y gcc")
    # -fassociative-math takes effect only without signed zeros and traps (GCC's rule)
    extra = ["-fno-signed-zeros", "-fno-trapping-math"] if "associative" in refused.flag else []
    proc = _compile(gcc, tree, [refused.flag, *extra])
    errors = [line for line in proc.stderr.splitlines() if "error: #error" in line]
    assert proc.returncode != 0 and len(errors) == 1, proc.stderr
    assert f"{refused.flag} is not supported: {refused.why}" in errors[0]


@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_fast_math_stops_clang_and_gcc(cc):
    compiler = require_tool(cc, f"apt-get install -y {cc}")
    proc = _compile(compiler, "uav_roll_f32", ["-ffast-math"])
    assert proc.returncode != 0 and "-ffast-math is not supported" in proc.stderr


@pytest.mark.parametrize("tree", TREES)
def test_the_builds_flags_pass(tree):
    gcc = require_tool("gcc", "apt-get install -y gcc")
    proc = _compile(gcc, tree, [*STRICT_WARNINGS, *EXACT_MATH, "-O2", "-fno-math-errno"])
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
