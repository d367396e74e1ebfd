"""The wide kernels of a float tree (P_WIDE_KERNELS: cholesky_from()'s 4 x 4 blocks, on an
ARM single-precision FPU only) factor and solve bit for bit as the plain ones and as the
NumPy reference, whatever the order and the first row. The host never takes that path by
itself, so it is built here a second time with __ARM_FP defined as a Cortex-M4F's
compiler defines it. The back substitution (chol_ltsolve(), four rows a trip on every
target, each sum in decreasing k) is checked the same way, every order's last block of
one to four rows included."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from rollmpc_codegen.reference.linalg import (chol_lsolve_from, chol_ltsolve,
                                              cholesky_from)

TREE = Path(__file__).resolve().parents[2] / "generated" / "uav_roll_f32"
CASES = [(n, start) for n in (1, 2, 3, 4, 5, 7, 8, 9, 13, 16, 31, 50) for start in
         sorted({0, 1, 2, 3, 4, n // 2, n - 1}) if start < n]

DRIVER = r"""
#include <stdio.h>
#include <string.h>
#include "rollmpc_internal.h"

/* the SPD matrix B B' + n I (B with entries from a fixed LCG), packed lower, in a */
static void spd(float *a, int n, unsigned seed)
{
    static float b[64 * 64];
    int i, j, k;
    for (i = 0; i < n * n; ++i) {
        seed = seed * 1664525u + 1013904223u;
        b[i] = (float)((seed >> 8) & 0xffff) / 65536.0f - 0.5f;
    }
    for (i = 0; i < n; ++i) {
        for (j = 0; j <= i; ++j) {
            float s = (i == j) ? (float)n : 0.0f;
            for (k = 0; k < n; ++k) {
                s += b[i * n + k] * b[j * n + k];
            }
            a[i * (i + 1) / 2 + j] = s;
        }
    }
}

static void put(const float *v, int count)
{
    int i;
    for (i = 0; i < count; ++i) {
        unsigned u;
        memcpy(&u, &v[i], sizeof u);
        printf("%08x ", u);
    }
}

int main(int argc, char **argv)
{
    static float a[64 * 65 / 2], full[64 * 65 / 2], y[64], x[64];
    int c;
    printf("wide %d\n", ROLLMPC_WIDE_KERNELS);
    for (c = 1; c + 1 < argc; c += 2) {
        int n, start, i, status;
        sscanf(argv[c], "%d", &n);
        sscanf(argv[c + 1], "%d", &start);
        spd(a, n, 12345u + (unsigned)n);
        memcpy(full, a, sizeof a);
        printf("%d %d ", n, start);
        put(a, n * (n + 1) / 2); /* A, then L and y */
        /* rows < start hold L already: factor them first, then the rest from start */
        rollmpc_cholesky_from(full, 0, start);
        memcpy(a, full, sizeof a);
        status = rollmpc_cholesky_from(a, start, n);
        for (i = 0; i < n; ++i) {
            y[i] = (float)(i % 5) - 1.75f;
        }
        rollmpc_chol_lsolve_from(a, 0, n, y);
        memcpy(x, y, sizeof x);
        rollmpc_chol_ltsolve(a, n, x);
        printf("%d ", status);
        put(a, n * (n + 1) / 2);
        put(y, n);
        put(x, n);
        printf("\n");
    }
    return 0;
}
"""


def build_and_run(tmp_path: Path, name: str, defines: tuple[str, ...]) -> list[str]:
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler: apt-get install -y gcc")
    src = tmp_path / "driver.c"
    src.write_text(DRIVER)
    exe = tmp_path / name
    subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
                    *defines, f"-I{TREE}", str(src), str(TREE / "rollmpc_linalg.c"), "-lm",
                    "-o", str(exe)], check=True, capture_output=True, text=True)
    args = [str(v) for case in CASES for v in case]
    return subprocess.run([str(exe), *args], check=True, capture_output=True,
                          text=True).stdout.splitlines()


def words(text: list[str]) -> np.ndarray:
    return np.array([int(w, 16) for w in text], np.uint32).view(np.float32)


def test_wide_kernels_factor_and_solve_as_the_plain_ones_and_the_reference(tmp_path):
    """Factor, forward and back substitution: wide == plain == reference, bit for bit."""
    plain = build_and_run(tmp_path, "plain", ())
    wide = build_and_run(tmp_path, "wide", ("-D__ARM_FP=4",))
    assert plain[0] == "wide 0" and wide[0] == "wide 1"  # each build took its own path
    assert len(plain) == len(CASES) + 1
    assert wide[1:] == plain[1:]
    for line in plain[1:]:
        n, start, *rest = line.split()
        n, start, size = int(n), int(start), int(n) * (int(n) + 1) // 2
        status, got = int(rest[size]), words(rest[size + 1:])
        a = words(rest[:size]).copy()  # A as the driver built it
        # the result does not depend on the first row: the reference factors from row 0
        assert status == 0 and cholesky_from(a, n)
        y = np.array([(i % 5) - 1.75 for i in range(n)], np.float32)
        chol_lsolve_from(a, n, y)
        x = y.copy()
        chol_ltsolve(a, n, x)
        assert np.array_equal(got.view(np.uint32), np.concatenate((a, y, x)).view(np.uint32)), \
            (n, start)
