"""The general constraints of a mode (``modes[].constraints``), written independently of
the generator for ``tests/solver/test_signal_rows.py``, on top of
:class:`independent_qp.IndependentQP`.

Nothing comes from ``features/signals.py``, ``features/terminal_set.py`` or
``qp/condense.py``: every signal is predicted by stepping the model (A, B of the context
JSON, whose first states are the plant's as the YAML writes them) from the definitions of
docs/features.md ("General constraints"):

    z_k = C x_k + D u_k at the times k of ``stages`` (1..N without D, 0..N-1 with it),
    lo <= z_k <= hi;  a mixed row E x_k + F u_k <= g likewise;
    a terminal polytope H (x_N - x_s) <= h, an equality x_N = x_s, with the steady state
    x_s of [A - I, B; C, 0] [x_s; u_s] = [0; r_N] (least squares) on the plant's states.

An LQR-invariant set is an output of the generator (the facets of the context's model):
it is taken as given, as rows Hx x_N + Hr r_N <= h.
"""
from __future__ import annotations

import numpy as np

from independent_qp import NO_BOUND, IndependentQP, vector


def _row(value) -> np.ndarray:
    value = value[0] if isinstance(value, list) and value and isinstance(value[0], list) else value
    return np.array([float(v) for v in value])


def yaml_signals(mode: dict, N: int, nu: int) -> list[tuple]:
    """(c, d, lo, hi, first, last) per scalar signal of the mode's YAML constraints."""
    out = []
    cons = mode.get("constraints", {})
    for spec in cons.get("signals", {}).values():
        c = _row(spec["C"]) if "C" in spec else np.zeros(0)
        d = _row(spec["D"]) if "D" in spec else np.zeros(0)
        lo, hi = float(spec.get("min", -np.inf)), float(spec.get("max", np.inf))
        out.append((c, d, lo, hi, spec.get("stages")))
    for spec in cons.get("mixed", {}).values():
        g = vector(spec["g"], len(spec["g"]))
        for i in range(g.size):
            c = np.array(spec["E"][i], float) if "E" in spec else np.zeros(0)
            d = np.array(spec["F"][i], float) if "F" in spec else np.zeros(0)
            out.append((c, d, -np.inf, g[i], spec.get("stages")))
    rows = []
    for c, d, lo, hi, stages in out:
        feed = bool(np.any(d))
        first, last = (0, N - 1) if feed else (1, N)
        if stages is not None:
            first, last = (stages, stages) if not isinstance(stages, list) else stages
        rows.append((c, np.r_[d, np.zeros(nu - d.size)], lo, hi, int(first), int(last)))
    return rows


class IndependentQPWithSignals(IndependentQP):
    """IndependentQP plus the signal rows (``terminal``: facets (Hx, Hr, h) of a set the
    generator computed, or None to read a polytope/equality from ``mode_yaml``)."""

    def __init__(self, spec, mode_ctx: dict, N: int, mode_yaml: dict, terminal=None):
        super().__init__(spec, mode_ctx, N)
        A, B, C = (np.array(mode_ctx[k], dtype=float) for k in ("A", "B", "C"))
        self.A, self.B, self.C = A, B, C
        self.signals = yaml_signals(mode_yaml, N, self.nu)
        self.terminal_yaml = mode_yaml.get("constraints", {}).get("terminal")
        self.terminal = terminal
        # the state at every time 0..N: X_k = Sx_k x + Su_k v
        self.Sx, self.Su = [np.eye(self.nx)], [np.zeros((self.nx, N * self.nu))]
        for k in range(N):
            Su = A @ self.Su[-1]
            Su[:, k * self.nu:(k + 1) * self.nu] += B
            self.Sx.append(A @ self.Sx[-1])
            self.Su.append(Su)

    def _signal_rows(self, x, r):
        N, nu, ns = self.N, self.nu, len(self.soft_rows)
        G, lo, hi = [], [], []
        for c, d, low, high, first, last in self.signals:
            cz = np.r_[c, np.zeros(self.nx - c.size)]
            for k in range(first, last + 1):
                row = cz @ self.Su[k]
                if k < N:
                    row = row.copy()
                    row[k * nu:(k + 1) * nu] += d
                free = cz @ self.Sx[k] @ x
                G.append(np.r_[row @ self.T, np.zeros(ns)])
                lo.append(max(low - free, -NO_BOUND))
                hi.append(min(high - free, NO_BOUND))
        for hx, hr, h in self._terminal_facets():
            row = hx @ self.Su[N]
            G.append(np.r_[row @ self.T, np.zeros(ns)])
            free = hx @ self.Sx[N] @ x + hr @ r[(N - 1) * self.ny:]
            lo.append(-NO_BOUND if h[0] == -np.inf else h[0] - free)
            hi.append(h[1] - free)
        return G, lo, hi

    def _terminal_facets(self):
        """(hx, hr, (lo, hi)) per terminal row on x_N and r_N."""
        if self.terminal is not None:
            Hx, Hr, h = self.terminal
            return [(Hx[i], Hr[i], (-np.inf, h[i])) for i in range(h.size)]
        t = self.terminal_yaml
        if t is None:
            return []
        t = {"kind": t} if isinstance(t, str) else t
        assert self.nd == 0, "an independent x_s with a disturbance model is not written here"
        p = self.nx - self.n_prev  # the plant's states
        A, B, C = self.A[:p, :p], self.B[:p], self.C[:, :p]
        lhs = np.block([[A - np.eye(p), B], [C, np.zeros((self.ny, self.nu))]])
        rhs = np.vstack([np.zeros((p, self.ny)), np.eye(self.ny)])
        Mx = np.linalg.lstsq(lhs, rhs, rcond=None)[0][:p]  # x_s = Mx r
        H = np.eye(p) if t["kind"] == "equality" else np.array(t["H"], float)
        h = np.zeros(p) if t["kind"] == "equality" else np.array(t["h"], float)
        lo = -h if t["kind"] == "equality" else np.full(h.size, -np.inf)
        Hx = np.zeros((H.shape[0], self.nx))
        Hx[:, :p] = H
        return [(Hx[i], -H[i] @ Mx, (lo[i], h[i])) for i in range(h.size)]

    def rows(self, x, r=None):
        G, lo, hi = super().rows(x)
        Gs, ls, hs = self._signal_rows(x, self._r if r is None else r)
        width = G.shape[1]
        return (np.vstack([G, np.array(Gs).reshape(-1, width)]), np.r_[lo, ls], np.r_[hi, hs])

    def solve(self, x, r):
        self._r = np.asarray(r, float)
        return super().solve(x, r)
