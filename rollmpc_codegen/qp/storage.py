"""Stage 5: the structured QP data the C stores, cast once to the storage precision.

The dual Hessian H = M E^-1 M' is never stored densely (1.28 MB per mode in double for
the paper's problem).  Every constraint row r is ``sign_r * a(q_r)' U`` for a *quantity*
q_r: an input U_i (box rows, q in [0, n)) or a predicted output (Gamma U)_k
(output rows, q = n + k).  Hence ``H_rs = sign_r sign_s Hq[q_r, q_s]`` with

    Hq = [[E^-1,         E^-1 Gamma'       ],
          [Gamma E^-1,   Gamma E^-1 Gamma' ]]

stored as E^-1 Gamma' (dense), Gamma E^-1 Gamma' (packed lower, only when output rows
exist) and E^-1 itself in Woodbury form (below).  The L/D/U split of the paper is
implicit: D = diag(H), U = L' by symmetry.

The primal polish never touches E itself: with a heavy terminal weight (P2 = 1e9) the
float entries of E (~3e5) cannot also carry its stage part (~20).  E is kept split as
``E = S + V' (2P) V``: S = 2(Psi + Gamma_s' Omega_s Gamma_s) over the stages 1..N-1
(well conditioned), V = the terminal rows of Gamma, and (2P)^-1, so the polish solves
the augmented system [S_FF V_F'; V_F -(2P)^-1] with a small Schur complement.  When P
is not positive definite, the terminal term stays inside S and V is empty.

With S^-1 (packed), Uv = V S^-1 and T = (2P)^-1 + V S^-1 V', Woodbury gives
``E^-1 = S^-1 - Ew' Ew`` with ``Ew = chol(T)^-1 Uv`` (nt x n): E^-1 costs no storage of its
own, and when few inputs are bound the polish solves with S^-1_BB instead of S_FF.

The unconstrained solution uses ``theta0 = Kx x + (E^-1 Gamma') w`` with ``w = 2 Omega R``
(``Kr = E^-1 F = (E^-1 Gamma')(2 Omega)``, so the reference gain needs no storage of its own).
A held reference makes w constant over the stages 0..N-2, so the C sums the columns of
E^-1 Gamma' per run of equal w and takes the longest run from the precomputed column sum
``colsum`` (one n-vector per output): n (nx + ny) operations instead of n (nx + N ny).

Δu rows (``modes[].bounds.du_min/du_max``, row kind 2 of :func:`.mpc.condense`) are on the
quantity D_i = U_i - U_{i-nu} (D_i = U_i at stage 0, whose u_prev is in the right-hand
side), numbered q = n + N ny + i.  Their Hq entries are differences of the ones above,
``Hq(D_a, b) = Hq(a, b) - Hq(a - nu, b)`` (on either side), so they need no data.

``out_bound`` (one value per predicted output) bounds ``|(Gamma th)_k| <= out_bound_k
max_i |th_i|``; when that certifies every output row, the C skips the N^2/2 prediction.
``row_next`` maps each row to the same constraint one stage later, for the shifted warm start.

With move blocking (:mod:`..features.move_blocking`) n = p nu (one input vector per block) and
Gamma is the blocked Gamma T; ``stage_block`` tells the C's prediction which block holds
each stage, ``row_next`` maps an input row to the block holding its first stage + 1, and
``out_bound`` stays that of the stage Markov parameters (sound, see move_blocking).

Both the renderer and the NumPy reference read these arrays, so the numbers the C is
compiled with and the numbers the reference computes with are the same by construction.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..features import move_blocking, soft_constraints
from ..features import signals as signal_rows
from .packed import packed_lower, unpack_lower  # noqa: F401  (storage.unpack_lower: callers)
from .signal_storage import signal_storage
from .arrays import STORED_ARRAYS
from .condense import CondensedQP, solve_refined
from .rows import OUTPUT, SIGNAL, is_predicted, kind_of_quantity, quantities
from ..model.plant import DiscretePlant


def dtype_of(precision: str):
    return np.float64 if precision == "double" else np.float32


@dataclass(frozen=True)
class ModeData:
    """One mode's arrays exactly as the C stores them (dtype = storage precision).

    The shape, C type and meaning of each stored array are declared once, in
    :data:`.arrays.STORED_ARRAYS`; construction checks every shape against it.
    """

    name: str
    nx: int
    nu: int
    ny: int
    N: int
    n: int  # decision variables
    m: int  # constraint rows
    n_yq: int  # output quantities N*ny
    actuator_index: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    L: np.ndarray
    innovation_limit: np.ndarray
    Kx: np.ndarray
    EinvGt: np.ndarray
    Sinv_p: np.ndarray
    Ew: np.ndarray
    Uv: np.ndarray
    T: np.ndarray
    S_p: np.ndarray
    V: np.ndarray
    P2inv: np.ndarray
    GEinvGt_p: np.ndarray  # empty without output rows
    Omega2: np.ndarray
    Phi: np.ndarray
    markov_by_output: np.ndarray
    row_q: np.ndarray
    row_sign: np.ndarray
    row_c: np.ndarray
    row_next: np.ndarray
    colsum: np.ndarray
    out_bound: np.ndarray
    u_min: np.ndarray
    u_max: np.ndarray
    stage_block: np.ndarray | None = None  # None: unblocked
    soft_l1: np.ndarray | None = None  # None: without soft bounds
    soft_w: np.ndarray | None = None
    w_cap: int = 0  # working-set capacity: n, plus the soft (output, stage) pairs
    # general constraints (features/signals.py): the signal quantities; 0 / None without
    nzq: int = 0  # (signal, time) quantities
    nsig: int = 0  # scalar signals
    nsig_live: int = 0  # the first of them, those of constraints.signals and .mixed
    z_pred_ops: int = 0  # multiply-adds of predict_signals()
    z_markov: np.ndarray | None = None
    z_sig: np.ndarray | None = None
    z_stage: np.ndarray | None = None
    Zx: np.ndarray | None = None
    Zr: np.ndarray | None = None
    EinvZt: np.ndarray | None = None
    ZEinvZt_p: np.ndarray | None = None
    GEinvZt: np.ndarray | None = None
    z_bound: np.ndarray | None = None
    z_soft_l1: np.ndarray | None = None
    z_soft_w: np.ndarray | None = None

    def __post_init__(self):
        for array in STORED_ARRAYS:
            value = getattr(self, array.name)
            if value is not None and array.exists_in(self) and value.shape != array.shape(self):
                raise ValueError(f"{self.name}.{array.name} has shape {value.shape}, "
                                 f"declared {array.shape(self)}")

    @property
    def nt(self) -> int:
        return self.V.shape[0]

    @property
    def row_kinds(self) -> np.ndarray:
        """The RowKind code of every row (qp/rows.py), from its quantity."""
        return kind_of_quantity(self.row_q, self.n, self.n_yq)

    @property
    def output_rows(self) -> np.ndarray:
        """Which rows bound an output quantity (n <= q < n + nyq)."""
        return self.row_kinds == OUTPUT.code

    @property
    def signal_rows(self) -> np.ndarray:
        """Which rows bound a signal quantity (q >= 2 n + nyq)."""
        return self.row_kinds == SIGNAL.code

    @property
    def predicted_rows(self) -> np.ndarray:
        """Rows whose quantity the C predicts on line (output and signal rows)."""
        return is_predicted(self.row_kinds)

    @property
    def has_signal_rows(self) -> bool:
        return self.nzq > 0

    @property
    def has_signal_reference(self) -> bool:
        """Some signal row follows the reference (a terminal set: Zr)."""
        return self.Zr is not None

    @property
    def has_output_and_signal_rows(self) -> bool:
        return self.has_output_rows and self.has_signal_rows

    @property
    def has_soft_signal_rows(self) -> bool:
        return self.z_soft_w is not None

    @property
    def has_output_rows(self) -> bool:
        return bool(np.any(self.output_rows))

    @cached_property
    def _predicted(self) -> tuple[np.ndarray, int]:
        """(pred_out, ny_pred): the outputs predict_outputs() computes, ascending, then the
        others, and their count. Those with constraint rows: an output that is tracked
        but never bounded (a yaw, a climb rate) costs nothing in the prediction, whose
        dot product per output would cost as much for it (until da87413 the prediction
        spread each input over every output, and predicted all of them once more than
        two thirds had rows)."""
        rows = np.unique((self.row_q[self.output_rows] - self.n) % self.ny)
        count = int(rows.size)
        if count == self.ny:
            return np.arange(self.ny, dtype=np.int32), count
        rest = np.setdiff1d(np.arange(self.ny), rows)
        return np.concatenate((rows, rest)).astype(np.int32), count

    @property
    def pred_out(self) -> np.ndarray:
        return self._predicted[0]

    @property
    def ny_pred(self) -> int:
        return self._predicted[1]

    @property
    def scan_rows(self) -> np.ndarray:
        """The rows by kind, for violated_kind(): the rows that are not predicted (input
        and Δu bounds), ascending, then the predicted ones (output and signal rows),
        ascending. A scan of one kind then reads only its own rows, in the order a scan
        of every row meets them."""
        pred = self.predicted_rows
        return np.concatenate((np.flatnonzero(~pred), np.flatnonzero(pred))).astype(np.int32)

    @property
    def m_box(self) -> int:
        """The rows that are not predicted: the first m_box of scan_rows."""
        return int(np.count_nonzero(~self.predicted_rows))

    def soft_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """(l1, w) of every row, as the C's soft_of() reads them (0 for hard rows)."""
        l1, w = np.zeros(self.m, self.Kx.dtype), np.zeros(self.m, self.Kx.dtype)
        side = (self.row_sign > 0).astype(int)
        if self.soft_w is not None:
            out = self.output_rows
            idx = 2 * ((self.row_q[out] - self.n) % self.ny) + side[out]
            l1[out], w[out] = self.soft_l1[idx], self.soft_w[idx]
        if self.z_soft_w is not None:
            sig = self.signal_rows
            idx = 2 * self.z_sig[self.row_q[sig] - SIGNAL.base(self.n, self.n_yq)] + side[sig]
            l1[sig], w[sig] = self.z_soft_l1[idx], self.z_soft_w[idx]
        return l1, w

    @property
    def has_soft_rows(self) -> bool:
        """Some output row is soft (soft_constraints)."""
        return bool(np.any(self.soft_rows()[1] > 0))

    @property
    def has_rate_rows(self) -> bool:
        """Δu rows (quantities n + N ny + i, see the module docstring)."""
        return bool(np.any(self.row_q >= self.n + self.n_yq))


def mode_data(name: str, actuator_index, plant: DiscretePlant, obs_gain: np.ndarray,
              innovation_limit: np.ndarray, qp: CondensedQP, u_min, u_max, precision: str,
              soft_l1=None, soft_l2=None) -> ModeData:
    """The mode's stored arrays; soft_l1/soft_l2: the config's (ny, 2) soft penalties.
    An innovation limit of +inf (never clip) is stored as the largest finite number, so
    the data stays finite and only an innovation that overflowed is clipped."""
    dt = dtype_of(precision)
    N, ny, nu = qp.N, qp.ny, qp.nu
    EinvGt = solve_refined(qp.E, qp.Gamma.T)  # full double accuracy (see solve_refined)
    has_out = bool(np.any(qp.row_kind == OUTPUT.code))
    GEinvGt = ((qp.Gamma.astype(np.longdouble) @ EinvGt.astype(np.longdouble))
               .astype(np.float64) if has_out else np.zeros((0, 0)))
    GEinvGt = 0.5 * (GEinvGt + GEinvGt.T)
    Omega2 = np.array([2.0 * qp.Omega[i * ny:(i + 1) * ny, i * ny:(i + 1) * ny]
                       for i in range(N)])
    S, V, P2inv = qp.terminal_split()
    Sinv = solve_refined(S, np.eye(qp.n))
    Sinv = 0.5 * (Sinv + Sinv.T)
    Uv = solve_refined(S, V.T).T if V.shape[0] else np.zeros((0, qp.n))
    T = P2inv + V @ Uv.T
    T = 0.5 * (T + T.T)
    Ew = (np.linalg.solve(np.linalg.cholesky(T), Uv) if V.shape[0]
          else np.zeros((0, qp.n)))
    row_q = quantities(qp.row_kind, qp.row_index, qp.n, N * ny)
    colsum = (EinvGt.astype(np.longdouble)[:, :(N - 1) * ny].reshape(qp.n, N - 1, ny)
              .sum(axis=1).T.astype(np.float64))

    def cast(a):
        return np.ascontiguousarray(np.asarray(a, dtype=np.float64).astype(dt))

    markov = cast(qp.markov)  # (N, ny, nu)
    soft = {"w_cap": qp.n if qp.soft_l2 is None else soft_constraints.working_set_cap(
        qp.n, qp.row_kind, qp.row_index, qp.soft_l2)}
    if soft_l2 is not None:
        l1, w = soft_constraints.storage(soft_l1, soft_l2)
        soft |= {"soft_l1": cast(l1), "soft_w": cast(w)}
    next_rows = next_stage_rows(row_q, qp.row_sign, qp.n, nu, ny, N * ny, qp.blocks)
    signal = {}
    if qp.signals is not None:
        signal = signal_storage(qp, EinvGt if has_out else None, cast, dt)
        first = int(np.flatnonzero(qp.row_kind == SIGNAL.code)[0])
        next_rows[first:] = signal_rows.next_signal_rows(qp.signals, first)
    # a row's next-stage row never comes before it: carry_factor() shifts lam in place
    assert np.all(next_rows >= np.arange(next_rows.size)), "row_next maps a row backwards"
    return ModeData(**soft, **signal,
        name=name, nx=qp.nx, nu=nu, ny=ny, N=N, n=qp.n, m=qp.m, n_yq=N * ny,
        actuator_index=np.asarray(actuator_index, dtype=np.int32),
        A=cast(plant.A), B=cast(plant.B), C=cast(plant.C), L=cast(obs_gain),
        innovation_limit=cast(np.minimum(innovation_limit, np.finfo(dt).max)),
        Kx=cast(qp.Kx), EinvGt=cast(EinvGt), Sinv_p=cast(packed_lower(Sinv)), Ew=cast(Ew),
        Uv=cast(Uv), T=cast(T), S_p=cast(packed_lower(S)), V=cast(V), P2inv=cast(P2inv),
        GEinvGt_p=cast(packed_lower(GEinvGt)), Omega2=cast(Omega2), Phi=cast(qp.Phi),
        markov_by_output=markov_by_output(markov), row_q=row_q,
        row_sign=qp.row_sign.astype(np.int32), row_c=cast(qp.c),
        row_next=next_rows,
        colsum=cast(colsum), out_bound=cast(output_bound(markov, dt)),
        u_min=cast(u_min), u_max=cast(u_max),
        stage_block=None if qp.blocks is None else move_blocking.stage_block(qp.blocks))


def next_stage_rows(row_q: np.ndarray, row_sign: np.ndarray, n: int, nu: int,
                    ny: int, nyq: int, blocks: tuple[int, ...] | None = None) -> np.ndarray:
    """Row of the same constraint one stage later (a row of the last stage maps to itself);
    with move blocking an input row maps to move_blocking.next_input_quantity's block."""
    where = {(int(q), int(s)): r for r, (q, s) in enumerate(zip(row_q, row_sign))}
    later = None if blocks is None else move_blocking.next_input_quantity(blocks, nu)
    out = np.empty(row_q.size, dtype=np.int32)
    for r, (q, s) in enumerate(zip(row_q, row_sign)):
        # each kind stays in its own range: input rows [0, n), output rows [n, n + nyq),
        # Δu rows [n + nyq, 2n + nyq); a last-stage row maps to itself
        if q < n and later is not None:
            out[r] = where.get((int(later[q]), int(s)), r)
            continue
        step, end = (nu, n) if q < n else ((ny, n + nyq) if q < n + nyq
                                           else (nu, 2 * n + nyq))
        nxt = int(q) + step
        out[r] = where.get((nxt, int(s)), r) if nxt < end else r
    return out


def markov_by_output(markov: np.ndarray) -> np.ndarray:
    """The (N, ny, nu) Markov parameters as predict_outputs() reads them: one row per
    output, lags descending, so each output's sum over the inputs (t, b) in order is one
    contiguous dot product with th."""
    N, ny, nu = markov.shape
    return np.ascontiguousarray(markov[::-1].transpose(1, 0, 2).reshape(ny, N * nu))


def output_bound(markov: np.ndarray, dt) -> np.ndarray:
    """g_k with |(Gamma th)_k| <= g_k max|th| for the stored (rounded) Markov parameters.

    g_k = sum of |C A^l B| over the lags of output k's row of Gamma, inflated by
    (1 + 8 N eps) so that the on-line product g_k * max|th| (one rounding) and the
    rounding of the exact prediction (N ny nu terms) cannot defeat the certificate.
    """
    N, ny, nu = markov.shape
    per_lag = np.abs(markov.astype(np.float64)).sum(axis=2)  # (N, ny)
    g = np.cumsum(per_lag, axis=0).reshape(N * ny)
    eps = float(np.finfo(dt).eps)
    return g * (1.0 + 8.0 * N * max(nu, 1) * eps)
