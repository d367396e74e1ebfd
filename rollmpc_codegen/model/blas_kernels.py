"""One set of OpenBLAS kernels on every x86-64 machine, so that the offline maths (and so
every generated file) is the same to the last bit wherever it runs.

The OpenBLAS in NumPy's and SciPy's wheels picks its kernels by the CPU (DYNAMIC_ARCH): on
a CPU with AVX-512 it takes the SkylakeX kernels, whose sums round differently in the
last bit from the AVX2 (Haswell) kernels, and 32,202 numbers of uav_roll's data changed
between two machines of the same kind. The choice is made once, when the library loads,
from ``OPENBLAS_CORETYPE``: :func:`pin_kernels` sets it (unless the user did) before NumPy
is imported, which ``import rollmpc_codegen`` does first. A process that imported NumPy
before rollmpc keeps the kernels it loaded; :func:`kernels_in_use` tells which.
"""
from __future__ import annotations

import os
import platform

PINNED_CORE = "Haswell"  # AVX2 + FMA: every x86-64 server CPU since 2013
_CPUINFO = "/proc/cpuinfo"


def _cpu_has(flags: set[str]) -> bool:
    try:
        with open(_CPUINFO, encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return flags <= set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return False


def pins_here() -> bool:
    """Whether this machine takes the pin: x86-64 Linux with AVX2 and FMA (a forced core
    the CPU cannot run would stop on an illegal instruction)."""
    return platform.machine().lower() in ("x86_64", "amd64") and _cpu_has({"avx2", "fma"})


def pin_kernels() -> None:
    """Set OPENBLAS_CORETYPE to :data:`PINNED_CORE` where :func:`pins_here`, unless the
    user set it; elsewhere nothing."""
    if pins_here():
        os.environ.setdefault("OPENBLAS_CORETYPE", PINNED_CORE)


def kernels_in_use() -> list[str]:
    """The architectures of the OpenBLAS libraries loaded now (threadpoolctl)."""
    from threadpoolctl import threadpool_info

    return sorted({str(i.get("architecture")) for i in threadpool_info()
                   if i.get("internal_api") == "openblas"})
