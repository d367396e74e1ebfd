"""Control horizon and move blocking: a mode's decision vector held constant over blocks.

``move_blocking: [b_1, ..., b_p]`` (block lengths, each >= 1, summing to the horizon N)
makes each block of stages hold one input vector; ``control_horizon: Nc`` (1 <= Nc <= N,
u_k = u_{Nc-1} for k >= Nc) is the pattern [1, ..., 1, N - Nc + 1].  Both keys exist at
the top level (every mode) and per mode (overrides the top level); docs/features.md,
"Control horizon and move blocking".

The decision vector becomes U_b (p nu) with ``U = T U_b`` and T the 0/1 expansion
(:func:`expansion`).  :func:`..qp.condense.condense` builds the blocked QP from the full one:
Gamma_b = Gamma T, Psi_b = T' Psi T (so E_b = T' E T, and a Δu weight penalises the
step between consecutive blocks), the state gradient T' Gx, one pair of input rows per
block (at the block's first stage) and the output rows of Gamma_b, unchanged in number.
Everything after that (qp/condense.py and qp/storage.py: E^-1 Gamma', Kx, colsum, the
terminal split S + V'(2P)V) is already written for any n.

The C predicts the outputs from the Markov parameters over the *stages* (the N^2/2
product of predict_outputs()); a blocked mode stores ``stage_block`` (the block of each
stage, N int16) and reads ``th[stage_block[t] nu + b]`` for stage t, which is exactly the
prediction of the expanded U = T th.  Hence the output certificate ``out_bound`` of the
unblocked problem (sum of |C A^i B| over the row, inflated for rounding) stays sound
as it is: the C's rounded sum is the same sequence of operations on U, and max|U| = max|th|.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..config.errors import ConfigError


def blocks_of(control_horizon: Any, move_blocking: Any, horizon: int,
              key: str) -> tuple[int, ...] | None:
    """The block lengths given by one level's keys (``key`` = that level's path, "" at the
    top), or None when neither is given.  A pattern of N blocks of 1 is returned as it is
    (callers treat it as unblocked, see :func:`is_blocked`)."""
    def name(k):
        return f"{key}.{k}" if key else k

    if control_horizon is not None and move_blocking is not None:
        raise ConfigError(name("move_blocking"),
                          "give either control_horizon or move_blocking, not both")
    if control_horizon is not None:
        nc = control_horizon
        if isinstance(nc, bool) or not isinstance(nc, int):
            raise ConfigError(name("control_horizon"), f"must be an integer, got {nc!r}")
        if nc < 1:
            raise ConfigError(name("control_horizon"), f"must be >= 1, got {nc}")
        if nc > horizon:
            raise ConfigError(name("control_horizon"),
                              f"must be <= horizon ({horizon}), got {nc}")
        return (1,) * (nc - 1) + (horizon - nc + 1,)
    if move_blocking is not None:
        if not isinstance(move_blocking, list) or not move_blocking:
            raise ConfigError(name("move_blocking"),
                              "must be a non-empty list of block lengths")
        for i, b in enumerate(move_blocking):
            if isinstance(b, bool) or not isinstance(b, int):
                raise ConfigError(f"{name('move_blocking')}[{i}]",
                                  f"must be an integer, got {b!r}")
            if b < 1:
                raise ConfigError(f"{name('move_blocking')}[{i}]",
                                  f"must be a positive block length, got {b}")
        if sum(move_blocking) != horizon:
            raise ConfigError(name("move_blocking"), f"the block lengths must sum to the "
                              f"horizon ({horizon}), got {sum(move_blocking)}")
        return tuple(move_blocking)
    return None


def is_blocked(blocks: tuple[int, ...] | None) -> bool:
    return blocks is not None and any(b != 1 for b in blocks)


def stage_block(blocks: tuple[int, ...]) -> np.ndarray:
    """(N,) the block that holds each stage."""
    return np.repeat(np.arange(len(blocks)), blocks).astype(np.int32)


def block_starts(blocks: tuple[int, ...]) -> np.ndarray:
    """(p,) the first stage of each block."""
    return np.concatenate(([0], np.cumsum(blocks)[:-1])).astype(np.int32)


def expansion(blocks: tuple[int, ...], nu: int) -> np.ndarray:
    """T (N nu x p nu, 0/1) with U = T U_b."""
    sb = stage_block(blocks)
    T = np.zeros((sb.size * nu, len(blocks) * nu))
    for t, j in enumerate(sb):
        T[t * nu:(t + 1) * nu, j * nu:(j + 1) * nu] = np.eye(nu)
    return T


def next_input_quantity(blocks: tuple[int, ...], nu: int) -> np.ndarray:
    """(p nu,) for the shifted warm start: the input of today's block j is guessed from
    yesterday's block holding stage s_j + 1 (s_j = its first stage; the last block maps to
    itself).  For blocks of one stage that is block j + 1, as without blocking; a longer
    block keeps its own bound (most of its stages were in it yesterday).  Only a guess:
    the polish verifies every working set."""
    sb, starts = stage_block(blocks), block_starts(blocks)
    later = sb[np.minimum(starts + 1, sb.size - 1)]
    return (later[:, None] * nu + np.arange(nu)[None, :]).reshape(-1).astype(np.int32)
