"""General linear constraints: every row on a *signal*, a linear combination of the
predicted state and input at one time (``modes[].constraints``, docs/features.md,
"General constraints").

A scalar signal on the prediction model is ``z_k = Cz x_k + Dz u_k + Rz r_k`` (Rz: the
reference a terminal set follows, :mod:`.terminal_set`).  Its rows bound it at the times
``first..last``; over the horizon

    z_k = Cz A^k x + Rz r_k + sum_{t <= s} m[s - t] u_t,

with s = k - 1 and ``m[l] = Cz A^l B`` without an input term (times 1..N), or s = k and
``m[0] = Dz``, ``m[l] = Cz A^(l-1) B`` with one (times 0..N-1).  So each signal has Markov
parameters like an output, and a row at stage s reads the last (s + 1) nu of them against
the first inputs, as ``predict_outputs()`` does (the C's ``predict_signals()``).

The rows are the fourth row kind (:data:`..qp.rows.SIGNAL`), one *quantity* per (signal,
time), in time order, each with a lower and an upper row where that bound is finite.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.plant import DiscretePlant
from . import move_blocking


@dataclass(frozen=True, eq=False)
class ModelSignal:
    """A scalar signal on the prediction model's state (plant, disturbance, u_prev)."""

    name: str
    key: str  # the config key it came from
    source: str  # "signals" | "mixed" | "terminal"
    Cz: np.ndarray  # (nx,)
    Dz: np.ndarray  # (nu,)
    Rz: np.ndarray | None  # (ny,): the reference term (terminal sets); None = 0
    lo: float
    hi: float
    first: int
    last: int
    soft_l1: np.ndarray  # (2,) lo side, hi side
    soft_l2: np.ndarray

    @property
    def feedthrough(self) -> bool:
        return bool(np.any(self.Dz))

    def stage(self, k: int) -> int:
        """The Markov stage of time k (the inputs u_0..u_stage reach z_k)."""
        return k if self.feedthrough else k - 1


def on_model(sig, plant: DiscretePlant, nu: int) -> ModelSignal:
    """A config :class:`~..config.schema.SignalConstraint` on the prediction model: its C
    on the plant's states first, 0 on the disturbance and previous-input states."""
    Cz = np.zeros(plant.nx)
    Cz[:sig.C.size] = sig.C
    Dz = np.zeros(nu)
    Dz[:sig.D.size] = sig.D
    return ModelSignal(name=sig.name, key=sig.key, source=sig.source, Cz=Cz, Dz=Dz, Rz=None,
                       lo=sig.lo, hi=sig.hi, first=sig.first, last=sig.last,
                       soft_l1=sig.soft_l1, soft_l2=sig.soft_l2)


def signal_markov(sig: ModelSignal, plant: DiscretePlant, N: int) -> np.ndarray:
    """(N, nu): m[l], the coefficient of u_(s - l) in z at stage s."""
    m = np.zeros((N, plant.nu))
    row = sig.Cz.copy()  # Cz A^j
    start = 0
    if sig.feedthrough:
        m[0], start = sig.Dz, 1
    for lag in range(start, N):
        m[lag] = row @ plant.B
        row = row @ plant.A
    return m


@dataclass(frozen=True)
class SignalBlock:
    """The signal quantities of one mode and their rows (appended to eq. (6)'s)."""

    signals: tuple[ModelSignal, ...]
    sig: np.ndarray  # (nzq,) signal of each quantity
    stage: np.ndarray  # (nzq,) its Markov stage
    time: np.ndarray  # (nzq,) its time k
    markov: np.ndarray  # (nsig, N, nu)
    Zx: np.ndarray  # (nzq, nx) free response Cz A^k
    Zr: np.ndarray  # (nzq, ny) reference term (zeros without one)
    Gz: np.ndarray  # (nzq, n) z = Gz U + Zx x + Zr r_k (U blocked with move blocking)
    # the rows: sign * z <= c + W x + Wr R, on quantity `index`
    L: np.ndarray
    W: np.ndarray
    Wr: np.ndarray  # (rows, N ny)
    c: np.ndarray
    index: np.ndarray
    sign: np.ndarray
    l1: np.ndarray
    l2: np.ndarray

    @property
    def nzq(self) -> int:
        return self.sig.size

    @property
    def has_reference(self) -> bool:
        return bool(np.any(self.Zr))


def signal_block(signals: tuple[ModelSignal, ...], plant: DiscretePlant, N: int, ny: int,
                 blocks: tuple[int, ...] | None) -> SignalBlock:
    """The quantities (time by time, signal by signal) and rows of ``signals``."""
    nx, nu = plant.nx, plant.nu
    markov = np.array([signal_markov(s, plant, N) for s in signals]).reshape(len(signals), N, nu)
    powers = [np.eye(nx)]
    for _ in range(N):
        powers.append(powers[-1] @ plant.A)
    quantities = sorted((k, j) for j, s in enumerate(signals) for k in range(s.first, s.last + 1))
    sig = np.array([j for _, j in quantities], dtype=np.int32)
    time = np.array([k for k, _ in quantities], dtype=np.int32)
    stage = np.array([signals[j].stage(k) for k, j in quantities], dtype=np.int32)
    Zx = np.array([signals[j].Cz @ powers[k] for k, j in quantities]).reshape(len(quantities), nx)
    Zr = np.array([np.zeros(ny) if signals[j].Rz is None else signals[j].Rz
                   for _, j in quantities]).reshape(len(quantities), ny)
    G = np.zeros((len(quantities), N * nu))
    for q, (j, s) in enumerate(zip(sig, stage)):
        for t in range(s + 1):
            G[q, t * nu:(t + 1) * nu] = markov[j, s - t]
    if blocks is not None:
        G = G @ move_blocking.expansion(blocks, nu)
    rows = _rows(signals, sig, time, G, Zx, Zr, N, ny)
    return SignalBlock(signals=signals, sig=sig, stage=stage, time=time, markov=markov,
                       Zx=Zx, Zr=Zr, Gz=G, **rows)


def _rows(signals, sig, time, G, Zx, Zr, N: int, ny: int) -> dict:
    """Per quantity a lower row -z <= -lo + Zx x + Zr r_k and an upper row
    z <= hi - Zx x - Zr r_k, where that bound is finite."""
    L, W, Wr, c, index, sign, l1, l2 = [], [], [], [], [], [], [], []
    for q, (j, k) in enumerate(zip(sig, time)):
        s = signals[j]
        for side, (sg, bound) in enumerate(((-1, s.lo), (1, s.hi))):
            if not np.isfinite(bound):
                continue
            wr = np.zeros(N * ny)
            if k >= 1:  # r_k is the preview's entry k - 1
                wr[(k - 1) * ny:k * ny] = -sg * Zr[q]
            L.append(sg * G[q])
            W.append(-sg * Zx[q])
            Wr.append(wr)
            c.append(sg * bound)
            index.append(q)
            sign.append(sg)
            l1.append(s.soft_l1[side])
            l2.append(s.soft_l2[side])
    n, nx = G.shape[1], Zx.shape[1]
    return {"L": np.array(L).reshape(len(L), n), "W": np.array(W).reshape(len(W), nx),
            "Wr": np.array(Wr).reshape(len(Wr), N * ny), "c": np.array(c),
            "index": np.array(index, dtype=np.int32), "sign": np.array(sign, dtype=np.int32),
            "l1": np.array(l1, dtype=float), "l2": np.array(l2, dtype=float)}


def lag_descending(markov: np.ndarray) -> np.ndarray:
    """(nsig, N nu): each signal's Markov parameters, the longest lag first, so that a
    quantity at stage s reads its row's last (s + 1) nu entries against th's first ones
    (as ``markov_by_output``)."""
    nsig, N, nu = markov.shape
    return np.ascontiguousarray(markov[:, ::-1, :].reshape(nsig, N * nu))


def prediction_bound(block: SignalBlock, stored_markov: np.ndarray, N: int, nu: int,
                     eps: float) -> np.ndarray:
    """b_j with |z_j - Zx_j x - Zr_j r| = |(Gz th)_j| <= b_j max|th| for the stored (rounded)
    Markov parameters, inflated for the rounding of the on-line sum and of b_j max|th|
    (as the outputs' out_bound: qp/storage.output_bound)."""
    absm = np.abs(stored_markov.astype(np.float64))  # (nsig, N nu), lags descending
    width = (block.stage + 1) * nu
    b = np.array([absm[j, N * nu - w:].sum() for j, w in zip(block.sig, width)])
    return b * (1.0 + 8.0 * N * max(nu, 1) * eps)


def next_signal_rows(block: SignalBlock, first_row: int) -> np.ndarray:
    """For the shifted warm start: each signal row's row at the next time (a row without
    one maps to itself), the block's rows numbered from ``first_row``."""
    where = {(int(block.sig[q]), int(block.time[q]), int(s)): first_row + i
             for i, (q, s) in enumerate(zip(block.index, block.sign))}
    return np.array([where.get((int(block.sig[q]), int(block.time[q]) + 1, int(s)),
                               first_row + i)
                     for i, (q, s) in enumerate(zip(block.index, block.sign))], dtype=np.int32)
