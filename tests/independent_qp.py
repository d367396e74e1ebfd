"""An independent formulation of each example's MPC problem, for
``tests/qp/test_independent_formulation.py``.

Nothing here comes from the generator's QP stage (``qp/condense.py``: Phi, Gamma, E, F, the
rows L, W, c), from ``sim.scenario.preview`` or from the NumPy mirror of the C.  The QP
is written from the cost's definition (README, "Configuration schema" and "How the
controller works"; docs/features.md for Δu, disturbances, blocking and soft bounds):

    J = sum_{i=1..N} (y_i - r_i)' W_i (y_i - r_i)      W_i = Q for i < N and P for i = N:
                                                       README's Q/R/P are the "stage output,
                                                       input and terminal output weights", so
                                                       the terminal weight replaces Q on y_N
      + sum_{k=0..N-1} (u_k - u_s)' R (u_k - u_s)      u_s = 0, or with ``observer.disturbance``
                                                       the steady input that cancels the
                                                       estimated disturbance at the origin
      + sum_{k=0..N-1} du_k' R_delta du_k              du_k = u_k - u_{k-1}, u_{-1} = the
                                                       previous command (last nu states)
      + sum over soft rows of (l1 s + l2 s^2)          one slack per output, side and stage

    x_{k+1} = A x_k + B u_k, y_k = C x_k   (A, B, C of the mode from the context JSON)
    u_min <= u_k <= u_max,  du_min <= du_k <= du_max,  y_min - s <= y_i <= y_max + s,  s >= 0,
    and with move blocking (control_horizon) every stage of a block takes the block's input.

The weights, bounds and blocks are read from the YAML file by the README's rules (a scalar
broadcasts, a flat list is a diagonal, a list of rows a matrix; ``1.0e6`` read as a
string by YAML 1.1 is a number), and the QP is solved by DAQP (a dual active-set solver
that shares no code with rollmpc) in the variables (U per block, slacks).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NO_BOUND = 1e30  # DAQP's infinity
PAPER_LEVELS, PAPER_SEGMENT_S = (0.0, -20.0, 20.0, -40.0, 40.0, 0.0), 10.0  # README, section 4.1


def vector(value, size: int) -> np.ndarray:
    """A per-entry value: a scalar broadcasts, a list gives every entry."""
    if isinstance(value, list):
        assert len(value) == size, value
        return np.array([float(v) for v in value])
    return np.full(size, float(value))


def matrix(value, size: int) -> np.ndarray:
    """A weight: a scalar times I, a flat list on the diagonal, or a list of rows."""
    if isinstance(value, list) and value and isinstance(value[0], list):
        return np.array([[float(v) for v in row] for row in value])
    return np.diag(vector(value, size))


def block_lengths(level: dict, N: int) -> list[int] | None:
    """``control_horizon: Nc`` = blocks [1, ..., 1, N - Nc + 1]; ``move_blocking`` as given."""
    if level.get("control_horizon") is not None:
        nc = int(level["control_horizon"])
        return [1] * (nc - 1) + [N - nc + 1]
    return None if level.get("move_blocking") is None else [int(b) for b in level["move_blocking"]]


@dataclass
class ModeSpec:
    """One mode's cost and bounds, from its YAML mapping."""

    Q: np.ndarray
    R: np.ndarray
    P: np.ndarray
    R_delta: np.ndarray | None
    u_min: np.ndarray
    u_max: np.ndarray
    y_min: np.ndarray
    y_max: np.ndarray
    du_min: np.ndarray
    du_max: np.ndarray
    soft_l1: np.ndarray  # (ny, 2): column 0 = y_min, 1 = y_max; l2 > 0 makes a bound soft
    soft_l2: np.ndarray
    blocks: list[int] | None
    disturbance: str

    @classmethod
    def from_yaml(cls, doc: dict, index: int) -> "ModeSpec":
        mode, N = doc["modes"][index], int(doc["horizon"])
        ny, nu = len(doc["outputs"]), len(mode["actuators"])
        w, b = mode["weights"], mode["bounds"]
        R_delta = None if w.get("R_delta") is None else matrix(w["R_delta"], nu)
        soft = b.get("soft", {})
        l1, l2 = np.zeros((ny, 2)), np.zeros((ny, 2))
        for side, key in enumerate(("y_min", "y_max")):
            if key in soft:
                l1[:, side] = vector(soft[key]["l1"], ny)
                l2[:, side] = vector(soft[key]["l2"], ny)
        mode_blocks = block_lengths(mode, N)
        return cls(
            Q=matrix(w["Q"], ny), R=matrix(w["R"], nu), P=matrix(w.get("P", w["Q"]), ny),
            R_delta=None if R_delta is None or not R_delta.any() else R_delta,
            u_min=vector(b["u_min"], nu), u_max=vector(b["u_max"], nu),
            y_min=vector(b.get("y_min", -np.inf), ny), y_max=vector(b.get("y_max", np.inf), ny),
            du_min=vector(b.get("du_min", -np.inf), nu), du_max=vector(b.get("du_max", np.inf), nu),
            soft_l1=l1, soft_l2=l2,
            blocks=mode_blocks if mode_blocks is not None else block_lengths(doc, N),
            disturbance=mode.get("observer", {}).get("disturbance", "none"))


class IndependentQP:
    """The QP of one mode in the variables z = (one input vector per block, slacks)."""

    def __init__(self, spec: ModeSpec, mode_ctx: dict, N: int):
        A, B, C = (np.array(mode_ctx[k], dtype=float) for k in ("A", "B", "C"))
        self.spec, self.N = spec, N
        self.nx, self.nu, self.ny = A.shape[0], B.shape[1], C.shape[0]
        nu, nx = self.nu, self.nx
        has_rate = spec.R_delta is not None or np.isfinite(np.r_[spec.du_min, spec.du_max]).any()
        self.n_prev = nu if has_rate else 0  # u_{-1}: the last nu states
        self.nd = {"none": 0, "input": nu, "output": self.ny}[spec.disturbance]
        # the prediction loop: x_k = Sx x + Su v with v = (u_0, ..., u_{N-1}); y_i = C x_i
        Sx, Su = np.eye(nx), np.zeros((nx, N * nu))
        self.Yx, self.Yu = np.zeros((N, self.ny, nx)), np.zeros((N, self.ny, N * nu))
        for k in range(N):
            Sx, Su = A @ Sx, A @ Su
            Su[:, k * nu:(k + 1) * nu] += B
            self.Yx[k], self.Yu[k] = C @ Sx, C @ Su
        # stage -> block: v = T z_U
        lengths = spec.blocks or [1] * N
        stage_block = [j for j, length in enumerate(lengths) for _ in range(length)]
        self.T = np.zeros((N * nu, len(lengths) * nu))
        for t, j in enumerate(stage_block):
            self.T[t * nu:(t + 1) * nu, j * nu:(j + 1) * nu] = np.eye(nu)
        self.n_u = self.T.shape[1]
        self.target = self._input_target(A, B, C)
        self.soft_rows = [(i, a, side) for i in range(N) for a in range(self.ny)
                          for side, bound in enumerate((spec.y_min[a], spec.y_max[a]))
                          if np.isfinite(bound) and spec.soft_l2[a, side] > 0]

    @property
    def has_hard_output_rows(self) -> bool:
        s = self.spec
        return bool(np.any(np.isfinite(np.c_[s.y_min, s.y_max]) & (s.soft_l2 <= 0)))

    def _input_target(self, A, B, C) -> np.ndarray:
        """M with u_s = M x: the input that holds the plant states at the origin output
        0 against the disturbance states d, [A_p - I, B_p; C_p, 0] [x_s; u_s] = -[B_d; C_d] d
        (least squares), from the augmented A and C; 0 without a disturbance model."""
        M = np.zeros((self.nu, self.nx))
        if self.nd == 0:
            return M
        p = self.nx - self.nd - self.n_prev
        lhs = np.block([[A[:p, :p] - np.eye(p), B[:p]], [C[:, :p], np.zeros((self.ny, self.nu))]])
        rhs = -np.vstack([A[:p, p:p + self.nd], C[:, p:p + self.nd]])
        M[:, p:p + self.nd] = np.linalg.lstsq(lhs, rhs, rcond=None)[0][p:]
        return M

    def cost(self, x: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Hv, gv) with J = v'Hv v + 2 gv'v + const over the stage inputs v."""
        s, N, nu, ny = self.spec, self.N, self.nu, self.ny
        Hv, gv = np.zeros((N * nu, N * nu)), np.zeros(N * nu)
        for i in range(N):
            W = s.P if i == N - 1 else s.Q
            Hv += self.Yu[i].T @ W @ self.Yu[i]
            gv += self.Yu[i].T @ W @ (self.Yx[i] @ x - r[i * ny:(i + 1) * ny])
        u_s, u_prev = self.target @ x, x[self.nx - self.n_prev:]
        for k in range(N):
            here = slice(k * nu, (k + 1) * nu)
            Hv[here, here] += s.R
            gv[here] -= s.R @ u_s
            if s.R_delta is None:
                continue
            Hv[here, here] += s.R_delta
            if k == 0:
                gv[here] -= s.R_delta @ u_prev
            else:
                before = slice((k - 1) * nu, k * nu)
                Hv[before, before] += s.R_delta
                Hv[here, before] -= s.R_delta
                Hv[before, here] -= s.R_delta
        return Hv, gv

    def rows(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(G, lower, upper) of the rows lower <= G z <= upper: Δu rows, then output rows."""
        s, N, nu, ns = self.spec, self.N, self.nu, len(self.soft_rows)
        G, lo, hi = [], [], []
        u_prev = x[self.nx - self.n_prev:]
        for k in range(N):
            for b in range(nu):
                if not np.isfinite([s.du_min[b], s.du_max[b]]).any():
                    continue
                row = np.zeros(N * nu)
                row[k * nu + b] = 1.0
                shift = u_prev[b] if k == 0 else 0.0
                if k > 0:
                    row[(k - 1) * nu + b] = -1.0
                G.append(np.r_[row @ self.T, np.zeros(ns)])
                lo.append(max(s.du_min[b] + shift, -NO_BOUND))
                hi.append(min(s.du_max[b] + shift, NO_BOUND))
        for i in range(N):
            for a in range(self.ny):
                for side, bound in enumerate((s.y_min[a], s.y_max[a])):
                    if not np.isfinite(bound):
                        continue
                    row = np.r_[self.Yu[i][a] @ self.T, np.zeros(ns)]
                    if (i, a, side) in self.soft_rows:  # y + s >= y_min, y - s <= y_max
                        row[self.n_u + self.soft_rows.index((i, a, side))] = 1.0 if side == 0 else -1.0
                    free = self.Yx[i][a] @ x
                    G.append(row)
                    lo.append(bound - free if side == 0 else -NO_BOUND)
                    hi.append(bound - free if side == 1 else NO_BOUND)
        width = self.n_u + ns
        return np.array(G).reshape(-1, width), np.array(lo), np.array(hi)

    def solve(self, x, r) -> tuple[int, np.ndarray | None]:
        """(DAQP's exit flag: 1 optimal, -1 infeasible; U per block or None)."""
        import daqp

        x, r = np.asarray(x, dtype=float), np.asarray(r, dtype=float)
        s, ns = self.spec, len(self.soft_rows)
        Hv, gv = self.cost(x, r)
        H = np.zeros((self.n_u + ns, self.n_u + ns))
        H[:self.n_u, :self.n_u] = 2.0 * self.T.T @ Hv @ self.T
        f = np.r_[2.0 * self.T.T @ gv, np.zeros(ns)]
        for j, (_, a, side) in enumerate(self.soft_rows):
            H[self.n_u + j, self.n_u + j] = 2.0 * s.soft_l2[a, side]
            f[self.n_u + j] = s.soft_l1[a, side]
        G, lo, hi = self.rows(x)
        blocks = self.n_u // self.nu
        lower = np.r_[np.tile(s.u_min, blocks), np.zeros(ns), lo]
        upper = np.r_[np.tile(s.u_max, blocks), np.full(ns, NO_BOUND), hi]
        z, _, flag, _ = daqp.solve(0.5 * (H + H.T), f, G, upper, lower,
                                   np.zeros(upper.size, dtype=np.intc), primal_tol=1e-12)
        return flag, (z[:self.n_u] if flag == 1 else None)


def reference_signal(doc: dict) -> np.ndarray:
    """(samples, ny): README's ``simulation.reference`` levels (a scalar level applies to
    every output) held ``segment`` s each; without the key the paper's scenario."""
    sim = doc.get("simulation", {}).get("reference", {})
    levels, segment = sim.get("levels", PAPER_LEVELS), sim.get("segment", PAPER_SEGMENT_S)
    ny, per = len(doc["outputs"]), int(round(float(segment) / float(doc["sample_time"])))
    return np.array([vector(level, ny) for level in levels for _ in range(per)])


def preview(signal: np.ndarray, k: int, N: int) -> np.ndarray:
    """r_{k+1}, ..., r_{k+N} (output-major per stage), the last sample held past the end."""
    last = len(signal) - 1
    return np.concatenate([signal[min(k + i, last)] for i in range(1, N + 1)])


def next_mode(current: int, s: float, sched: dict) -> int:
    """docs/features.md, "k modes": band b's mode when t_{b-1} + eps_{b-1} < s < t_b - eps_b
    (the end bands have one condition), else the current mode."""
    t, eps, modes = sched["thresholds"], sched["epsilons"], sched["band_modes"]
    for b, mode in enumerate(modes):
        above_lower = b == 0 or s > t[b - 1] + eps[b - 1]
        below_upper = b == len(modes) - 1 or s < t[b] - eps[b]
        if above_lower and below_upper:
            return mode
    return current


class ObserverBank:
    """Every mode's predictor observer x+ = A x + B u_j + L (y - C x), from P_init's zeros;
    u_j = the commands of the mode's own actuators (README, "How the controller works")."""

    def __init__(self, ctx: dict):
        self.modes = [{k: np.array(m[k], dtype=float) for k in ("A", "B", "C", "L")}
                      | {"act": np.array(m["actuator_index"])} for m in ctx["modes"]]
        self.x = [np.zeros(m["A"].shape[0]) for m in self.modes]

    def update(self, y: np.ndarray, u: np.ndarray) -> None:
        for j, m in enumerate(self.modes):
            x = self.x[j]
            self.x[j] = m["A"] @ x + m["B"] @ u[m["act"]] + m["L"] @ (y - m["C"] @ x)
