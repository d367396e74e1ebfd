"""The generated C compiles warning-free under strict and autopilot flag sets, uses only
static memory, and the host C test program (no Python) passes bit for bit."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from compile_flags import ARM_HINT, AUTOPILOT, CLANG_HINT, STRICT, compile_objects
from conftest import UAV, require_tool
from rollmpc_codegen.parts import CORES
from rollmpc_codegen.pipeline import generate


@pytest.fixture(scope="module", params=["double", "float"])
def sources(request, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp(f"gen_{request.param}") / "uav_roll"
    generate(UAV, out, request.param)
    return out


@pytest.mark.parametrize("opt", ["-O0", "-O2", pytest.param("-Os", marks=pytest.mark.slow)])
def test_gcc_strict_no_warnings(sources, tmp_path, opt):
    proc = compile_objects("gcc", sources, [opt, *STRICT, *AUTOPILOT], tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


@pytest.mark.parametrize("opt", [pytest.param("-O0", marks=pytest.mark.slow), "-O2"])
def test_clang_strict_no_warnings(sources, tmp_path, opt):
    cc = require_tool("clang", CLANG_HINT)
    proc = compile_objects(cc, sources, [opt, *STRICT, *AUTOPILOT], tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


@pytest.mark.parametrize("core", sorted(CORES))
def test_arm_cores_no_warnings(sources, tmp_path, core):
    """Every declared core's flags (PX4's and ArduPilot's, parts.py), both precisions:
    soft-float double on the single-precision FPUs, hardware double on the M7's."""
    cc = require_tool("arm-none-eabi-gcc", ARM_HINT)
    flags = [*CORES[core].cflags, "-O2", "-ffreestanding", "-fno-math-errno",
             "-ffp-contract=off", *STRICT, *AUTOPILOT]
    proc = compile_objects(cc, sources, flags, tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


def test_float_build_has_no_double_literals(tmp_path_factory):
    out = tmp_path_factory.mktemp("f32") / "uav_roll_f32"
    generate(UAV, out, "float")
    for c in out.glob("*.c"):
        text = re.sub(r"/\*.*?\*/", "", c.read_text(), flags=re.S)  # code, not comments
        text = re.sub(r"\b(?:R_|[A-Z0-9_]+_R)\([^)]*\)", "", text)  # R_(x) pastes f on
        # every floating literal in the float build carries the f suffix
        bare = re.findall(r"(?<![\w.])\d+(?:\.\d*(?:[eE][-+]?\d+)?|[eE][-+]?\d+)(?![\w.])",
                          text)
        assert bare == [], f"{c.name}: {bare[:5]}"


def test_static_memory_only(sources, tmp_path):
    proc = compile_objects("gcc", sources, ["-O2", *STRICT], tmp_path)
    assert proc.returncode == 0, proc.stderr
    nm = require_tool("nm", "apt-get install -y binutils")
    undefined, defined = set(), set()
    for obj in tmp_path.glob("*.o"):
        out = subprocess.run([nm, str(obj)], capture_output=True, text=True).stdout
        for line in out.splitlines():
            parts = line.split()
            (undefined if parts[-2] == "U" else defined).add(parts[-1])
    external = undefined - defined
    heap = {"malloc", "calloc", "realloc", "free", "alloca", "__builtin_alloca"}
    assert not (external & heap), external & heap
    # only the square root, and the block moves GCC may emit for loops (which GCC needs
    # from the C library even when freestanding), come from outside
    assert external <= {"sqrt", "sqrtf", "memset", "memmove", "memcpy"}, external


@pytest.mark.slow  # make test builds and runs the testvectors program under the sanitizers
def test_host_c_test_program_passes(tmp_path):
    """`rollmpc testvectors` + the C compiler alone: the make ctest path."""
    from rollmpc_codegen.cli.main import main

    for precision in ("double", "float"):
        out = tmp_path / precision
        assert main(["testvectors", str(UAV), "--precision", precision, "-o", str(out),
                     "--steps", "2200"]) == 0
        exe = out / "test_vectors"
        cmd = ["gcc", "-O2", "-ffp-contract=off", *STRICT, f"-I{out}",
               *map(str, sorted(out.glob("*.c"))), "-lm", "-o", str(exe)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        run = subprocess.run([str(exe)], capture_output=True, text=True)
        assert run.returncode == 0, run.stdout
        m = re.search(r"^(\d+) passed, (\d+) failed$", run.stdout, re.M)
        assert m and int(m.group(2)) == 0 and int(m.group(1)) >= 2200, run.stdout


@pytest.mark.parametrize("precision", ["double", "float"])
def test_single_precision_constant_flag(tmp_path_factory, precision):
    """ArduPilot's -fsingle-precision-constant would round a double tree's literals (all
    the stored matrices) to float: the double tree refuses to compile under it, naming the
    reason; the float tree (every literal already float) compiles warning-free."""
    out = tmp_path_factory.mktemp(f"spc_{precision}") / "uav_roll"
    generate(UAV, out, precision)
    proc = compile_objects("gcc", out, ["-O2", *STRICT, "-fsingle-precision-constant"],
                           out.parent / "obj")
    if precision == "float":
        assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    else:
        assert proc.returncode != 0
        assert "double_tree_built_with_single_precision_constants" in proc.stderr
