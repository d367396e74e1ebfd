"""Stage 3: the condensed MPC QP of eqs. (4)-(6) for one mode, in double precision.

Everything the C needs is computed here once (one source of truth):

* prediction ``Y = Phi x + Gamma U`` (eq. 4), weights Omega, Psi;
* ``E = 2(Psi + Gamma' Omega Gamma)`` (the paper's G_j), ``E^-1``, ``F = 2 Gamma' Omega``;
* unconstrained gains ``theta0 = Kx x + Kr R`` with ``Kr = E^-1 F``, ``Kx = -Kr Phi``
  (precomputed in double: forming ``-E^-1 F(Phi x - R)`` on line is unusable in float);
* the constraints ``L U <= c + W x`` of eq. (6), rows ordered by stage as in the paper,
  with the rows on y_{0|k} dropped (they carry no decision variable);
* the dual Hessian ``H = L E^-1 L'`` and its L/D/U split (for reference and tests; the C
  reads H through its structure, see :mod:`rollmpc_codegen.qp.storage`).

Offset-free tracking (:mod:`..features.disturbance_model`) and Δu weighting (:mod:`..features.input_rate`)
add a state-dependent gradient term ``Gx x`` (``Gx`` below), which only changes Kx; Δu
weighting also makes Psi block tridiagonal.

Move blocking (:mod:`..features.move_blocking`) substitutes U = T U_b before any of the above:
Gamma, Psi and Gx become Gamma T, T' Psi T and T' Gx, and the input rows are one pair per
block, so n = p nu; ``markov`` stays the unblocked (stage) one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..features import input_rate, move_blocking, soft_constraints
from ..features.signals import ModelSignal, SignalBlock, on_model, signal_block
from ..features.terminal_set import terminal_signals
from ..config import ConfigError, ModeConfig
from ..model.plant import DiscretePlant
from .rows import INPUT, OUTPUT, RATE, SIGNAL


@dataclass(frozen=True)
class CondensedQP:
    N: int
    nx: int
    nu: int
    ny: int
    Phi: np.ndarray  # (N ny, nx)
    Gamma: np.ndarray  # (N ny, n): N nu columns, or p nu with move blocking (Gamma T)
    markov: np.ndarray  # (N, ny, nu): C A^i B, i = 0..N-1 (Gamma is block Toeplitz in these)
    Omega: np.ndarray  # (N ny, N ny)
    Psi: np.ndarray  # (N nu, N nu): blkdiag(R), plus D' R_delta D with Δu weighting
    E: np.ndarray  # (n, n)
    Einv: np.ndarray
    F: np.ndarray  # (n, N ny)
    Kx: np.ndarray  # (n, nx)
    Kr: np.ndarray  # (n, N ny)
    L: np.ndarray  # (m, n) eq. (6)
    W: np.ndarray  # (m, nx)
    c: np.ndarray  # (m,)
    row_kind: np.ndarray  # (m,) the RowKind code (qp/rows.py)
    row_index: np.ndarray  # (m,) the quantity within its kind: U (box, Δu: u_i - u_{i-nu}),
    #                        Y (output) or the signal block's (signal)
    row_sign: np.ndarray  # (m,) -1 for a lower bound row, +1 for an upper bound row
    # offset-free tracking: R weights U - Ut x (Ut = the disturbance-cancelling input
    # target per stage, disturbance_model); None = 0, the paper's eq. (5)
    Ut: np.ndarray | None = None  # (N nu, nx)
    # the gradient's state-dependent part beyond F Phi x (None = 0): -2 blkdiag(R) Ut for
    # the input target, plus input_rate.delta_gradient (-2 R_delta u_prev) for Δu
    Gx: np.ndarray | None = None  # (n, nx)
    blocks: tuple[int, ...] | None = None  # move blocking (None: one block per stage)
    # soft output rows (soft_constraints): per row the slack penalty l1 s + l2 s^2 (0 for
    # hard rows); None without soft bounds
    soft_l1: np.ndarray | None = None  # (m,)
    soft_l2: np.ndarray | None = None  # (m,)
    # constant part of the gradient (soft_constraints.explicit_qp: l1 of the slacks)
    f_const: np.ndarray | None = None  # (n,)
    # general constraints (features/signals.py): the signal quantities, and the rows'
    # reference term L U <= c + W x + Wr R (terminal sets; None = 0)
    signals: SignalBlock | None = None
    Wr: np.ndarray | None = None  # (m, N ny)

    @property
    def n(self) -> int:
        return self.E.shape[0]

    @property
    def m(self) -> int:
        return self.L.shape[0]

    def dual_hessian(self) -> np.ndarray:
        """H = L E^-1 L' (dense; m x m)."""
        return self.L @ self.Einv @ self.L.T

    def ldu(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The paper's split H = L + D + U (strictly lower, diagonal, strictly upper)."""
        H = self.dual_hessian()
        return np.tril(H, -1), np.diag(np.diag(H)), np.triu(H, 1)

    def terminal_split(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(S, V, (2P)^-1) with E = S + V'(2P)V; V empty when P is not positive definite."""
        ny, N = self.ny, self.N
        P = self.Omega[-ny:, -ny:]
        if np.linalg.eigvalsh(P).min() <= 0:
            return self.E, np.zeros((0, self.n)), np.zeros((0, 0))
        V = self.Gamma[-ny:]
        S = 2.0 * (self.Psi + self.Gamma[:-ny].T @ self.Omega[:-ny, :-ny] @ self.Gamma[:-ny])
        return 0.5 * (S + S.T), V.copy(), np.linalg.inv(2.0 * P)

    def gradient(self, x: np.ndarray, R: np.ndarray, dtype=np.float64) -> np.ndarray:
        """f of min 1/2 U'E U + f'U: F (Phi x - R) + Gx x (Gx: input target, Δu), in
        ``dtype`` (e.g. np.longdouble for the extended-precision reference)."""
        x, R = np.asarray(x, dtype=dtype), np.asarray(R, dtype=dtype)
        f = self.F.astype(dtype) @ (self.Phi.astype(dtype) @ x - R)
        f = f if self.Gx is None else f + self.Gx.astype(dtype) @ x
        return f if self.f_const is None else f + self.f_const.astype(dtype)

    def theta0(self, x: np.ndarray, R: np.ndarray) -> np.ndarray:
        return self.Kx @ x + self.Kr @ R

    def gamma(self, x: np.ndarray, R: np.ndarray | None = None, dtype=np.float64) -> np.ndarray:
        """Right-hand side c + W x of eq. (6), plus Wr R where rows follow the reference
        (R: the preview; required then)."""
        x = np.asarray(x, dtype=dtype)
        b = self.c.astype(dtype) + self.W.astype(dtype) @ x
        if self.Wr is not None:
            b = b + self.Wr.astype(dtype) @ np.asarray(R, dtype=dtype)
        return b


def solve_refined(E: np.ndarray, B: np.ndarray, iterations: int = 3) -> np.ndarray:
    """E^-1 B to full double accuracy: LU solve plus refinement with long-double residuals.

    With cond(E) ~ 2.5e6 (the outer mode) a plain solve loses ~6 digits, which shows up
    as ~1e-6 deg in U; mixed-precision refinement recovers them (cond * eps_double << 1).
    """
    lu = scipy.linalg.lu_factor(E)
    X = scipy.linalg.lu_solve(lu, B)
    EL = E.astype(np.longdouble)
    BL = B.astype(np.longdouble)
    for _ in range(iterations):
        R = BL - EL @ X.astype(np.longdouble)
        X = (X.astype(np.longdouble)
             + scipy.linalg.lu_solve(lu, R.astype(np.float64)).astype(np.longdouble))
        X = X.astype(np.float64)
    return X


def _block_diag(block: np.ndarray, count: int, last: np.ndarray | None = None) -> np.ndarray:
    k = block.shape[0]
    out = np.zeros((k * count, k * count))
    for i in range(count):
        out[i * k:(i + 1) * k, i * k:(i + 1) * k] = block
    if last is not None:
        out[-k:, -k:] = last
    return out


def _overflow(key: str, N: int) -> ConfigError:
    return ConfigError(f"{key}.plant", f"its predictions overflow double over the horizon "
                       f"(N = {N}): the plant grows too fast for this horizon")


def predictions(plant: DiscretePlant, N: int, key: str) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, the Markov parameters C A^i B, i < N) of eq. (4): O(N nx^3), so the pipeline
    checks them for overflow before the size verdict and the dense maths."""
    A, B, C = plant.A, plant.B, plant.C
    nx, nu, ny = plant.nx, plant.nu, plant.ny
    Phi = np.zeros((N * ny, nx))
    markov = np.zeros((N, ny, nu))
    Ak = np.eye(nx)
    for i in range(N):
        markov[i] = C @ Ak @ B  # C A^i B
        Ak = Ak @ A
        Phi[i * ny:(i + 1) * ny] = C @ Ak  # C A^{i+1}
    if not (np.all(np.isfinite(Phi)) and np.all(np.isfinite(markov))):  # an unstable plant
        raise _overflow(key, N)
    return Phi, markov


def condense(plant: DiscretePlant, mode: ModeConfig, N: int, key: str) -> CondensedQP:
    """Build the condensed QP of one mode; ``key`` (e.g. ``modes[0]``) names it in errors."""
    nx, nu, ny = plant.nx, plant.nu, plant.ny
    Phi, markov = predictions(plant, N, key)
    Gamma = np.zeros((N * ny, N * nu))
    for i in range(N):  # output step i+1
        for k in range(i + 1):  # input step k
            Gamma[i * ny:(i + 1) * ny, k * nu:(k + 1) * nu] = markov[i - k]
    Omega = _block_diag(mode.Q, N, last=mode.P)
    Psi_R = _block_diag(mode.R, N)
    Psi = (Psi_R if mode.R_delta is None
           else Psi_R + input_rate.delta_hessian(mode.R_delta, N))
    Ut = Gx = None
    if plant.input_target is not None:  # offset-free: R weights U - Ut x
        Ut = np.tile(plant.input_target, (N, 1))
        Gx = -2.0 * Psi_R @ Ut
    if mode.R_delta is not None:  # Δu weighting: -2 R_delta u_prev on the first stage
        G = input_rate.delta_gradient(mode.R_delta, N, nx)
        Gx = G if Gx is None else Gx + G
    if mode.blocks is not None:  # U = T U_b: the QP in the block inputs
        Tb = move_blocking.expansion(mode.blocks, nu)
        Gamma, Psi = Gamma @ Tb, Tb.T @ Psi @ Tb
        Gx = None if Gx is None else Tb.T @ Gx
    if not np.all(np.isfinite(Gamma)):  # the blocks' sums of finite Markov parameters
        raise _overflow(key, N)
    E = 2.0 * (Psi + Gamma.T @ Omega @ Gamma)
    E = 0.5 * (E + E.T)
    if not np.all(np.isfinite(E)):  # before eigvalsh, which fails on inf
        raise ConfigError(f"{key}.weights", "the QP Hessian E = 2(Psi + Gamma' Omega Gamma) "
                          "overflows double: the weights and the plant's gains are too large "
                          "together")
    eig = np.linalg.eigvalsh(E)
    if eig.min() <= 1e-12 * eig.max():  # numerically: a weight ratio beyond 1e12 too
        raise ConfigError(f"{key}.weights", "the QP Hessian E = 2(Psi + Gamma' Omega Gamma) "
                          f"is not positive definite (min eigenvalue {eig.min():.3g}, max "
                          f"{eig.max():.3g}: the min must exceed 1e-12 of the max)")
    if eig.max() / eig.min() > 1e14:
        raise ConfigError(f"{key}.weights", f"the QP Hessian is too ill-conditioned "
                          f"(cond {eig.max() / eig.min():.3g} > 1e14)")
    Einv = solve_refined(E, np.eye(E.shape[0]))
    Einv = 0.5 * (Einv + Einv.T)
    F = 2.0 * Gamma.T @ Omega
    Kr = solve_refined(E, F)
    Kx = -(Kr.astype(np.longdouble) @ Phi.astype(np.longdouble)).astype(np.float64)
    if Gx is not None:  # the state-dependent gradient only changes Kx
        Kx = Kx - solve_refined(E, Gx)
    L, W, c, kind, index, sign = _constraints(mode, Phi, Gamma, N, nu, ny)
    soft_l1, soft_l2 = soft_constraints.row_penalties(mode.soft_l1, mode.soft_l2, kind, index,
                                                      sign, ny)
    rows = dict(L=L, W=W, c=c, row_kind=kind, row_index=index, row_sign=sign,
                soft_l1=soft_l1, soft_l2=soft_l2)
    if mode.signals or mode.terminal is not None:
        rows = _with_signal_rows(rows, signal_block(model_signals(mode, plant, N, key), plant,
                                                    N, ny, mode.blocks), N * ny)
    return CondensedQP(N=N, nx=nx, nu=nu, ny=ny, Phi=Phi, Gamma=Gamma, markov=markov,
                       Omega=Omega, Psi=Psi, E=E, Einv=Einv, F=F, Kx=Kx, Kr=Kr, Ut=Ut,
                       Gx=Gx, blocks=mode.blocks, **rows)


def model_signals(mode: ModeConfig, plant: DiscretePlant, N: int, key: str
                  ) -> tuple[ModelSignal, ...]:
    """Every signal of the mode (features/signals.py): its constrained signals and mixed
    rows, then its terminal constraint's facets (features/terminal_set.py)."""
    out = tuple(on_model(s, plant, plant.nu) for s in mode.signals)
    if mode.terminal is not None:
        out += terminal_signals(mode, plant, N, key)
    return out


def _with_signal_rows(rows: dict, block: SignalBlock, nyq: int) -> dict:
    """eq. (6)'s rows followed by the signal block's (kind SIGNAL), with their soft
    penalties and, where a row follows the reference, the Wr term."""
    m, ms = rows["c"].size, block.c.size
    soft = rows["soft_l2"] is not None or bool(np.any(block.l2 > 0))

    def penalties(name, own):
        base = rows[name] if rows[name] is not None else np.zeros(m)
        return np.concatenate((base, own)) if soft else None

    return {
        "L": np.vstack((rows["L"], block.L)), "W": np.vstack((rows["W"], block.W)),
        "c": np.concatenate((rows["c"], block.c)),
        "row_kind": np.concatenate((rows["row_kind"], np.full(ms, SIGNAL.code, np.int32))),
        "row_index": np.concatenate((rows["row_index"], block.index)),
        "row_sign": np.concatenate((rows["row_sign"], block.sign)),
        "soft_l1": penalties("soft_l1", block.l1), "soft_l2": penalties("soft_l2", block.l2),
        "signals": block,
        "Wr": (np.vstack((np.zeros((m, nyq)), block.Wr)) if block.has_reference else None),
    }


def _constraints(mode: ModeConfig, Phi, Gamma, N: int, nu: int, ny: int):
    """Eq. (6) rows of the input, Δu and output kinds (qp/rows.py), stage by stage:
    [-u_i, +u_i, -du_i, +du_i, -y_i, +y_i], i = 0..N.

    u exists for stages 0..N-1; y rows exist for stages 1..N (y_0 depends on x only, so
    its rows are dropped) and only for finite bounds.  Δu rows (kind 2, finite
    ``du_min``/``du_max`` only) bound u_i - u_{i-1}; at stage 0 that is u_0 - u_prev with
    u_prev = the last nu states (input_rate.augment), so W carries sign * 1 on it.  With
    move blocking the input rows of block j (U_b,j) sit at its first stage, and Gamma is
    the blocked Gamma T (blocking and Δu rows are not combined: config/checks.py rejects it).
    """
    n = Gamma.shape[1]
    first = (np.arange(N) if mode.blocks is None
             else move_blocking.block_starts(mode.blocks))
    block_at = {int(s): j for j, s in enumerate(first)}
    rows_L, rows_W, rows_c, kind, index, sign = [], [], [], [], [], []

    def add(L_row, W_row, c_val, k, idx, s):
        rows_L.append(L_row)
        rows_W.append(W_row)
        rows_c.append(c_val)
        kind.append(k)
        index.append(idx)
        sign.append(s)

    nx = Phi.shape[1]
    for stage in range(N + 1):
        if stage in block_at:
            for s, bounds in ((-1, mode.u_min), (1, mode.u_max)):
                for j in range(nu):
                    q = block_at[stage] * nu + j
                    e = np.zeros(n)
                    e[q] = s
                    add(e, np.zeros(nx), s * bounds[j], INPUT.code, q, s)
            if mode.du_min is not None:
                for s, bounds in ((-1, mode.du_min), (1, mode.du_max)):
                    for j in range(nu):
                        if not np.isfinite(bounds[j]):
                            continue
                        q = stage * nu + j
                        e = np.zeros(n)
                        e[q] = s
                        w = np.zeros(nx)
                        if stage == 0:
                            w[nx - nu + j] = s
                        else:
                            e[q - nu] = -s
                        add(e, w, s * bounds[j], RATE.code, q, s)
        if stage >= 1:
            for s, bounds in ((-1, mode.y_min), (1, mode.y_max)):
                for j in range(ny):
                    if not np.isfinite(bounds[j]):
                        continue
                    k = (stage - 1) * ny + j
                    add(s * Gamma[k], -s * Phi[k], s * bounds[j], OUTPUT.code, k, s)
    return (np.array(rows_L), np.array(rows_W), np.array(rows_c),
            np.array(kind, dtype=np.int32), np.array(index, dtype=np.int32),
            np.array(sign, dtype=np.int32))
