"""The stored arrays of a mode's signal quantities (general constraints,
features/signals.py), beside :mod:`.storage`'s: the Markov parameters, free response and
reference term of each quantity, and its blocks of the quantity Hessian Hq
(E^-1 Gz', Gz E^-1 Gz' packed, and Gamma E^-1 Gz' beside output rows), cast once."""
from __future__ import annotations

import numpy as np

from ..features import signals as signal_rows
from ..features import soft_constraints
from .condense import CondensedQP, solve_refined
from .packed import packed_lower


def signal_storage(qp: CondensedQP, EinvGt: np.ndarray | None, cast, dt) -> dict:
    """The signal block's stored arrays (features/signals.py): its Markov parameters, free
    response and reference term, and its Hq blocks E^-1 Gz', Gz E^-1 Gz' (packed) and,
    beside output rows, Gamma E^-1 Gz'."""
    block, N, nu = qp.signals, qp.N, qp.nu
    EinvZt = solve_refined(qp.E, block.Gz.T)
    ZEZ = (block.Gz.astype(np.longdouble) @ EinvZt.astype(np.longdouble)).astype(np.float64)
    markov = cast(signal_rows.lag_descending(block.markov))
    soft = np.array([[s.soft_l1, s.soft_l2] for s in block.signals])  # (nsig, 2, 2)
    out = {"nzq": block.nzq, "nsig": len(block.signals),
           "nsig_live": sum(s.source != "terminal" for s in block.signals),
           "z_pred_ops": int(np.sum((block.stage + 1) * nu)),
           "z_markov": markov, "z_sig": block.sig.astype(np.int32),
           "z_stage": block.stage.astype(np.int32), "Zx": cast(block.Zx),
           "EinvZt": cast(EinvZt), "ZEinvZt_p": cast(packed_lower(0.5 * (ZEZ + ZEZ.T))),
           "z_bound": cast(signal_rows.prediction_bound(block, markov, N, nu,
                                                        float(np.finfo(dt).eps)))}
    if block.has_reference:
        out["Zr"] = cast(block.Zr)
    if EinvGt is not None:
        out["GEinvZt"] = cast((qp.Gamma.astype(np.longdouble) @ EinvZt.astype(np.longdouble))
                              .astype(np.float64))
    if np.any(soft[:, 1] > 0):
        l1, w = soft_constraints.storage(soft[:, 0], soft[:, 1])
        out["z_soft_l1"], out["z_soft_w"] = cast(l1), cast(w)
    return out
