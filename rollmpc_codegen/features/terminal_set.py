"""``modes[].constraints.terminal``: a constraint on the predicted state x_N.

It is written in deviation from the steady state x_s that holds the last stage's
reference r_N (with the disturbance estimate d of an offset-free model), so it follows
the reference: x_s = M [r_N; d] from :mod:`..model.terminal_law`.  Each facet is a signal
at time N (:mod:`.signals`) whose row carries r_N in its right-hand side (``Zr``).

* ``polytope``: ``H (x_N - x_s) <= h`` (H on the plant's states; h >= 0, so x_s is in it);
* ``equality``: ``x_N = x_s`` (a lower and an upper row per plant state);
* ``lqr_invariant``: the maximal admissible set of the terminal LQR law
  ``u = u_s + K (x_s - x)`` (the law of ``simulate --baseline lqr``): the states (and
  references) from which that law keeps every hard bound -- input, Δu, output and the
  constrained signals that hold to the end of the horizon -- at every future sample.
  Computed by the standard iteration (Gilbert and Tan 1991) on ``xi = (x, r)`` with r
  constant: the bound rows at k = 0, 1, ... steps ahead until the next step's rows are
  all redundant (one LP per row, scipy's HiGHS), the reference's steady state kept 1 %
  inside each bound so that the iteration ends; then the redundant rows are dropped.

With the set, the plan shifted one sample and finished by the terminal law is feasible
for the next sample whenever the last plan was (recursive feasibility): the terminal set
changes which plans are allowed, not the cost.  Soft bounds are left out of the set, and
so are its facets on the reference alone (the steady state's margin: no plan can meet
them), so a reference beyond 99 % of an output bound makes the set approximate, not
the QP infeasible.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from ..config.errors import ConfigError
from ..config.schema import ModeConfig
from ..model.plant import DiscretePlant
from ..model.terminal_law import tracking_law
from .signals import ModelSignal

STEADY_STATE_MARGIN = 0.01  # of each bound's span (or size, one-sided): Gilbert-Tan's
MAX_STEPS = 500  # steps ahead the iteration may look before it gives up
REDUNDANT_TOL = 1e-9  # relative: a row whose LP maximum is within it of its bound


def terminal_signals(mode: ModeConfig, plant: DiscretePlant, N: int, key: str
                     ) -> tuple[ModelSignal, ...]:
    """The terminal constraint's facets as signals at time N."""
    t = mode.terminal
    tkey = f"{key}.constraints.terminal"
    law = tracking_law(plant.A, plant.B, plant.C, mode.Q, mode.R, plant.disturbance_states)
    nx, ny = plant.nx, plant.ny
    if t.kind == "lqr_invariant":
        Hx, Hr, h = maximal_admissible_set(mode, plant, N, law, tkey)
        # a facet on the reference (and disturbance) alone is no row the plan can meet:
        # the steady state's margin, left out (a reference beyond it is not refused)
        on_plan = np.abs(Hx[:, law.keep]).max(axis=1, initial=0.0) > 1e-9
        Hx, Hr, h = Hx[on_plan], Hr[on_plan], h[on_plan]
        lo = np.full(h.size, -np.inf)
    else:
        nxp = nx - plant.nd - plant.n_prev  # the plant's states come first
        H = np.eye(nxp) if t.kind == "equality" else t.H
        h = np.zeros(nxp) if t.kind == "equality" else t.h
        lo = -h if t.kind == "equality" else np.full(h.size, -np.inf)
        Mx = law.Mx[:nxp]  # x_s of the plant's states (the kept states start with them)
        Hx = np.zeros((H.shape[0], nx))
        Hx[:, :nxp] = H
        Hx[:, law.dist] = -H @ Mx[:, ny:]
        Hr = -H @ Mx[:, :ny]
    soft = np.array([t.soft_l1, t.soft_l2], float)
    return tuple(ModelSignal(name=f"terminal[{i}]", key=tkey, source="terminal",
                             Cz=Hx[i], Dz=np.zeros(plant.nu), Rz=Hr[i], lo=float(lo[i]),
                             hi=float(h[i]), first=N, last=N,
                             soft_l1=soft[0] * np.isfinite([lo[i], h[i]]),
                             soft_l2=soft[1] * np.isfinite([lo[i], h[i]]))
                 for i in range(h.size))


def _bound_rows(mode: ModeConfig, plant: DiscretePlant, N: int, Kx, Kr):
    """(Y, lo, hi): the hard bounds under the law, as rows on xi = (x, r)."""
    nx, nu, ny = plant.nx, plant.nu, plant.ny
    rows, lo, hi = [np.hstack((Kx, Kr))], [mode.u_min], [mode.u_max]
    if plant.n_prev:  # Δu = u - u_prev, the last nu states
        prev = np.zeros((nu, nx))
        prev[:, nx - nu:] = np.eye(nu)
        rows.append(np.hstack((Kx - prev, Kr)))
        lo.append(mode.du_min if mode.du_min is not None else np.full(nu, -np.inf))
        hi.append(mode.du_max if mode.du_max is not None else np.full(nu, np.inf))
    soft = np.zeros((ny, 2)) if mode.soft_l2 is None else mode.soft_l2
    rows.append(np.hstack((plant.C, np.zeros((ny, ny)))))
    lo.append(np.where(soft[:, 0] > 0, -np.inf, mode.y_min))
    hi.append(np.where(soft[:, 1] > 0, np.inf, mode.y_max))
    for s in mode.signals:
        if s.last < (N - 1 if np.any(s.D) else N):
            continue  # a bound that stops before the horizon's end does not hold after it
        Cz = np.zeros(nx)
        Cz[:s.C.size] = s.C
        Dz = np.zeros(nu)
        Dz[:s.D.size] = s.D
        rows.append(np.hstack((Cz + Dz @ Kx, Dz @ Kr))[None, :])
        lo.append([-np.inf if s.soft_l2[0] > 0 else s.lo])
        hi.append([np.inf if s.soft_l2[1] > 0 else s.hi])
    Y, lo, hi = np.vstack(rows), np.concatenate(lo), np.concatenate(hi)
    keep = np.isfinite(lo) | np.isfinite(hi)
    return Y[keep], lo[keep], hi[keep]


def _one_sided(Y, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """a' xi <= b rows of lo <= Y xi <= hi, each scaled to a unit coefficient norm."""
    A = np.vstack((Y[np.isfinite(hi)], -Y[np.isfinite(lo)]))
    b = np.concatenate((hi[np.isfinite(hi)], -lo[np.isfinite(lo)]))
    norm = np.maximum(np.linalg.norm(A, axis=1), 1e-300)
    return A / norm[:, None], b / norm


def _tightened(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    span = np.where(np.isfinite(lo) & np.isfinite(hi), hi - lo,
                    np.where(np.isfinite(hi), np.abs(hi), np.abs(lo)))
    margin = STEADY_STATE_MARGIN * span
    return lo + margin, hi - margin


def _max(a, A, b) -> float:
    """max a' xi over A xi <= b (inf when unbounded, -inf when empty)."""
    res = linprog(-a, A_ub=A, b_ub=b, bounds=(None, None), method="highs")
    if res.status == 2:
        return -np.inf
    if res.status == 3:
        return np.inf
    return float(-res.fun)


def _redundant(a, bound, A, b) -> bool:
    return _max(a, A, b) <= bound + REDUNDANT_TOL * max(1.0, abs(bound))


def maximal_admissible_set(mode: ModeConfig, plant: DiscretePlant, N: int, law, key: str):
    """(Hx, Hr, h): Hx x + Hr r <= h, the maximal admissible set of the law."""
    nx, ny = plant.nx, plant.ny
    Kx, Kr = law.affine(nx, ny)
    Acl = np.block([[plant.A + plant.B @ Kx, plant.B @ Kr], [np.zeros((ny, nx)), np.eye(ny)]])
    Y, lo, hi = _bound_rows(mode, plant, N, Kx, Kr)
    # the steady state of xi = (x, r): x_k* = (I - Acl_kk)^-1 (Acl_kd d + B_k Kr r)
    keep, dist = law.keep, law.dist
    fixed = np.concatenate((dist, nx + np.arange(ny)))  # d and r stay as they are
    limit = np.zeros((nx + ny, nx + ny))
    limit[fixed, fixed] = 1.0
    Akk = Acl[np.ix_(keep, keep)]
    limit[np.ix_(keep, fixed)] = np.linalg.solve(np.eye(keep.size) - Akk, Acl[np.ix_(keep, fixed)])
    A_ss, b_ss = _one_sided(Y @ limit, *_tightened(lo, hi))
    A, b = _one_sided(Y, lo, hi)
    A, b = np.vstack((A_ss, A)), np.concatenate((b_ss, b))
    if _max(np.zeros(nx + ny), A, b) == -np.inf:
        raise ConfigError(key, "the terminal LQR keeps no state within the bounds (the set "
                          "is empty): check that the bounds contain the steady states")
    step = Y
    for k in range(1, MAX_STEPS + 1):
        step = step @ Acl
        new_A, new_b = _one_sided(step, lo, hi)
        if all(_redundant(a, bound, A, b) for a, bound in zip(new_A, new_b)):
            return _split(_irredundant(A, b), nx)
        A, b = np.vstack((A, new_A)), np.concatenate((b, new_b))
    raise ConfigError(key, f"the LQR-invariant set is not finitely determined within "
                      f"{MAX_STEPS} steps (the terminal law is too slow for its bounds): "
                      "use kind: polytope or equality")


def _irredundant(A, b):
    """Drop, one by one, the rows the others imply."""
    keep = np.ones(len(b), bool)
    for i in range(len(b)):
        keep[i] = False
        if not _redundant(A[i], b[i], A[keep], b[keep]):
            keep[i] = True
    return A[keep], b[keep]


def _split(Ab, nx):
    A, b = Ab
    return A[:, :nx], A[:, nx:], b
