"""Seeded random MPC configurations and QP instances for the reliability campaigns.

The C API solves only the QPs of a configured MPC, so "random QPs" are drawn as random
*controllers* (plant, weights, bounds, horizon) whose condensed QP has the wanted size
and conditioning, plus random states and reference previews for each of them.

Three kinds of plant:

* ``generic``: a random discrete (or continuous, sampled) state-space plant, stable,
  marginally stable or unstable, 1-2 inputs and outputs;
* ``delay``: a pure delay chain ``y_{k+1} = b u_{k+1-d}``.  With ``y_max = b u_max`` the
  output rows are *identical* to input rows (linearly dependent active sets), and for
  d >= 2 the first output rows have an all-zero left-hand side (a zero row of M);
* ``twin_outputs``: two outputs with ``y_2 = s y_1`` and bounds scaled alike, so output
  rows come in dependent pairs.

cond(E) is steered by the input weight: with ``G = Gamma' Omega Gamma``,
``E = 2(R + G)`` and ``cond(E) ~ (rho + lmax(G)) / (rho + lmin(G))`` for ``R = rho I``.
Everything is a pure function of the seed; the YAML written for a config is its
reproducer.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import yaml

from ..config import ConfigError, parse
from ..qp.condense import condense
from ..model.observer import observer_gain
from ..model.plant import discretise
from ..qp.work import UNBOUNDED_WORK

KINDS = ("generic", "delay", "twin_outputs")
COND_DECADES = 7  # cond(E) targets span 1e0 .. 1e7


@dataclass(frozen=True)
class RandomConfig:
    """One drawn controller: its YAML-ready dict and what was drawn."""

    seed: int
    kind: str
    data: dict  # the config, plain Python types (yaml.safe_dump-able)
    cond_target: float
    y_scale: float = 1.0  # output bounds are about +-y_scale
    meta: dict = field(default_factory=dict)

    def yaml(self) -> str:
        return yaml.safe_dump(self.data, sort_keys=False)


def _plain(a) -> list:
    return np.asarray(a, dtype=float).tolist()


def _random_dynamics(rng: np.random.Generator, nx: int, N: int) -> np.ndarray:
    """Discrete A with random (possibly complex, possibly unstable) eigenvalues.

    Unstable radii are capped so that |lambda|^N <= 30: the free response over the
    horizon stays representable with output bounds of order 1.
    """
    regime = rng.choice(["stable", "marginal", "unstable"], p=[0.5, 0.25, 0.25])
    rmax = min(1.08, 30.0 ** (1.0 / N))
    eig_blocks, k = [], 0
    while k < nx:
        if regime == "unstable" and k == 0:
            rad = rng.uniform(1.005, max(1.006, rmax))
        elif regime == "marginal" and k == 0:
            rad = 1.0
        else:
            rad = rng.uniform(0.2, 0.97)
        if k + 1 < nx and rng.random() < 0.4:
            th = rng.uniform(0.05, 1.2)
            a, b = rad * np.cos(th), rad * np.sin(th)
            eig_blocks.append(np.array([[a, b], [-b, a]]))
            k += 2
        else:
            eig_blocks.append(np.array([[rad * rng.choice([1.0, 1.0, 1.0, -1.0])]]))
            k += 1
    J = np.zeros((nx, nx))
    i = 0
    for blk in eig_blocks:
        s = blk.shape[0]
        J[i:i + s, i:i + s] = blk
        i += s
    Qo, _ = np.linalg.qr(rng.normal(size=(nx, nx)))
    T = Qo @ np.diag(10.0 ** rng.uniform(-0.5, 0.5, nx))
    return T @ J @ np.linalg.inv(T)


def _base(prefix: str, precision: str, N: int, Ts: float, n_out: int, n_act: int) -> dict:
    outputs = [f"y{i}" for i in range(n_out)]
    actuators = [f"u{i}" for i in range(n_act)]
    # no work budget: the campaigns measure what the solver reaches, not when
    return {"prefix": prefix, "precision": precision, "sample_time": Ts, "horizon": int(N),
            "outputs": outputs, "actuators": actuators, "modes": [],
            "solver": {"work_budget": UNBOUNDED_WORK},
            "simulation": {"schedule_source": "output"}}


def _hessian_spectrum(data: dict) -> tuple[float, float, object]:
    """(lmin, lmax) of G = Gamma' Omega Gamma for the config's mode 0, and the QP.

    Raises ConfigError (as the generator would) for a draw it cannot use.
    """
    cfg = parse(data)
    mode = cfg.modes[0]
    plant = discretise(mode, cfg.sample_time, "modes[0]")
    observer_gain(plant, mode, "modes[0]")
    qp = condense(plant, mode, cfg.horizon, "modes[0]")
    G = qp.Gamma.T @ qp.Omega @ qp.Gamma
    eig = np.linalg.eigvalsh(0.5 * (G + G.T))
    return float(max(eig.min(), 0.0)), float(eig.max()), qp


def _rho_for(cond: float, lmin: float, lmax: float) -> float:
    """Input weight rho with (rho + lmax)/(rho + lmin) = cond (or the nearest reachable)."""
    if cond <= 1.0 + 1e-9:
        return lmax * 1e6
    rho = (lmax - cond * lmin) / (cond - 1.0)
    # unreachable (G alone is better conditioned than asked): the same order as lmax/cond
    return rho if rho > 0 else lmax / cond


def draw_instance(rng: np.random.Generator, qp, y_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """A state x (outputs within about +-y_scale) and a stepped reference preview r."""
    ny, N = qp.ny, qp.N
    C = qp.Phi[:ny]  # C A; the free response of the first step
    z = rng.normal(size=qp.nx)
    yz = np.abs(C @ z).max()
    x = z * (rng.uniform(0.0, 1.0) * y_scale / yz if yz > 0 else 0.0)
    r = np.empty((N, ny))
    for a in range(ny):
        cuts = np.sort(rng.integers(0, N, size=rng.integers(0, 3)))
        levels = rng.uniform(-1.6, 1.6, size=cuts.size + 1) * y_scale
        seg = np.searchsorted(cuts, np.arange(N), side="right")
        r[:, a] = levels[seg]
    return x, r.ravel()


def _finish_bounds(data: dict, rng: np.random.Generator, qp, nu: int, y_scale: float,
                   mode_bounds: dict) -> None:
    """Input bounds from the unconstrained solutions of typical instances."""
    if "u_max" not in mode_bounds:
        th = []
        for _ in range(48):
            x, r = draw_instance(rng, qp, y_scale)
            th.append((qp.Kx @ x + qp.Kr @ r).reshape(qp.N, nu))
        th = np.abs(np.array(th))  # (samples, N, nu)
        typical = np.median(th.max(axis=1), axis=0)  # per input
        tau = rng.uniform(1.0, 4.0, size=nu)
        u_max = np.maximum(typical / tau, 1e-3)
        mode_bounds["u_max"] = _plain(u_max)
        mode_bounds["u_min"] = _plain(-u_max * rng.uniform(0.3, 1.0, size=nu))
    data["modes"][0]["bounds"] = mode_bounds


def random_config(seed: int, prefix: str = "rq", precision: str = "double",
                  kind: str | None = None, n_max: int = 100,
                  cond_decade: int | None = None) -> RandomConfig:
    """Draw one single-mode controller; ``cond_decade`` d targets cond(E) in [1e d, 1e(d+1))."""
    rng = np.random.default_rng(seed)
    kind = kind or str(rng.choice(KINDS, p=[0.7, 0.15, 0.15]))
    decade = int(rng.integers(0, COND_DECADES)) if cond_decade is None else int(cond_decade)
    cond = float(10.0 ** (decade + rng.uniform(0.0, 1.0)))
    y_scale = 1.0
    for _attempt in range(50):
        try:
            data, meta = _draw_plant(rng, kind, prefix, precision, n_max)
        except _Retry:
            continue
        mode = data["modes"][0]
        nu = len(mode["actuators"])
        mode["weights"]["R"] = 1.0
        try:
            lmin, lmax, qp = _hessian_spectrum(data)
            for _ in range(3):  # too well conditioned for the target: a heavier terminal weight
                if lmin <= 0 or lmax / lmin >= 2.0 * cond:
                    break
                boost = 4.0 * cond * lmin / lmax
                mode["weights"]["P"] = _plain(np.asarray(mode["weights"]["P"]) * boost)
                lmin, lmax, qp = _hessian_spectrum(data)
        except ConfigError:  # uncontrollable, unobservable, no observer: draw again
            continue
        rho = _rho_for(cond, lmin, lmax)
        spread = 10.0 ** rng.uniform(-0.2, 0.2, size=nu) if nu > 1 else np.ones(1)
        mode["weights"]["R"] = _plain(rho * spread)
        try:
            _, _, qp = _hessian_spectrum(data)
        except ConfigError:
            continue
        _finish_bounds(data, rng, qp, nu, y_scale, meta.pop("bounds"))
        parse(data)  # must be a valid config
        return RandomConfig(seed=seed, kind=kind, data=data, cond_target=cond,
                            y_scale=y_scale, meta=meta)
    raise RuntimeError(f"seed {seed}: no valid {kind} config in 50 draws")


class _Retry(Exception):
    pass


def _draw_plant(rng: np.random.Generator, kind: str, prefix: str, precision: str,
                n_max: int) -> tuple[dict, dict]:
    """Plant, horizon, output weights and (partial) bounds of one mode."""
    if kind == "generic":
        nu = int(rng.choice([1, 1, 1, 2]))
        ny = 1 if nu == 1 else int(rng.choice([1, 2]))
    elif kind == "delay":
        nu, ny = 1, 1
    else:
        nu, ny = 2, 2
    n_target = int(rng.choice([8, 16, 24, 40, 60, 80, 100]))
    N = max(2, min(n_target, n_max) // nu)
    Ts = 0.05
    data = _base(prefix, precision, N, Ts, ny, nu)
    bounds: dict = {}
    plant: dict
    if kind == "generic":
        nx = int(rng.integers(1, 6))
        if rng.random() < 0.75:
            A = _random_dynamics(rng, nx, N)
            plant = {"state_space": {"A": _plain(A), "B": _plain(rng.normal(size=(nx, nu))),
                                     "C": _plain(rng.normal(size=(ny, nx))), "discrete": True}}
        else:  # continuous, sampled by the generator (ZOH), optionally with integrators
            Ac = rng.normal(size=(nx, nx))
            Ac = Ac - (np.max(np.linalg.eigvals(Ac).real) + rng.uniform(-0.5, 3.0)) * np.eye(nx)
            plant = {"state_space": {"A": _plain(Ac), "B": _plain(rng.normal(size=(nx, nu))),
                                     "C": _plain(rng.normal(size=(ny, nx)))},
                     "integrator": bool(rng.random() < 0.4)}
        sides = rng.choice(["both", "upper", "none"], p=[0.6, 0.2, 0.2])
        if sides != "none":
            bounds["y_max"] = _plain(rng.uniform(0.7, 1.3, size=ny))
        if sides == "both":
            bounds["y_min"] = _plain(-rng.uniform(0.7, 1.3, size=ny))
    elif kind == "delay":
        d = int(rng.integers(1, 4))
        b = float(rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-0.5, 0.5))
        A = np.diag(np.ones(d - 1), -1)
        B = np.zeros((d, 1))
        B[0, 0] = 1.0
        C = np.zeros((1, d))
        C[0, -1] = b
        plant = {"state_space": {"A": _plain(A), "B": _plain(B), "C": _plain(C),
                                 "discrete": True}}
        u_max = float(10.0 ** rng.uniform(-0.5, 0.5))
        u_min = -u_max * float(rng.uniform(0.3, 1.0))
        bounds = {"u_min": u_min, "u_max": u_max}
        # y = b u (delayed): the same bounds on y make output rows copies of input rows
        lo, hi = sorted((b * u_min, b * u_max))
        bounds["y_min"], bounds["y_max"] = lo, hi
    else:
        nx = int(rng.integers(1, 5))
        A = _random_dynamics(rng, nx, N)
        c = rng.normal(size=nx)
        s = float(rng.choice([1.0, 2.0, -1.0, 0.5]))
        C = np.vstack([c, s * c])
        plant = {"state_space": {"A": _plain(A), "B": _plain(rng.normal(size=(nx, nu))),
                                 "C": _plain(C), "discrete": True}}
        y_hi = float(rng.uniform(0.7, 1.3))
        y_lo = -float(rng.uniform(0.7, 1.3))
        lo2, hi2 = sorted((s * y_lo, s * y_hi))
        bounds["y_min"], bounds["y_max"] = [y_lo, lo2], [y_hi, hi2]
    Q = 10.0 ** rng.uniform(-1.0, 1.0, size=ny)
    P = Q * (10.0 ** rng.uniform(0.0, 3.0) if rng.random() < 0.6 else 1.0)
    data["modes"].append({
        "name": "m0", "actuators": list(data["actuators"]), "plant": plant,
        "weights": {"Q": _plain(Q), "R": 1.0, "P": _plain(P)}, "bounds": {"u_min": -1.0,
                                                                          "u_max": 1.0}})
    return data, {"bounds": bounds, "N": N, "nu": nu, "ny": ny}


def random_controller(seed: int, n_modes: int = 1, horizon: int = 8, method: str = "hildreth_plus_prime",
                      polish: bool = True, warm_start: bool = True, max_iterations: int = 200,
                      prefix: str = "fz", precision: str = "double") -> dict:
    """A valid random (switched) controller config, for property-based fuzzing.

    Each mode drives its own 1-2 actuators; outputs (1-2) are shared; plants are random
    discrete state-space models (or a SISO transfer function); 2 modes get a hysteresis
    scheduler on the first output.  Draws that the generator rejects are redrawn.
    """
    from ..pipeline import build_model

    rng = np.random.default_rng(seed)
    for _attempt in range(100):
        ny = int(rng.integers(1, 3))
        nus = [int(rng.integers(1, 3)) for _ in range(n_modes)]
        data = _base(prefix, precision, horizon, float(rng.choice([0.01, 0.05, 0.1])), ny,
                     sum(nus))
        first = 0
        for j, nu in enumerate(nus):
            acts = data["actuators"][first:first + nu]
            first += nu
            if nu == 1 and ny == 1 and rng.random() < 0.3:
                den = np.poly(-rng.uniform(0.5, 20.0, size=int(rng.integers(1, 4))))
                plant = {"transfer_function": {"num": [float(rng.uniform(0.5, 10.0))],
                                               "den": _plain(den)},
                         "integrator": bool(rng.random() < 0.5)}
            else:
                nx = int(rng.integers(1, 5))
                plant = {"state_space": {"A": _plain(_random_dynamics(rng, nx, horizon)),
                                         "B": _plain(rng.normal(size=(nx, nu))),
                                         "C": _plain(rng.normal(size=(ny, nx))),
                                         "discrete": True}}
            u_max = rng.uniform(0.5, 5.0, size=nu)
            bounds = {"u_min": _plain(-u_max * rng.uniform(0.2, 1.0, size=nu)),
                      "u_max": _plain(u_max)}
            if rng.random() < 0.6:
                bounds["y_min"] = _plain(-rng.uniform(1.0, 5.0, size=ny))
                bounds["y_max"] = _plain(rng.uniform(1.0, 5.0, size=ny))
            Q = 10.0 ** rng.uniform(-1, 1, size=ny)
            data["modes"].append({
                "name": f"m{j}", "actuators": acts, "plant": plant,
                "weights": {"Q": _plain(Q), "R": _plain(10.0 ** rng.uniform(-2, 1, size=nu)),
                            "P": _plain(Q * 10.0 ** rng.uniform(0, 3))},
                "bounds": bounds})
        if n_modes == 2:
            half = float(rng.uniform(0.5, 2.0))
            data["scheduler"] = {"signal": "s", "lower": -half, "upper": half,
                                 "epsilon": float(rng.uniform(0.0, 0.4) * half),
                                 "inside": "m0", "outside": "m1"}
        data["solver"] = {"method": method, "polish": polish, "warm_start": warm_start,
                          "max_iterations": max_iterations, "work_budget": UNBOUNDED_WORK,
                          "omega": float(rng.uniform(1.0, 1.6)),
                          "sigma": float(rng.uniform(0.0, 1.0))}
        try:
            build_model(parse(data))
        except ConfigError:
            continue
        return data
    raise RuntimeError(f"seed {seed}: no valid controller in 100 draws")
