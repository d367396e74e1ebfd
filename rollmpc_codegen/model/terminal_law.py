"""The LQR tracking law of a mode's prediction model, declared once: the gain of the
terminal set (features/terminal_set.py) and of ``simulate --baseline lqr``
(sim/lqr_baseline.py).

* **Gain**: infinite-horizon discrete LQR on every state but the disturbances (which no
  input moves), ``K = dlqr(A_k, B_k, C_k' Q C_k + reg, R + reg)``, with the config's stage
  weights Q (on the outputs) and R; the terminal output weight P has no role in an
  infinite-horizon design.  Where Q leaves a mode undetectable or R is singular, 1e-9 of
  the weights' scale on the diagonal makes the Riccati equation solvable.
* **Steady state**: for a constant reference r and disturbance estimate d,
  ``(A - I) x_s + B u_s + A_d d = 0``, ``C x_s + C_d d = r`` on the kept states (least
  squares when not square): ``[x_s; u_s] = M [r; d]``.
* **Law**: ``u = u_s + K (x_s - x)`` on the kept states (K as control.dlqr returns it:
  u = -K x regulates).
"""
from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np


@dataclass(frozen=True)
class TrackingLaw:
    K: np.ndarray  # (nu, nk) state feedback gain on the kept states (u = -K x regulates)
    keep: np.ndarray  # the state indices but the disturbance states'
    dist: np.ndarray  # the disturbance states' indices (empty without a model)
    Mx: np.ndarray  # (nk, ny + nd): x_s = Mx [r; d]
    Mu: np.ndarray  # (nu, ny + nd): u_s = Mu [r; d]

    def affine(self, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
        """(Kx, Kr) with u = Kx x + Kr r on the whole state x (the disturbance estimate
        x[dist] entering through the steady state)."""
        nu = self.K.shape[0]
        G = self.Mu + self.K @ self.Mx  # u = -K x_k + (Mu + K Mx) [r; d]
        Kx = np.zeros((nu, nx))
        Kx[:, self.keep] = -self.K
        Kx[:, self.dist] = G[:, ny:]
        return Kx, G[:, :ny]


def tracking_law(A: np.ndarray, B: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
                 dist: np.ndarray) -> TrackingLaw:
    """The law of the model (A, B, C) whose states ``dist`` are constant disturbances."""
    nx, nu, ny = A.shape[0], B.shape[1], C.shape[0]
    keep = np.setdiff1d(np.arange(nx), dist)
    Ak, Bk, Ck = A[np.ix_(keep, keep)], B[keep], C[:, keep]
    K = _dlqr(Ak, Bk, Ck.T @ Q @ Ck, R)
    nk = keep.size
    target = np.block([[Ak - np.eye(nk), Bk], [Ck, np.zeros((ny, nu))]])
    rhs = np.block([[np.zeros((nk, ny)), -A[np.ix_(keep, dist)]],
                    [np.eye(ny), -C[:, dist]]])
    M = np.linalg.pinv(target) @ rhs
    return TrackingLaw(K=K, keep=keep, dist=np.asarray(dist, int), Mx=M[:nk], Mu=M[nk:])


def _dlqr(A: np.ndarray, B: np.ndarray, Qx: np.ndarray, R: np.ndarray) -> np.ndarray:
    try:
        return np.asarray(control.dlqr(A, B, Qx, R)[0], float)
    except (ValueError, np.linalg.LinAlgError, control.ControlArgument):
        reg = 1e-9 * max(1.0, float(np.abs(Qx).max()), float(np.abs(R).max()))
        return np.asarray(control.dlqr(A, B, Qx + reg * np.eye(A.shape[0]),
                                       R + reg * np.eye(B.shape[1]))[0], float)
