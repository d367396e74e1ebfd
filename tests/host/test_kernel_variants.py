"""Both kernel variants of a float tree run on the host, each bit for bit with the NumPy
reference: the plain kernels the host compiler selects, and the wide ones the Cortex-M4F
build selects (P_WIDE_KERNELS, templates/internal.h.j2), forced with kernel_flags().

tests/data/kernels/repeated_rows.yaml breaks its dual factor down at step 149 of its
noisy scenario, where the two variants leave different partial rows in work.chol: the
commands, statuses and work counts stay the reference's with either, and the instances
show that each build did run its own variant. (The sanitizer and valgrind runs of the
wide kernels: tests/reliability/test_sanitizers_and_stack.py; the target's instance against the host
build of its kernels: tests/target/test_instance_bit_exact.py.)"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import Built
from rollmpc_codegen.codegen.build_flags import KERNEL_VARIANTS, kernel_flags
from rollmpc_codegen.sim.simulate import run_closed_loop

ROWS = Path(__file__).resolve().parents[1] / "data" / "kernels" / "repeated_rows.yaml"
# the whole scenario (steps=None: its 180 samples); at step 158 independent_rows() empties
# the warm start, which resume_working_set() must then leave for a cold start
STEPS, NOISE, BREAKDOWN = None, 0.01, 149
KEYS = ("iterations", "polish_iterations", "active", "work")  # P_info = reference's last


def instance_without_info(c) -> bytes:
    """The host instance's bytes, the diagnostics (with the host's solve time) zeroed."""
    state = bytearray(c.instance())
    at = int(c.ffi.cast("uintptr_t", c._fn["last_info"](c.ctrl))) - \
        int(c.ffi.cast("uintptr_t", c.ctrl))
    size = c.ffi.sizeof(f"{c.prefix}_info")
    state[at:at + size] = bytes(size)
    return bytes(state)


class Lockstep:
    """The C and the reference on the same inputs; every difference and instance kept."""

    def __init__(self, built: Built):
        self.c, self.ref = built.c, built.reference()
        self.mismatches, self.instances = [], []

    def step(self, y, s, r):
        st_c, u_c = self.c.step(y, s, r)
        st_r, u_r = self.ref.step(y, s, r)
        info = self.c.info()
        if (st_c, u_c.tobytes(), *(info[k] for k in KEYS)) != \
                (st_r, u_r.tobytes(), *(self.ref.last[k] for k in KEYS)):
            self.mismatches.append((len(self.instances), st_c, st_r, u_c, u_r))
        self.instances.append(instance_without_info(self.c))
        return st_c, u_c


@pytest.fixture(scope="module")
def lockstep_runs(build_root):
    runs = {}
    for kernels in KERNEL_VARIANTS:
        built = Built(ROWS, "float", build_root, extra=kernel_flags("rows", kernels == "wide"))
        lock = Lockstep(built)
        log = run_closed_loop(built.model.config, lock, steps=STEPS, noise_std=NOISE)
        runs[kernels] = (lock, log)
    return runs


@pytest.mark.parametrize("kernels", KERNEL_VARIANTS)
def test_each_kernel_variant_is_bit_exact_with_the_reference(lockstep_runs, kernels):
    lock, log = lockstep_runs[kernels]
    assert lock.mismatches == [], lock.mismatches[:3]
    assert len(set(log.status)) > 1  # constrained and infeasible samples, not a quiet loop


def test_the_variants_leave_different_instances_where_a_factor_breaks_down(lockstep_runs):
    (plain, plain_log), (wide, wide_log) = (lockstep_runs[k] for k in KERNEL_VARIANTS)
    assert np.array_equal(plain_log.u, wide_log.u)
    differ = [k for k, (a, b) in enumerate(zip(plain.instances, wide.instances)) if a != b]
    assert differ and differ[0] == BREAKDOWN
