"""The compiler flags of the generated C, declared once: what the host and target builds
pass, the warning sets the C is kept clean under, and the flags that break its guarantees,
which ``config.h.j2`` refuses with an ``#error`` and the generated README lists."""
from __future__ import annotations

from typing import NamedTuple

STRICT_WARNINGS = ("-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
                   "-Wdouble-promotion", "-Werror")
# PX4's C flags and ArduPilot's frame limit: the generated C compiles clean under them too
AUTOPILOT_WARNINGS = ("-Wfloat-equal", "-Wcast-align", "-Wstrict-prototypes",
                      "-Wbad-function-cast", "-Wnested-externs", "-fno-common",
                      "-Wframe-larger-than=1300")
# no fused multiply-add: every product and sum rounds as the NumPy reference's
EXACT_MATH = ("-ffp-contract=off",)


class RefusedFlag(NamedTuple):
    flag: str
    macro: str  # what the compiler predefines (nonzero) under the flag
    why: str


REFUSED_FLAGS = (
    RefusedFlag("-ffast-math", "__FAST_MATH__",
                "it compiles the NaN/Inf checks away and reorders the sums"),
    RefusedFlag("-ffinite-math-only", "__FINITE_MATH_ONLY__",
                "it compiles the NaN/Inf checks away"),
    RefusedFlag("-fassociative-math", "__ASSOCIATIVE_MATH__",
                "it reorders the sums (no longer the reference's)"),
    RefusedFlag("-freciprocal-math", "__RECIPROCAL_MATH__",
                "it turns divisions into products with reciprocals (no longer the reference's)"),
)


def context_build_flags() -> dict:
    """The flags for the templates (the README and the config header's guards)."""
    return {"strict": list(STRICT_WARNINGS), "autopilot": list(AUTOPILOT_WARNINGS),
            "exact": list(EXACT_MATH),
            "refused": [f._asdict() for f in REFUSED_FLAGS]}


# The kernel variants of a tree (templates/internal.h.j2, P_WIDE_KERNELS): the target's
# compiler picks one (wide for float on an ARM single-precision FPU, plain elsewhere); a
# host build may be given either, so that the host tests run what the target runs.
KERNEL_VARIANTS = ("plain", "wide")


def kernel_flags(prefix: str, wide: bool | None) -> tuple[str, ...]:
    """The compiler flags that select the wide (True) or plain (False) kernels of the
    tree of ``prefix``; None leaves the choice to the compiler."""
    return () if wide is None else (f"-D{prefix.upper()}_WIDE_KERNELS={int(wide)}",)
