"""NumPy reference of the generated QP solver, operation by operation.

It mirrors ``templates/solver.c.j2`` and ``linalg.c.j2``: the same storage-precision
numbers (from :mod:`rollmpc_codegen.qp.storage`), the same loops in the same order, scalars of
the storage dtype (float32 where the C uses float), and *sequential* sums (``seqsum``
below, never BLAS or pairwise summation).  The C is compiled with
``-ffp-contract=off`` so that it, too, rounds every product and every sum.
Agreement is therefore bit for bit, which the tests check.

Where the C skips work that cannot change a result (the output prediction when
``outputs_certified()`` proves no output row can be violated), the reference does the
work anyway: an unsound certificate would then show up as a bit-exactness failure.
"""
from __future__ import annotations

import numpy as np

from ..qp.storage import ModeData, unpack_lower
from ..features.soft_constraints import slacks
from ..status import INACCURATE, INFEASIBLE, MAX_ITER, NUMERICAL, OPTIMAL


def seqsum(products: np.ndarray, start=None) -> np.generic:
    """``acc = start (default 0); for p in products: acc += p`` in the products' dtype."""
    dt = products.dtype
    head = np.zeros(1, dt) if start is None else np.array([start], dt)
    return np.add.accumulate(np.concatenate((head, products)))[-1]


def seqsum_rows(P: np.ndarray) -> np.ndarray:
    """Row-wise :func:`seqsum` of a 2-D array of products (each row from 0)."""
    head = np.zeros((P.shape[0], 1), P.dtype)
    return np.add.accumulate(np.hstack((head, P)), axis=1)[:, -1]


def dot4_rows(P: np.ndarray) -> np.ndarray:
    """Row-wise mirror of the C ``dot4``: lanes i mod 4, the tail into lane 0,
    combined as (s0 + s1) + (s2 + s3)."""
    rows, length = P.shape
    main = length - length % 4
    lanes = [seqsum_rows(P[:, j:main:4]) for j in range(4)]
    s0 = np.add.accumulate(np.hstack((lanes[0][:, None], P[:, main:])), axis=1)[:, -1]
    return (s0 + lanes[1]) + (lanes[2] + lanes[3])


def s_row_dots(S: np.ndarray, rows, v: np.ndarray) -> np.ndarray:
    """Mirror of ``s_row_dot`` for each q in ``rows``: dot4 up to the diagonal, dot4 below."""
    out = np.empty(len(rows), S.dtype)
    for j, q in enumerate(rows):
        head = dot4_rows((S[q, :q + 1] * v[:q + 1])[None, :])[0]
        tail = dot4_rows((S[q, q + 1:] * v[q + 1:])[None, :])[0]
        out[j] = head + tail
    return out


def cholesky_packed(a: np.ndarray, n: int, start: int = 0) -> bool:
    """Mirror of ``P_cholesky_from`` (in place on the packed array, rows ``start``..n-1);
    False on a bad pivot."""
    dt = a.dtype
    tri = _tri_offsets(n)
    for i in range(start, n):
        ri = a[tri[i]:tri[i] + i + 1]
        for j in range(i + 1):
            rj = a[tri[j]:tri[j] + j + 1]
            s = seqsum(-(ri[:j] * rj[:j]), start=ri[j]) if j else ri[j]
            if i == j:
                if not s > 0:
                    return False
                ri[i] = np.sqrt(dt.type(s))
            else:
                ri[j] = dt.type(s) / rj[j]
    return True


def chol_lsolve_packed(l: np.ndarray, n: int, b: np.ndarray) -> None:
    """Mirror of ``P_chol_lsolve`` (L y = b, in place on b)."""
    tri = _tri_offsets(n)
    for i in range(n):
        s = seqsum(-(l[tri[i]:tri[i] + i] * b[:i]), start=b[i])
        b[i] = s / l[tri[i] + i]


def chol_ltsolve_packed(l: np.ndarray, n: int, b: np.ndarray) -> None:
    """Mirror of ``P_chol_ltsolve`` (L' x = y, in place on b)."""
    tri = _tri_offsets(n)
    for i in range(n - 1, -1, -1):
        col = l[tri[i + 1:n] + i] if i + 1 < n else np.zeros(0, l.dtype)
        s = seqsum(-(col * b[i + 1:n]), start=b[i])
        b[i] = s / l[tri[i] + i]


def chol_solve_packed(l: np.ndarray, n: int, b: np.ndarray) -> None:
    """Mirror of ``P_chol_solve`` (in place on b)."""
    chol_lsolve_packed(l, n, b)
    chol_ltsolve_packed(l, n, b)


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


def _tri_offsets(n: int) -> np.ndarray:
    i = np.arange(n + 1)
    return i * (i + 1) // 2


class SolverRef:
    """Reference of ``P_qp_solve`` for one mode; holds that mode's warm-start multipliers."""

    def __init__(self, md: ModeData, solver_ctx: dict):
        self.md = md
        self.dt = md.Kx.dtype.type
        dt = self.dt
        s = solver_ctx
        self.reduced, self.warm, self.polish_on = s["reduced"], s["warm_start"], s["polish"]
        self.polish_first = s.get("polish_first", False)
        self.omega, self.sigma, self.delta = dt(s["omega"]), dt(s["sigma"]), dt(s["delta"])
        self.tol = dt(s["feasibility_tol"])
        self.max_iter, self.polish_every, self.polish_max = (
            s["max_iterations"], s["polish_every"], s["polish_max"])
        self.limit = dt(1e30)
        self.active_set = s.get("active_set", False)
        self.active_set_max = s.get("active_set_max", 0)
        self.dep_tol = dt(s.get("dependence_tol", 0.0))
        n, nyq = md.n, md.n_yq
        # E^-1 exactly as hq() forms it: S^-1(a, b) - sum_o Ew[o, a] Ew[o, b]
        acc = np.zeros((n, n), md.Kx.dtype)
        for o in range(md.nt):
            acc = acc + np.outer(md.Ew[o], md.Ew[o])
        self.Sinv = unpack_lower(md.Sinv_p, n)
        Einv = self.Sinv - acc
        has_out = md.has_output_rows
        GEG = unpack_lower(md.GEinvGt_p, nyq) if has_out else np.zeros((nyq, nyq), md.Kx.dtype)
        Hq = np.block([[Einv, md.EinvGt], [md.EinvGt.T, GEG]])
        self.has_rate = md.has_rate_rows
        if self.has_rate:
            Hq = _rate_extended(Hq, n, md.nu)
        q, sg = md.row_q, md.row_sign
        same = sg[:, None] == sg[None, :]
        Hrows = Hq[np.ix_(q, q)]
        self.H = np.where(same, Hrows, -Hrows)  # H_rs, exactly as h_rows()
        self.Hdiag = Hq[q, q]
        EM = Hq[:n][:, q]
        self.EM = np.where(sg[None, :] > 0, EM, -EM)  # (E^-1 M_s')_i, as em_col()
        self.S = unpack_lower(md.S_p, n)
        # Gamma in the storage dtype, rows restricted to their nonzero prefix in predict
        N, ny, nu = md.N, md.ny, md.nu
        self.Gam = np.zeros((nyq, N * nu), md.Kx.dtype)  # over the stages (n with no blocks)
        # move blocking: the C reads th[stage_block[t] nu + b] for stage t (U = T th)
        self.expand = (None if md.stage_block is None else
                       (md.stage_block[:, None] * nu + np.arange(nu)[None, :]).reshape(-1))
        for k in range(nyq):
            stage, a = divmod(k, ny)
            for t in range(stage + 1):
                self.Gam[k, t * nu:(t + 1) * nu] = md.markov[stage - t, a, :]
        self.has_out = has_out
        self.lam = np.zeros(md.m, md.Kx.dtype)
        self.one, self.zero = dt(1.0), dt(0.0)
        # the bound data: baked (md), or live with runtime_bounds (ControllerRef.set_bounds)
        self.row_c, self.u_min, self.u_max = md.row_c, md.u_min, md.u_max
        # soft output rows (soft_of() per row): w = 1/(2 l2) (0: hard) and l1; the slack
        # states of the working-set rows (ws->slack_on); the working-set capacity
        self.soft_l1, self.soft_w = md.soft_rows()
        self.soft = bool(np.any(self.soft_w > 0))
        self.slack_on = np.zeros(md.m, bool)
        self.wcap = md.w_cap if self.soft else n
        self.slack_max, self.slack_rows = self.zero, 0

    # -- pieces mirroring the static functions of solver.c.j2 ------------------------
    def _unconstrained(self, x, r):
        """Mirror of unconstrained(): th0 summed per run of equal w (see reference_runs())."""
        md, ny = self.md, self.md.ny
        rr = r.reshape(md.N, ny)
        w = np.empty(md.n_yq, md.Kx.dtype)
        for k in range(md.n_yq):
            stage, a = divmod(k, ny)
            w[k] = seqsum(md.Omega2[stage, a, :] * rr[stage])
        W = w.reshape(md.N, ny)
        last = md.N - 1
        starts = [st for st in range(last) if st == 0 or np.any(W[st] != W[st - 1])]
        bounds = list(zip(starts, starts[1:] + [last]))
        lengths = [e - b for b, e in bounds]
        longest = int(np.argmax(lengths)) if lengths else -1
        G = md.EinvGt.reshape(md.n, md.N, ny)
        acc = seqsum_rows(md.Kx * x[None, :])
        for a in range(ny):
            other = np.zeros(md.n, md.Kx.dtype)
            for j, (b, e) in enumerate(bounds):
                if j != longest:
                    s = seqsum_rows(G[:, b:e, a])
                    acc = acc + W[b, a] * s
                    other = other + s
            if longest >= 0:
                acc = acc + W[bounds[longest][0], a] * (md.colsum[a] - other)
            acc = acc + G[:, last, a] * W[last, a]
        px = seqsum_rows(md.Phi * x[None, :]) if self.has_out else None
        return acc, px

    def _predict(self, th):
        md = self.md
        out = np.empty(md.n_yq, md.Kx.dtype)
        th = th if self.expand is None else th[self.expand]
        for k in range(md.n_yq):
            width = (k // md.ny + 1) * md.nu
            out[k] = seqsum(self.Gam[k, :width] * th[:width])
        return out

    def _values(self, th, yv):
        q, n = self.md.row_q, self.md.n
        if self.has_rate:  # mirror of row_value() with Δu rows
            d = q - (n + self.md.n_yq)
            i = np.clip(d, 0, n - 1)
            prev = th[np.maximum(i - self.md.nu, 0)]
            rate = np.where(d >= self.md.nu, th[i] - prev, th[i])
            plain = th[np.minimum(q, n - 1)] if yv is None else np.where(
                q < n, th[np.minimum(q, n - 1)], yv[np.clip(q - n, 0, self.md.n_yq - 1)])
            return np.where(d >= 0, rate, plain)
        if yv is None:
            return th[q]
        return np.where(q < n, th[np.minimum(q, n - 1)], yv[np.maximum(q - n, 0)])

    def _is_output(self):
        q, n = self.md.row_q, self.md.n
        return (q >= n) & (q < n + self.md.n_yq)

    def _excess(self, th, gam):
        """Mirror of row_excess() and tol_scale() for every row: (M th - gamma, max(1, |gamma|))."""
        yv = self._predict(th) if self.has_out else None
        v = self._values(th, yv)
        sg = self.md.row_sign
        ag = np.abs(gam)
        return np.where(sg > 0, v - gam, -v - gam), np.where(ag > self.one, ag, self.one)

    def _violated(self, th, gam):
        viol, scale = self._excess(th, gam)
        return viol > self.tol * scale

    @staticmethod
    def _drop_negative(W, z, guess):
        """Mirror of drop_negative(): (kept rows, 0 none dropped / 1 dropped / -1 give up)."""
        keep = z >= 0
        if np.all(keep):
            return W, 0
        kept = W[keep]
        give_up = kept.size == 0 or (guess and 2 * kept.size < W.size)
        return kept, (-1 if give_up else 1)

    def _violated_outside(self, th, gam, W):
        """Mirror of violated_outside(): violated input rows first, output rows only if none."""
        viol = self._violated(th, gam)
        viol[W] = False
        box = ~self._is_output()
        first = np.flatnonzero(viol & box)
        return first if first.size else np.flatnonzero(viol)

    def _correct(self, th0, rows, mult):
        sel = mult > 0
        rows, mult = rows[sel], mult[sel]
        return th0 - seqsum_rows(self.EM[:, rows] * mult[None, :])

    def _sweep(self, S, K, lam):
        e2 = self.zero
        diverged = False
        om = self.omega
        for r in S:
            mask = (S != r) & (lam[S] > 0)
            others = S[mask]
            acc = seqsum(self.H[r, others] * lam[others])
            t = -(K[r] + acc) / self.Hdiag[r]
            if self.soft_w[r] > 0 and t > self.soft_l1[r]:  # piecewise maximum
                t = (self.soft_l1[r] * self.soft_w[r] - (K[r] + acc)) / (self.Hdiag[r] + self.soft_w[r])
            wv = (self.one - om) * lam[r] + om * t
            nl = wv if wv > 0 else self.zero
            d = nl - lam[r]
            e2 = e2 + d * d
            lam[r] = nl
            if not nl <= self.limit:
                diverged = True
        return e2, diverged

    def _primal_solve(self, th0, W):
        """Mirror of primal_solve(): bounds, then the cheaper form; (ok, th, z or None)."""
        md = self.md
        n, dt = md.n, md.Kx.dtype
        th = np.zeros(n, dt)
        dv = np.zeros(n, dt)
        qW = md.row_q[W]
        if np.unique(qW).size != qW.size:
            return False, None, None
        th[qW] = np.where(md.row_sign[W] > 0, self.row_c[W], -self.row_c[W])
        dv[qW] = th[qW] - th0[qW]
        bound = np.zeros(n, bool)
        bound[qW] = True
        if W.size < n - W.size:
            return self._primal_bound(th0, W, qW, th, dv, bound)
        return self._primal_free(th0, W, th, dv, bound)

    def _primal_free(self, th0, W, th, dv, bound):
        """Mirror of primal_solve_free()."""
        md = self.md
        nt, dt = md.nt, md.Kx.dtype
        F = np.flatnonzero(~bound)
        B = np.flatnonzero(bound)
        nf = F.size
        rhs = np.empty(nf, dt)
        for a, f in enumerate(F):
            rhs[a] = -s_row_dots(self.S, [f], dv)[0]  # dv is 0 on the free inputs here
        Y = np.ascontiguousarray(md.V[:, F]) if nt else np.zeros((0, nf), dt)
        if nf:
            chol = np.concatenate([self.S[F[a], F[:a + 1]] for a in range(nf)])
            if not cholesky_packed(chol, nf):
                return False, None, None
            chol_solve_packed(chol, nf, rhs)
            for o in range(nt):
                chol_solve_packed(chol, nf, Y[o])
        nu = np.zeros(nt, dt)
        if nt:
            small = np.empty(nt * (nt + 1) // 2, dt)
            for o in range(nt):
                for p in range(o + 1):
                    small[o * (o + 1) // 2 + p] = (seqsum(md.V[o, F] * Y[p])
                                                   + md.P2inv[o, p])
                nu[o] = seqsum(np.concatenate((md.V[o, F] * rhs, md.V[o, B] * dv[B])))
            if not cholesky_packed(small, nt):
                return False, None, None
            chol_solve_packed(small, nt, nu)
        for a, f in enumerate(F):
            dv[f] = seqsum(-(Y[:, a] * nu), start=rhs[a])
            th[f] = th0[f] + dv[f]
        self._free_state = (dv, nu)
        return True, th, None

    def _free_multipliers(self, W):
        """Mirror of free_multipliers() for the last free-form solve."""
        md = self.md
        dv, nu = self._free_state
        qW = md.row_q[W]
        g = s_row_dots(self.S, qW, dv)
        g = np.add.accumulate(np.hstack((g[:, None], md.V[:, qW].T * nu[None, :])), axis=1)[:, -1]
        return np.where(md.row_sign[W] > 0, -g, g)

    def _primal_bound(self, th0, W, qW, th, dv, bound):
        """Mirror of primal_solve_bound() (through S^-1; few bound inputs)."""
        md = self.md
        nt, dt, nb = md.nt, md.Kx.dtype, W.size
        chol = np.concatenate([self.Sinv[qW[a], qW[:a + 1]] for a in range(nb)])
        x1 = dv[qW].copy()
        Y = np.ascontiguousarray(md.Uv[:, qW]) if nt else np.zeros((0, nb), dt)
        if not cholesky_packed(chol, nb):
            return False, None, None
        chol_solve_packed(chol, nb, x1)
        for o in range(nt):
            chol_solve_packed(chol, nb, Y[o])
        nu = np.zeros(nt, dt)
        if nt:
            small = np.empty(nt * (nt + 1) // 2, dt)
            for o in range(nt):
                for p in range(o + 1):
                    small[o * (o + 1) // 2 + p] = md.T[o, p] - seqsum(md.Uv[o, qW] * Y[p])
                nu[o] = seqsum(md.Uv[o, qW] * x1)
            if not cholesky_packed(small, nt):
                return False, None, None
            chol_solve_packed(small, nt, nu)
        beta = np.array([seqsum(Y[:, a] * nu, start=x1[a]) for a in range(nb)], dt)
        z = np.where(md.row_sign[W] > 0, -beta, beta)
        F = np.flatnonzero(~bound)
        d = seqsum_rows(np.hstack((self.Sinv[np.ix_(F, qW)] * beta[None, :],
                                   -(md.Uv[:, F].T * nu[None, :]))))
        th[F] = th0[F] + d
        return True, th, z

    def _factor(self, W, start=0, chol=None):
        """Mirror of factor_working_set(): rows start.. of chol(H_WW + w of the slack rows);
        (ok, packed factor)."""
        nw = len(W)
        if chol is None:
            chol = np.zeros(nw * (nw + 1) // 2 + nw + 1, self.md.Kx.dtype)
        for i in range(start, nw):
            tri = i * (i + 1) // 2
            chol[tri:tri + i + 1] = self.H[W[i], W[:i + 1]]
            if self.slack_on[W[i]]:
                chol[tri + i] = chol[tri + i] + self.soft_w[W[i]]
        return cholesky_packed(chol, nw, start=start), chol

    def _dual_solve(self, W, K):
        """Mirror of dual_solve(): returns (ok, z)."""
        nw = W.size
        ok, chol = self._factor(W)
        if not ok:
            return False, None
        z = -K[W]
        on = self.slack_on[W]
        z[on] = z[on] + self.soft_l1[W][on] * self.soft_w[W][on]
        chol_solve_packed(chol, nw, z)
        return True, z

    def _slack_in_set(self, W, z):
        """Mirror of slack_in_set() for the working set: (z - l1) w where slack, else 0."""
        sl = (z - self.soft_l1[W]) * self.soft_w[W]
        return np.where(self.slack_on[W], sl, self.zero)

    def _switch_states(self, W, z):
        """Mirror of switch_states(): flip the rows whose multiplier crossed l1; count."""
        l1, on = self.soft_l1[W], self.slack_on[W]
        flip = (self.soft_w[W] > 0) & np.where(on, z < l1, z > l1)
        self.slack_on[W[flip]] = ~on[flip]
        return int(np.count_nonzero(flip))

    def _set_states(self, W, lam_of_W):
        """Mirror of set_state() for rows joining with these multipliers."""
        self.slack_on[W] = (self.soft_w[W] > 0) & (lam_of_W > self.soft_l1[W])

    def _holds(self, W, z, viol, scale):
        """Mirror of working_set_holds() (violated_in_set() with soft rows), from the
        rows' excess and tolerance scale at th (_excess())."""
        if self.soft:
            return not np.any(viol[W] - self._slack_in_set(W, z) > self.tol * scale[W])
        return not np.any((viol > self.tol * scale)[W])

    def _polish(self, W, lam, th0, K, gam, guess=False):
        """Mirror of polish() from working set W; returns (ok, th, active, iterations)."""
        md = self.md
        n = md.n
        its = 0
        if W.size == 0 or W.size > self.wcap:
            return False, None, 0, its
        for _ in range(self.polish_max):
            its += 1
            box_only = bool(np.all(md.row_q[W] < n))
            if box_only:
                ok, th, z = self._primal_solve(th0, W)
                if not ok:
                    return False, None, 0, its
                add = self._violated_outside(th, gam, W)
                if add.size == 0:
                    if z is None:
                        z = self._free_multipliers(W)
                    W, dropped = self._drop_negative(W, z, guess)
                    if dropped < 0:
                        return False, None, 0, its
                    if dropped:
                        continue
                    lam[:] = 0
                    lam[W] = z
                    return True, th, W.size, its
            else:
                ok, z = self._dual_solve(W, K)
                if not ok:
                    return False, None, 0, its
                if self.soft and self._switch_states(W, z):
                    continue
                W, dropped = self._drop_negative(W, z, guess)
                if dropped < 0:
                    return False, None, 0, its
                if dropped:
                    continue
                th = self._correct(th0, W, z)
                add = self._violated_outside(th, gam, W)
                if add.size == 0:
                    if not self._holds(W, z, *self._excess(th, gam)):  # working_set_holds()
                        ok, th, z = self._refine_dual(W, z, th0, K, gam, th)
                        if not ok:
                            return False, None, 0, its
                    lam[:] = 0
                    lam[W] = z
                    return True, th, W.size, its
            if add.size > self.wcap - W.size:
                return False, None, 0, its
            self.slack_on[add] = False  # joining rows start tight
            W = np.union1d(W, add).astype(W.dtype)
        return False, None, 0, its

    def _refine_dual(self, W, z, th0, K, gam, th):
        """Mirror of refine_dual(): (ok, th, z) after up to two refinement rounds."""
        nw = W.size
        chol = self._factor(W)[1]  # the factor dual_solve() left in ws->chol
        for _ in range(2):
            e = self._excess(th, gam)[0][W]
            if self.soft:
                e = e - self._slack_in_set(W, z)
            chol_solve_packed(chol, nw, e)
            z = z + e
            if np.any(z < 0) or (self.soft and self._switch_states(W, z)):
                return False, th, z
            th = self._correct(th0, W, z)
            exc, scale = self._excess(th, gam)
            if self._holds(W, z, exc, scale):
                viol = exc > self.tol * scale
                viol[W] = False  # violated_outside(): the rows outside W
                return (not np.any(viol)), th, z
        return False, th, z

    # -- the dual active-set solve (Goldfarb-Idnani) ------------------------------------
    def _most_violated(self, th, gam, in_set):
        """Mirror of most_violated(): first row of largest relative violation, or -1."""
        viol, scale = self._excess(th, gam)
        cand = (~in_set) & (viol > self.tol * scale)
        if not np.any(cand):
            return -1
        rel = np.where(cand, viol / scale, self.zero)
        return int(np.argmax(rel))

    def _add_to_set(self, p, st):
        """Mirror of add_to_set() on the state dict st (W, z, L, steps, in_set)."""
        dt = self.md.Kx.dtype
        hpp = self.Hdiag[p]
        lp = self.zero
        wp, l1p, p_on = self.soft_w[p], self.soft_l1[p], False
        while True:
            st["steps"] += 1
            if st["steps"] > self.active_set_max:
                return -1
            W, z, L = st["W"], st["z"], st["L"]
            nw = len(W)
            h = self.H[W, p].astype(dt) if nw else np.zeros(0, dt)
            viol = seqsum(-(h * z), start=-st["K"][p] - hpp * lp)
            y = h.copy()
            chol_lsolve_packed(L, nw, y)
            zeta = seqsum(-(y * y), start=hpp)
            d = y.copy()
            chol_ltsolve_packed(L, nw, d)
            k, tblock, event = -1, self.zero, 0
            if self.soft:
                k, tblock, event = self._first_event(W, z, d)
                if p_on:
                    zeta = zeta + wp
                    viol = viol - (lp - l1p) * wp
                elif wp > 0:
                    tp = l1p - lp if l1p > lp else self.zero
                    if k < 0 or tp < tblock:
                        k, tblock, event = nw, tp, 2
            else:
                for i in range(nw):
                    if d[i] > 0:
                        ratio = z[i] / d[i]
                        if k < 0 or ratio < tblock:
                            k, tblock = i, ratio
            dependent = nw == self.wcap or not zeta > self.dep_tol * hpp
            if dependent and k < 0:
                return 1
            t = tblock if dependent else viol / zeta
            if not dependent:
                if k >= 0 and tblock < t:
                    t = tblock
                else:
                    k = -1
            z = z - t * d
            lp = lp + t
            if k < 0:
                tri = nw * (nw + 1) // 2
                L[tri:tri + nw] = y
                L[tri + nw] = np.sqrt(zeta)
                st["W"] = W + [p]
                st["z"] = np.concatenate((z, np.array([lp], dt)))
                st["in_set"][p] = True
                self.slack_on[p] = p_on
                return 0
            if event == 2:
                p_on = True
                st["z"] = z
                continue
            if event == 1:  # row k's diagonal gains or loses w: refactor from it
                self.slack_on[W[k]] = not self.slack_on[W[k]]
                st["z"] = z
                if not self._factor(W, start=k, chol=L)[0]:
                    return -1
                continue
            st["in_set"][W[k]] = False
            self.slack_on[W[k]] = False
            W = W[:k] + W[k + 1:]
            z = np.delete(z, k)
            st["W"], st["z"] = W, z
            if not self._factor(W, start=k, chol=L)[0]:
                return -1

    def _first_event(self, W, z, d):
        """The soft add_to_set()'s scan: (k, tblock, event) of the first multiplier to reach
        0 (event 0) or to cross l1 (event 1), ratios clamped at 0; k = -1 if none."""
        k, tblock, event = -1, self.zero, 0
        for i, r in enumerate(W):
            ev, ratio = 0, None
            if d[i] > 0:
                ev = int(self.slack_on[r])
                ratio = (z[i] - self.soft_l1[r] if ev else z[i]) / d[i]
            elif d[i] < 0 and self.soft_w[r] > 0 and not self.slack_on[r]:
                ev = 1
                ratio = (self.soft_l1[r] - z[i]) / -d[i]
            if ratio is not None:
                ratio = ratio if ratio > 0 else self.zero
                if k < 0 or ratio < tblock:
                    k, tblock, event = i, ratio, ev
        return k, tblock, event

    def _dual_active_set(self, lam, th0, K, gam):
        """Mirror of dual_active_set(): (code 0/1/-1, th, active, steps + polish its)."""
        md = self.md
        st = {"W": [], "z": np.zeros(0, md.Kx.dtype), "steps": 0, "K": K,
              "L": np.zeros(self.wcap * (self.wcap + 1) // 2 + self.wcap + 1, md.Kx.dtype),
              "in_set": np.zeros(md.m, bool)}
        th = th0.copy()
        code = 0
        self.slack_on[:] = False
        while True:
            p = self._most_violated(th, gam, st["in_set"])
            if p < 0:
                break
            code = self._add_to_set(p, st)
            if code != 0:
                break
            th = self._correct(th0, np.array(st["W"], np.int64), st["z"])
        if not st["W"]:
            if code == 0:
                lam[:] = 0
            return code, th, 0, st["steps"]
        W = np.sort(np.array(st["W"], np.int64))
        ok, th_p, act, its = self._polish(W, lam, th0, K, gam)
        if ok:
            return 0, th_p, act, st["steps"] + its
        return (1 if code == 1 else -1), th0, 0, st["steps"] + its

    # -- the solve -------------------------------------------------------------------
    def solve(self, x, r):
        """Returns (status, U, iterations, polish_iterations, active)."""
        md, dt = self.md, self.dt
        x = np.asarray(x, md.Kx.dtype)
        r = np.asarray(r, md.Kx.dtype)
        lam = self.lam
        th0, px = self._unconstrained(x, r)
        yv0 = self._predict(th0) if self.has_out else None
        v = self._values(th0, yv0)
        q, sg, n = md.row_q, md.row_sign, md.n
        gam = self.row_c.copy()
        if self.has_out:
            out = self._is_output()
            pxr = px[np.clip(q - n, 0, md.n_yq - 1)]
            gam = np.where(out, np.where(sg > 0, gam - pxr, gam + pxr), gam)
        if self.has_rate:  # first-stage Δu rows: gamma carries u_prev (last nu states)
            d = q - (n + md.n_yq)
            first = (d >= 0) & (d < md.nu)
            up = x[md.nx - md.nu + np.clip(d, 0, md.nu - 1)]
            gam = np.where(first, np.where(sg > 0, gam + up, gam - up), gam)
        K = np.where(sg > 0, gam - v, gam + v)
        if not np.any(K < 0):
            lam[:] = 0
            return self._finish(th0, th0, OPTIMAL) + (0, 0, 0)
        total, polish_its, active = 0, 0, 0
        if self.polish_on and self.polish_first:
            shifted = np.flatnonzero(lam[md.row_next] > 0)
            seeds = ([(shifted, True)] if self.warm else []) + [(np.flatnonzero(K < 0), False)]
            for W, guess in seeds:
                # seed_shifted()/seed_from_violated(): slack where the shifted lam > l1
                self._set_states(W, lam[md.row_next[W]] if guess else np.zeros(W.size, lam.dtype))
                ok, th_p, act, its = self._polish(W, lam, th0, K, gam, guess)
                polish_its += its
                if ok:
                    status, U = self._finish(th_p, th0, OPTIMAL)
                    return status, U, 0, polish_its, act
        if self.active_set:
            code, th_a, act, its = self._dual_active_set(lam, th0, K, gam)
            polish_its += its
            if code >= 0:
                status, U = self._finish(th_a, th0, OPTIMAL if code == 0 else INFEASIBLE)
                return status, U, 0, polish_its, act
        in_set = (K < self.sigma) if self.reduced else np.ones(md.m, bool)
        if not self.warm:
            lam[:] = 0
        lam[~in_set] = 0
        S = np.flatnonzero(in_set)
        status = MAX_ITER
        th = th0
        while True:
            converged = diverged = False
            chunk = self.polish_every if self.polish_on else self.max_iter
            t = 0
            while t < chunk and total < self.max_iter:
                e2, diverged = self._sweep(S, K, lam)
                total += 1
                t += 1
                if diverged:
                    break
                if e2 < self.delta:
                    converged = True
                    break
            if diverged:
                status = INFEASIBLE
                break
            th = self._correct(th0, S, lam[S])
            if self.polish_on:
                seed = S[lam[S] > 0]
                self._set_states(seed, lam[seed])  # seed_from_multipliers()
                ok, th_p, act, its = self._polish(seed, lam, th0, K, gam)
                polish_its += its
                if ok:
                    th, active, status = th_p, act, OPTIMAL
                    break
            exc, scale = self._excess(th, gam)
            viol = exc > self.tol * scale
            if self.soft:  # violated_beyond_slack(): beyond the slack of the multiplier
                sl = slacks(lam, self.soft_l1, self.soft_w)
                nviol = int(np.count_nonzero(exc - sl > self.tol * scale))
            else:
                nviol = int(np.count_nonzero(viol))
            added = 0
            if self.reduced and nviol:
                new = viol & ~in_set
                added = int(np.count_nonzero(new))
                in_set |= new
            if converged and nviol == 0:
                status = OPTIMAL
                break
            if total >= self.max_iter:
                status = MAX_ITER
                break
            if converged and added == 0:
                status = INACCURATE
                break
            if added:
                S = np.flatnonzero(in_set)
        if active == 0:
            active = int(np.count_nonzero(lam > 0))
        status, U = self._finish(th, th0, status)
        return status, U, total, polish_its, active

    def _finish(self, th, th0, status):
        md = self.md
        src = th
        if not np.all(np.isfinite(th)):
            status = NUMERICAL
            src = th0 if np.all(np.isfinite(th0)) else np.zeros_like(th0)
        lo = np.tile(self.u_min, md.n // md.nu)  # per stage, or per block
        hi = np.tile(self.u_max, md.n // md.nu)
        U = np.where(src < lo, lo, np.where(src > hi, hi, src))
        if status != OPTIMAL:
            self.lam[:] = 0
        if self.soft:  # the plan's slacks (finish()): 0 unless optimal
            sl = slacks(self.lam, self.soft_l1, self.soft_w)
            self.slack_max = sl.max(initial=self.zero)
            self.slack_rows = int(np.count_nonzero(sl > 0))
        return status, U
