"""Mirror of ``templates/solver/hq.c.j2`` (and ``s_at()`` of ``dot.c.j2``).

The C reads the dual Hessian H = M E^-1 M' through the quantity Hessian Hq and never
stores it: element by element (``hq()``, ``h_rows()``), or, for the polish's and the dual
active set's H_Wp, a column at a time (``h_column()``: ``einv_column()``,
``hq_input_column()``, ``h_from_column()``), which forms every element by ``hq()``'s
operations.  The reference tabulates the same elements once per mode, each formed by the
same operations in the same order, so every read agrees bit for bit either way.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..qp.storage import ModeData, unpack_lower


class HessianReads(NamedTuple):
    """Every element the C reads, tabulated in the storage dtype."""
    Sinv: np.ndarray   # S^-1, unpacked from Sinv_p (primal_solve_bound())
    S: np.ndarray      # S, unpacked from S_p (s_at())
    H: np.ndarray      # H_rs for rows r, s (h_rows())
    Hdiag: np.ndarray  # H_rr


def hessian_reads(md: ModeData) -> HessianReads:
    """The tables of one mode, Hq's blocks assembled exactly as ``hq()`` forms them."""
    n, nyq = md.n, md.n_yq
    # E^-1 exactly as hq() forms it: S^-1(a, b) - sum_o Ew[o, a] Ew[o, b]
    acc = np.zeros((n, n), md.Kx.dtype)
    for o in range(md.nt):
        acc = acc + np.outer(md.Ew[o], md.Ew[o])
    Sinv = unpack_lower(md.Sinv_p, n)
    Einv = Sinv - acc
    GEG = (unpack_lower(md.GEinvGt_p, nyq) if md.has_output_rows
           else np.zeros((nyq, nyq), md.Kx.dtype))
    Hq = np.block([[Einv, md.EinvGt], [md.EinvGt.T, GEG]])
    if md.has_rate_rows:
        Hq = _rate_extended(Hq, n, md.nu)
    if md.has_signal_rows:
        Hq = _signal_extended(Hq, md)
    q, sg = md.row_q, md.row_sign
    same = sg[:, None] == sg[None, :]
    Hrows = Hq[np.ix_(q, q)]
    return HessianReads(Sinv=Sinv, S=unpack_lower(md.S_p, n),
                        H=np.where(same, Hrows, -Hrows), Hdiag=Hq[q, q])


def _rate_extended(Hq: np.ndarray, n: int, nu: int) -> np.ndarray:
    """Hq with the n Δu quantities D_i = U_i - U_{i-nu} (D_i = U_i at stage 0) appended on
    both sides, exactly as hq() forms them: columns first (hq_side()), then rows."""
    def diff(M, axis):
        base = np.take(M, np.arange(n), axis=axis)
        prev = np.take(M, np.arange(n - nu), axis=axis)
        tail = np.take(base, np.arange(nu, n), axis=axis) - prev
        return np.concatenate((np.take(base, np.arange(nu), axis=axis), tail), axis=axis)
    X = np.hstack((Hq, diff(Hq, 1)))
    return np.vstack((X, diff(X, 0)))


def _signal_extended(Hq: np.ndarray, md: ModeData) -> np.ndarray:
    """Hq with the signal quantities from z0 = 2 n + nyq on (a gap where a mode without Δu
    rows has no Δu quantities), exactly as hq_signal() reads them: E^-1 Gz' against the
    inputs (a Δu quantity as a difference of two), G E^-1 Gz' against the outputs, and
    Gz E^-1 Gz'."""
    n, nyq, nu, dt = md.n, md.n_yq, md.nu, md.Kx.dtype
    z0 = 2 * n + nyq
    base = np.zeros((z0, z0), dt)
    base[:Hq.shape[0], :Hq.shape[1]] = Hq
    cross = np.zeros((z0, md.nzq), dt)
    cross[:n] = md.EinvZt
    if md.GEinvZt is not None:
        cross[n:n + nyq] = md.GEinvZt
    if md.has_rate_rows:  # D_d = U_d - U_(d-nu), or U_d in the first stage
        cross[n + nyq:n + nyq + nu] = md.EinvZt[:nu]
        cross[n + nyq + nu:] = md.EinvZt[nu:] - md.EinvZt[:n - nu]
    ZZ = unpack_lower(md.ZEinvZt_p, md.nzq)
    return np.block([[base, cross], [cross.T, ZZ]])
