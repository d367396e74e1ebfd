"""Mirror of ``templates/solver/unconstrained.c.j2``: th0 and the output prediction.

:class:`UnconstrainedMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``,
``has_out`` and the prediction data of :func:`output_prediction`.
"""
from __future__ import annotations

import numpy as np

from ..qp.storage import ModeData
from ..qp.work import unconstrained_work
from .linalg import seqsum, seqsum_rows


def output_prediction(md: ModeData) -> tuple[np.ndarray, np.ndarray | None]:
    """(Gamma over the stages, the input index of each stage's inputs or None): the data
    ``predict_outputs()`` reads, Gamma in the storage dtype with each row used only up to
    its nonzero prefix."""
    N, ny, nu, nyq = md.N, md.ny, md.nu, md.n_yq
    Gam = np.zeros((nyq, N * nu), md.Kx.dtype)  # over the stages (n with no blocks)
    # move blocking: the C reads th[stage_block[t] nu + b] for stage t (U = T th)
    expand = (None if md.stage_block is None else
              (md.stage_block[:, None] * nu + np.arange(nu)[None, :]).reshape(-1))
    for k in range(nyq):
        stage, a = divmod(k, ny)
        Gam[k, :(stage + 1) * nu] = md.markov_by_output[a, (N - 1 - stage) * nu:]
    return Gam, expand


class UnconstrainedMixin:
    def unconstrained(self, x, r):
        """Mirror of unconstrained(): (th0, the predicted rows' free response or None),
        th0 summed per run of equal w (reference_runs(), other_runs()). The free response
        is [Phi x; Zx x + Zr r] (signal_free_response(); zeros for the outputs of a mode
        with signal rows only)."""
        md, ny = self.md, self.md.ny
        rr = r.reshape(md.N, ny)
        w = np.empty(md.n_yq, md.Kx.dtype)
        for k in range(md.n_yq):
            stage, a = divmod(k, ny)
            w[k] = seqsum(md.Omega2[stage, a, :] * rr[stage])
        W = w.reshape(md.N, ny)
        last = md.N - 1
        runs, longest = self.reference_runs(W)
        summed = last - (runs[longest][1] - runs[longest][0] if runs else 0)
        self.work += unconstrained_work(md, summed, len(runs), self.has_out)
        G = md.EinvGt.reshape(md.n, md.N, ny)
        acc = seqsum_rows(md.Kx * x[None, :])
        for a in range(ny):
            acc, coef = self.other_runs(acc, G, W, a, runs, longest)
            if longest >= 0:
                acc = acc + W[runs[longest][0], a] * coef
            acc = acc + G[:, last, a] * W[last, a]
        px = seqsum_rows(md.Phi * x[None, :]) if self.has_out else None
        if md.has_signal_rows:
            px = np.concatenate((np.zeros(md.n_yq, md.Kx.dtype) if px is None else px,
                                 self.signal_free_response(x, r)))
        return acc, px

    @staticmethod
    def reference_runs(W):
        """Mirror of reference_runs(): the runs of equal w (rows of W by stage) over the
        stages 0..N-2 as (first stage, end stage) pairs, and the first longest (-1: none)."""
        last = W.shape[0] - 1
        starts = [st for st in range(last) if st == 0 or np.any(W[st] != W[st - 1])]
        runs = list(zip(starts, starts[1:] + [last]))
        lengths = [e - b for b, e in runs]
        return runs, (int(np.argmax(lengths)) if lengths else -1)

    def other_runs(self, acc, G, W, a, runs, longest):
        """Mirror of other_runs() for output a: (th0 so far plus w_j s_j over every run j but
        the longest, in run order; the longest run's column sums colsum_a - sum_j s_j),
        s_j the sums of E^-1 G' (``G``: by input, stage and output) over run j."""
        other = np.zeros(self.md.n, self.md.Kx.dtype)
        for j, (b, e) in enumerate(runs):
            if j != longest:
                s = seqsum_rows(G[:, b:e, a])
                acc = acc + W[b, a] * s
                other = other + s
        return acc, self.md.colsum[a] - other

    def predict_outputs(self, th):
        """Mirror of predict_outputs(): Gamma th (Gamma T th with move blocking) for the
        outputs with constraint rows (md.pred_out[:ny_pred]); the others 0; then, with
        signal rows, Gz th (predict_signals())."""
        md = self.md
        out = np.zeros(md.n_yq, md.Kx.dtype)
        full = th if self.expand is None else th[self.expand]
        predicted = np.isin(np.arange(md.n_yq) % md.ny, md.pred_out[:md.ny_pred])
        for k in np.flatnonzero(predicted):
            width = (k // md.ny + 1) * md.nu
            out[k] = seqsum(self.Gam[k, :width] * full[:width])
        if md.has_signal_rows:
            return np.concatenate((out, self.predict_signals(th)))
        return out
