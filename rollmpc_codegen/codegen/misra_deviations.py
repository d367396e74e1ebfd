"""The MISRA C:2012 deviations of the generated C, declared once.

``cppcheck --addon=misra`` (2.10) reports rule numbers; every finding on the generated C
must be covered by one of these (:mod:`rollmpc_codegen.verify.misra` checks, and the
generated README lists them, with ``P_`` written as the prefix).  ``files`` is a glob on
the generated file name without its prefix (``_solver.c``, ``.h``, ``*``).  ``kind``:
``advisory`` or ``required`` (a rule deviated for the stated reason, no defect), or
``false-positive`` (the addon flags code the rule does not forbid).  Rule headlines are
paraphrased (the MISRA rule texts are licensed and not shipped).
"""
from __future__ import annotations

import fnmatch
from typing import NamedTuple


class Deviation(NamedTuple):
    rule: str
    files: str  # glob on the file name with the prefix removed ("_solver.c", "*")
    kind: str  # "advisory" | "required" | "false-positive"
    reason: str

    def covers(self, rule: str, file: str, prefix: str) -> bool:
        """Does it cover a finding of ``rule`` in generated file ``file``?"""
        name = file[len(prefix):] if file.startswith(prefix) else file
        return rule == self.rule and fnmatch.fnmatch(name, self.files)


DEVIATIONS = (
    Deviation("2.2", "*", "required",
              "\"No dead code\": the addon flags size expressions such as HORIZON * "
              "N_OUTPUTS or NT_MAX * N_MAX where one factor is 1 for this configuration; "
              "the same template serves every configuration, so the operation is not dead "
              "in general."),
    Deviation("2.3", "_config.h", "advisory",
              "\"No unused type declarations\": the double tree declares a never-used array "
              "typedef whose size turns negative under GCC's -fsingle-precision-constant "
              "(ArduPilot), which would silently round every stored matrix to float; the "
              "declaration exists only to stop such a build at compile time."),
    Deviation("2.4", ".h", "advisory",
              "\"No unused tag declarations\": the status enum is public API for the "
              "integrator (switch on P_status); the library itself returns int."),
    Deviation("2.5", "_config.h", "advisory",
              "\"No unused macros\": the configuration header documents every size and "
              "switch (PRECISION_DOUBLE, NU_MAX, POLISH_FIRST, ...) for the integrator, "
              "whether or not this configuration's code uses it."),
    Deviation("2.5", ".h", "advisory",
              "\"No unused macros\": the status test STATUS_PLAN_USABLE() is the "
              "integrator's (glue code flies the command or its fallback by it); the "
              "library itself returns the status and does not test it."),
    Deviation("8.9", "_controller.c", "advisory",
              "\"Define an object at block scope if used in one function\": the scheduler "
              "thresholds of eq. (3) are generated file-scope constants so they are "
              "visible next to the file header."),
    Deviation("10.3", "*", "required",
              "\"No assignment to a different essential type\": 0/1 results of comparisons "
              "are stored in int flags and counters (C99 without stdbool, matching the "
              "int status API); the values are exactly 0 or 1, no information is lost."),
    Deviation("10.4", "*", "required",
              "\"Operands of the same essential type category\": int statuses are compared "
              "with the enum constants of P_status; the API returns statuses as int by "
              "design, and every enum constant is a small non-negative int."),
    Deviation("11.9", "*", "required",
              "\"NULL is the only null pointer constant\": pointers are compared with 0, "
              "which is a null pointer constant in C99 and needs no header; behaviour is "
              "identical to NULL."),
    Deviation("12.1", "*", "advisory",
              "\"Make operator precedence explicit\": index arithmetic such as a * n + b "
              "and comparisons joined by && are written in the usual C precedence; adding "
              "parentheses everywhere would obscure the maths the NumPy reference "
              "mirrors."),
    Deviation("12.3", "*", "false-positive",
              "\"No comma operator\": the addon flags declarations with several declarators "
              "(int i, j;). Those commas are not the comma operator; the generated code "
              "uses no comma operator."),
    Deviation("13.3", "_solver.c", "advisory",
              "\"++/-- with no other side effect\": list appends such as set[count++] = r "
              "are the idiomatic and reviewed form; each such statement has exactly one "
              "increment and one store to different objects."),
    Deviation("13.3", "_linalg.c", "advisory",
              "\"++/-- with no other side effect\": the inner loops of the packed kernels "
              "walk their rows with post-incremented pointers (s -= *x++ * *y++), the "
              "usual form of a sequential dot product, which the Cortex-M4F compiles to "
              "post-indexed loads; each pointer is incremented once per statement and "
              "read only through itself, and the summation order is the one the NumPy "
              "reference mirrors."),
    Deviation("14.1", "*", "false-positive",
              "\"No loop counter of floating type\": the addon flags the pointer walks of "
              "the packed kernels (while (y0 != end) over a float row); the loop is "
              "controlled by a pointer compared with a pointer, no floating-point value "
              "counts the loop."),
    Deviation("18.4", "*", "advisory",
              "\"No + or - on pointers\": the packed kernels advance row pointers through "
              "the packed triangle (q0 + j + 1, r + j, end = q0 + j); every pointer stays "
              "within its array (the bounds are the packed row lengths; ASan/UBSan and "
              "valgrind runs of the generator's reliability checks cover it), and the pointer "
              "walk is what the NumPy reference's summation order describes."),
    Deviation("2.4", "_solver.c", "false-positive",
              "\"No unused tag declarations\": the primal polish names its role and form "
              "flags with an anonymous enum (the C99 way to name int constants without "
              "macros); an anonymous enum declares no tag, and its constants are used."),
    Deviation("14.4", "*", "required",
              "\"Controlling expression essentially Boolean\": int flags holding 0 or 1 "
              "(use_y, converged, in_set[r], ...) are tested directly; C99 without "
              "stdbool, consistent with 10.3."),
    Deviation("15.4", "_solver.c", "advisory",
              "\"At most one break per loop\": the solver's outer loop stops on several "
              "documented conditions (optimal, diverged, cap, inaccurate); one break per "
              "condition keeps each status visible."),
    Deviation("15.5", "*", "advisory",
              "\"Single point of exit\": early returns on bad arguments and on "
              "factorisation failure keep the nominal path unindented; no resource needs "
              "releasing on exit (static memory only)."),
    Deviation("17.8", "_solver.c", "advisory",
              "\"Do not modify a function parameter\": index parameters are rebased (a -= "
              "n) and working-set sizes updated in place in small static helpers; the "
              "caller's values are unaffected (pass by value)."),
    Deviation("19.2", ".h", "advisory",
              "\"The union keyword should not be used\": P_work's index lists run (the "
              "reference's runs, read only while the unconstrained step is formed) and set "
              "(the sweep set, written after it) share one union of int16_t arrays: the "
              "same type, never live at once, so nothing is read as another type; it keeps "
              "the instance of a long horizon inside a 32 KiB RAM."),
    Deviation("20.10", "_config.h", "advisory",
              "\"No # or ## operators\": R_(x) pastes the f suffix onto literals in the "
              "float build (x##f), the only way to keep one template for both precisions "
              "with only float literals in the float build (tested: no double literal in "
              "the float build)."),
)
