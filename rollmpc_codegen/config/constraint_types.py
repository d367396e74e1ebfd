"""The dataclasses of ``modes[].constraints`` (config/constraints.py parses them; their
keys are declared with the others in schema.py)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class SignalConstraint:
    """One scalar constrained signal of a mode (``modes[].constraints``, features/signals.py):
    ``z = C x + D u`` on the plant's states x (as the state_space plant writes them, then
    its integrators) and the mode's inputs u, held within ``lo <= z <= hi`` at the times
    ``first..last`` (x_k and u_k at time k; k = 1..N without D, 0..N-1 with it).  A side
    is soft where its l2 > 0 (penalty l1 s + l2 s^2 of the slack s, as bounds.soft)."""

    name: str  # as reports print it: the signal's name, a mixed row's name[i]
    key: str  # the config key it came from, for errors and reports
    source: str  # "signals" | "mixed"
    C: np.ndarray  # (plant states,)
    D: np.ndarray  # (nu,)
    lo: float  # -inf: no lower rows
    hi: float  # +inf: no upper rows
    first: int
    last: int
    soft_l1: np.ndarray  # (2,): lo side, hi side
    soft_l2: np.ndarray  # (2,)


@dataclass(frozen=True, eq=False)
class TerminalConfig:
    """``modes[].constraints.terminal`` (features/terminal_set.py): a constraint on the
    predicted state x_N, in deviation from the steady state x_s that holds the last
    stage's reference (with the disturbance estimate of an offset-free model).

    * ``lqr_invariant``: the maximal admissible set of the terminal LQR, computed;
    * ``polytope``: ``H (x_N - x_s) <= h`` as given (H on the plant's states);
    * ``equality``: ``x_N = x_s``."""

    kind: str
    H: np.ndarray | None = None  # polytope only
    h: np.ndarray | None = None
    soft_l1: float = 0.0  # soft where l2 > 0, every row alike
    soft_l2: float = 0.0
