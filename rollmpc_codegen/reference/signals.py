"""Mirror of ``templates/solver/signals.c.j2``: the signal row kind's free response and
prediction (its Hq reads, ``hq_signal()``, are tabulated by :func:`.hq.hessian_reads`).

:class:`SignalsMixin` is part of :class:`~.solver.SolverRef`; it reads ``md`` and
``expand`` (the move-blocking map of :func:`.unconstrained.output_prediction`).

The reference keeps every predicted quantity in one vector, the outputs (Gamma th, nyq)
then the signals (Gz th, nzq): :func:`predicted_index` maps a row's quantity into it.
"""
from __future__ import annotations

import numpy as np

from ..qp.rows import OUTPUT, SIGNAL
from ..qp.storage import ModeData
from ..qp.work import free_response_work
from .linalg import seqsum, seqsum_rows


def predicted_index(md: ModeData, q: np.ndarray) -> np.ndarray:
    """The position of quantity q (an output or a signal) in the predicted vector
    [outputs; signals]; clipped into it for the quantities that are neither."""
    z0 = SIGNAL.base(md.n, md.n_yq)
    at = np.where(q >= z0, md.n_yq + q - z0, q - OUTPUT.base(md.n, md.n_yq))
    return np.clip(at, 0, md.n_yq + md.nzq - 1)


class SignalsMixin:
    def signal_free_response(self, x, r):
        """Mirror of signal_free_response(): Zx x, plus Zr r_k (r_k at the quantity's time)."""
        md = self.md
        pz = seqsum_rows(md.Zx * x[None, :])
        self.work += free_response_work(md)
        if md.Zr is not None:
            rk = r.reshape(md.N, md.ny)[md.z_stage]  # r_k, k = stage + 1
            pz = np.array([seqsum(np.concatenate(([pz[j]], md.Zr[j] * rk[j])))
                           for j in range(md.nzq)], md.Kx.dtype).reshape(md.nzq)
        return pz

    def predict_signals(self, th):
        """Mirror of predict_signals(): Gz th, each quantity one sequential dot product of
        its signal's Markov row (from lag stage down) with th from stage 0."""
        md = self.md
        th = th if self.expand is None else th[self.expand]
        row_len = md.N * md.nu
        zv = np.zeros(md.nzq, md.Kx.dtype)
        for j in range(md.nzq):
            width = (int(md.z_stage[j]) + 1) * md.nu
            zv[j] = seqsum(md.z_markov[md.z_sig[j], row_len - width:] * th[:width])
        return zv
