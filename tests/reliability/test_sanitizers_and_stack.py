"""The generated C under sanitizers and valgrind, and its stack usage.

* The host C test program of ``rollmpc testvectors`` (the ``make ctest`` suite: the whole
  scenario replayed bit for bit, plus QP solves) built with
  -fsanitize=address,undefined,float-cast-overflow: it passes with 0 reports.
* The soak program (a random closed loop with injected NaN/Inf inputs, checking the API
  contract at every sample) under the same sanitizers: 0 reports, 0 violations --
  100,000 steps of the paper's controller in the long run, 20,000 of a short-horizon
  variant in the default suite (which also runs the test-vector program on 1,200 steps
  of that variant; the long run replays the paper's whole scenario in both precisions).
* valgrind (memcheck) on the test-vector program: 0 errors.
* Each with the kernels the target runs (P_WIDE_KERNELS, forced on the host): the wide
  ones of a float tree under the sanitizers, valgrind and the soak, beside the plain ones.
* Stack: per-function frames from -fstack-usage and the call graph from
  -fcallgraph-info (GCC): no recursion, no unbounded dynamic frame, and the worst path
  from each entry point within 1 KiB on the host and on Cortex-M4F.
(``nm`` shows no heap symbols: tests/codegen/test_compile_flags.py::test_static_memory_only.)
"""
from __future__ import annotations

import pytest

from conftest import UAV, require_tool, short_uav_config
from rollmpc_codegen.parts import CORES
from rollmpc_codegen.codegen.build_flags import KERNEL_VARIANTS, kernel_flags
from rollmpc_codegen.pipeline import generate
from rollmpc_codegen.host.programs import (SANITIZE, SOAK_SUMMARY, VALGRIND_BUILD,
                                           VECTORS_SUMMARY, compile_program, run_program,
                                           write_soak_program)
from rollmpc_codegen.status import STATUS_NAMES
from rollmpc_codegen.target.stack_usage import analyse
from rollmpc_codegen.host.testvectors import write_test_vectors

VALGRIND_HINT = "apt-get install -y --no-install-recommends valgrind"
ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"
FREESTANDING = ("-ffreestanding", "-fno-math-errno")  # beside each core's flags (parts.py)
STACK_LIMIT = 1024  # bytes, worst path on a core; PX4's controller work queue has 2,240 B in all
HOST_STACK_LIMIT = 1152  # bytes: x86-64 GCC inlines more into P_qp_solve and polish


def _short(tmp_path):
    return short_uav_config(tmp_path, 20)


def _vectors(config, tmp_path, precision, steps, flags):
    src = write_test_vectors(config, tmp_path / f"tv_{precision}", precision, steps)
    return compile_program(src, tmp_path / f"tv_{precision}.exe", flags)


def _assert_vectors_pass(run, steps):
    passed, failed = run.counts(VECTORS_SUMMARY)
    assert run.returncode == 0 and failed == 0 and passed >= steps, run.stdout + run.stderr


def _assert_soak_clean(run, steps):
    counts = run.counts(SOAK_SUMMARY)
    assert counts, run.stdout + run.stderr[-3000:]
    n, faults, *statuses, violations = counts
    by_name = dict(zip(STATUS_NAMES.values(), statuses))
    assert run.returncode == 0 and n == steps and violations == 0, run.stdout
    assert sum(statuses) == steps  # every status P_step returned is one it documents
    assert faults > 0 and by_name["nonfinite_input"] == faults  # every injected fault
    assert by_name["optimal"] > 0.9 * steps
    return counts


# What the target runs per precision (P_WIDE_KERNELS: the M4F takes the wide kernels in
# float, the plain ones in double), forced on the host (tests/host/test_kernel_variants.py)
TARGET_KERNELS = [pytest.param("double", "plain", marks=pytest.mark.slow), ("float", "wide")]
# the soak and valgrind: the wide kernels in the long run (the vectors above run them
# under the sanitizers in make test)
LONG_WIDE = [pytest.param(k, marks=pytest.mark.slow) if k == "wide" else k
             for k in KERNEL_VARIANTS]


def _kernels(kernels: str) -> tuple[str, ...]:
    return kernel_flags("rollmpc", kernels == "wide")


@pytest.mark.parametrize("precision,kernels", TARGET_KERNELS)
def test_vectors_under_sanitizers(tmp_path, precision, kernels):
    exe = _vectors(_short(tmp_path), tmp_path, precision, 1200, (*SANITIZE, *_kernels(kernels)))
    run = run_program(exe)
    assert run.sanitizer_reports == 0, run.stderr[-3000:]
    _assert_vectors_pass(run, 1200)


@pytest.mark.slow
@pytest.mark.parametrize("precision", ["double", "float"])
def test_vectors_under_sanitizers_paper_controller(tmp_path, precision):
    exe = _vectors(UAV, tmp_path, precision, 6000, SANITIZE)
    run = run_program(exe)
    assert run.sanitizer_reports == 0, run.stderr[-3000:]
    _assert_vectors_pass(run, 6000)


@pytest.mark.slow  # the sanitised test vectors above run in make test
@pytest.mark.parametrize("kernels", KERNEL_VARIANTS)
def test_soak_under_sanitizers(tmp_path, kernels, steps=20000):
    src = write_soak_program(_short(tmp_path), tmp_path / "soak", "float")
    exe = compile_program(src, tmp_path / "soak.exe", (*SANITIZE, *_kernels(kernels)))
    run = run_program(exe, (str(steps), "3"))
    assert run.sanitizer_reports == 0, run.stderr[-3000:]
    _assert_soak_clean(run, steps)


@pytest.mark.slow
@pytest.mark.parametrize("precision", ["double", "float"])
def test_soak_100k_steps_under_sanitizers(tmp_path, precision):
    src = write_soak_program(UAV, tmp_path / "soak", precision)
    run = run_program(compile_program(src, tmp_path / "soak.exe", SANITIZE), ("100000", "1"))
    assert run.sanitizer_reports == 0, run.stderr[-3000:]
    _assert_soak_clean(run, 100000)


@pytest.mark.parametrize("kernels", LONG_WIDE)
def test_valgrind_on_the_test_program(tmp_path, kernels):
    valgrind = require_tool("valgrind", VALGRIND_HINT)
    exe = _vectors(_short(tmp_path), tmp_path, "float", 1200,
                   (*VALGRIND_BUILD, *_kernels(kernels)))
    run = run_program(exe, valgrind=valgrind)
    assert run.valgrind_errors == 0, run.stderr[-3000:]
    _assert_vectors_pass(run, 1200)


@pytest.mark.slow
@pytest.mark.parametrize("precision", ["double", "float"])
def test_valgrind_on_the_paper_test_program(tmp_path, precision):
    valgrind = require_tool("valgrind", VALGRIND_HINT)
    exe = _vectors(UAV, tmp_path, precision, 6000, VALGRIND_BUILD)
    run = run_program(exe, valgrind=valgrind)
    assert run.valgrind_errors == 0, run.stderr[-3000:]
    _assert_vectors_pass(run, 6000)


@pytest.mark.parametrize("target, precision", [
    ("host-O2", "float"), pytest.param("cortex-m4f-O2", "float", marks=pytest.mark.slow),
    ("cortex-m4f-Os", "float"), ("cortex-m33-Os", "float"), ("cortex-m7-Os", "double"),
    pytest.param("cortex-m7-O2", "double", marks=pytest.mark.slow)])
def test_stack_worst_path(tmp_path, target, precision):
    """Every core in the precision it runs; the M7's double tree computes in hardware."""
    src = tmp_path / "src"
    generate(UAV, src, precision)
    if target.startswith("cortex"):
        core = CORES[target[:-3]]
        cc = require_tool("arm-none-eabi-gcc", ARM_HINT)
        flags = (*core.cflags, *FREESTANDING, target[-3:])
    else:
        cc, flags = "gcc", (target[-3:],)
    report = analyse(src, tmp_path / "su", cc, flags)
    assert report.unbounded == []
    assert max(report.frames.values()) <= 1300  # ArduPilot's -Wframe-larger-than
    assert report.external <= {"sqrt", "sqrtf", "fabs", "fabsf", "memset", "memmove", "memcpy"}, \
        report.external  # libm and the block moves GCC emits for loops
    for entry in ("rollmpc_step", "rollmpc_solve_qp", "rollmpc_init"):
        depth, chain = report.worst_path(entry)  # raises on recursion
        assert depth <= (STACK_LIMIT if target.startswith("cortex") else HOST_STACK_LIMIT), \
            (entry, depth, chain)
        assert depth > 0 or entry == "rollmpc_init"  # a leaf may need no frame at all
