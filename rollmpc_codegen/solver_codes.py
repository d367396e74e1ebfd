"""The solver's internal return codes and the constants the C and the NumPy reference
share, each declared once.

The generated C returns these codes between its own functions (never to the caller: the
public codes are :mod:`.status`); :mod:`.codegen.context` passes them to the templates,
which define each as a macro in the partial that returns it, and the reference
(:mod:`.reference`) compares against the same values.  ``tests/codegen/test_mirror.py``
checks that every name below is defined in the rendered C with its value.
"""
from __future__ import annotations

from typing import NamedTuple

# The largest dual multiplier before the sweeps declare the QP infeasible (P_LAMBDA_LIMIT)
LAMBDA_LIMIT = 1.0e30


class InternalCode(NamedTuple):
    name: str
    value: int
    partial: str  # the template partial under templates/solver/ that defines its macro
    doc: str


INTERNAL_CODES = (
    InternalCode("OUT_OF_WORK", -2, "work",
                 "a solver part stopped: the budget cannot afford its next unit"),
    InternalCode("OUT_OF_WORK_AT_TH0", -3, "work",
                 "the dual active set stopped so before a point of its own"),
    InternalCode("GUESS_CAPPED", -4, "polish",
                 "polish(): a guess that resume_working_set() would repeat"),
    InternalCode("GUESS_HANDED_OVER", -5, "polish",
                 "polish(): a guess' set goes on, dual feasible or cycling (stopped())"),
    InternalCode("SET_HANDED_BACK", -6, "polish",
                 "polish(): the dual active set's set goes back to it, a row outside violated"),
    # dual_active_set()'s `from` is a row count (>= 0), -1 (nothing to resume: the warm
    # start may run) or COLD_START; it never meets OUT_OF_WORK, whose value it shares
    InternalCode("COLD_START", -2, "active_set",
                 "dual_active_set()'s from: no warm start (the guess' repeat)"),
)

# What the work array chol holds (ws->chol_holds; P_CHOL_* in internal.h)
CHOL_STATES = (("NONE", 0), ("DUAL", 1), ("PRIMAL", 2))

(OUT_OF_WORK, OUT_OF_WORK_AT_TH0, GUESS_CAPPED, GUESS_HANDED_OVER, SET_HANDED_BACK,
 COLD_START) = (c.value for c in INTERNAL_CODES)
CHOL_NONE, CHOL_DUAL, CHOL_PRIMAL = (value for _, value in CHOL_STATES)


def context_codes() -> dict:
    """The codes and constants for the templates: each code by name, the chol states."""
    return {"codes": {c.name: {"value": c.value, "partial": c.partial, "doc": c.doc}
                      for c in INTERNAL_CODES},
            "chol_states": [{"name": name, "value": value} for name, value in CHOL_STATES],
            "lambda_limit": LAMBDA_LIMIT}
