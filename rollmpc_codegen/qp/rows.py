"""The row kinds of the condensed QP ``L U <= c + W x``, each declared once.

Every constraint row is ``sign * q(U) <= c + W x`` for one *quantity* q of the decision
variables.  A kind says which quantities its rows bound, where those quantities are
numbered (the C's ``row_q``), whether its rows need an on-line prediction, whether they
may be soft, and what a user calls them in reports.  The condensing
(:mod:`.condense`), the stored data (:mod:`.storage`), the reference solver and the
templates read the layout from here:

====================  =====================================  =====================
kind                  quantity                               numbered from
====================  =====================================  =====================
``input``             the input U_i (box rows)               0
``output``            the predicted output (Gamma U)_k       n
``rate``              D_i = U_i - U_{i-nu} (Δu rows)         n + N ny
``signal``            z_j = Gz_j U, any linear combination   2 n + N ny
                      of states and inputs at one stage
                      (constraints.signals, .mixed,
                      .terminal: :mod:`..features.signals`)
====================  =====================================  =====================

The signal kind is the general one: a constrained signal ``z = C x + D u`` (measured or
not), a mixed row ``E x + F u <= g`` and a terminal facet ``h' x_N <= h`` are all rows on a
signal quantity, so a new constraint a user writes is a new *source* of signal rows
(one module in ``features/``), not a new kind: docs/architecture.md, "Adding a row kind".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RowKind:
    code: int  # CondensedQP.row_kind
    name: str
    label: str  # what a report calls its rows
    flag: str | None  # the context flag that builds its C (None: always built)
    predicted: bool  # its quantities need an on-line prediction (Gamma th, Gz th)
    soft: bool  # its bounds may be soft (bounds.soft, constraints.*.soft)

    def base(self, n: int, nyq: int) -> int:
        """The first quantity of the kind in a mode with n variables and N ny outputs."""
        return {"input": 0, "output": n, "rate": n + nyq, "signal": 2 * n + nyq}[self.name]


INPUT = RowKind(0, "input", "input bound", None, predicted=False, soft=False)
OUTPUT = RowKind(1, "output", "output bound", "has_output_rows", predicted=True, soft=True)
RATE = RowKind(2, "rate", "input-rate bound", "has_rate_rows", predicted=False, soft=False)
SIGNAL = RowKind(3, "signal", "signal constraint", "has_signal_rows", predicted=True, soft=True)
ROW_KINDS = (INPUT, OUTPUT, RATE, SIGNAL)
BY_CODE = {k.code: k for k in ROW_KINDS}


def quantities(kind: np.ndarray, index: np.ndarray, n: int, nyq: int) -> np.ndarray:
    """row_q of every row: its kind's base plus its index within the kind."""
    kind = np.asarray(kind)
    base = np.zeros(kind.size, dtype=np.int64)
    for k in ROW_KINDS:
        base[kind == k.code] = k.base(n, nyq)
    return (base + np.asarray(index)).astype(np.int32)


def kind_of_quantity(q: np.ndarray, n: int, nyq: int) -> np.ndarray:
    """The kind code of each quantity q (the inverse of :func:`quantities`' layout)."""
    q = np.asarray(q)
    return np.select([q < n, q < n + nyq, q < 2 * n + nyq],
                     [INPUT.code, OUTPUT.code, RATE.code], SIGNAL.code)


def is_predicted(kind: np.ndarray) -> np.ndarray:
    """Rows whose quantity needs a prediction (output and signal rows)."""
    kind = np.asarray(kind)
    return np.isin(kind, [k.code for k in ROW_KINDS if k.predicted])
