"""``modes[].constraints``: constrained signals, mixed rows and the terminal constraint.

* ``signals: {name: {C, D, min, max, stages, soft}}``: a scalar signal z = C x + D u,
  measured or not, bounded like an output;
* ``mixed: {name: {E, F, g, stages, soft}}``: rows E x + F u <= g, one scalar signal each
  (``name[i]``), upper bounds only;
* ``terminal``: ``lqr_invariant``, ``equality``, or ``{kind: polytope, H, h}``
  (:class:`~.schema.TerminalConfig`).

x is the plant's state as the ``state_space`` plant writes it (then one integrator per
output with ``integrator: true``: C may leave those columns out); a transfer-function
plant's states are the generator's realisation, so only its inputs (D, F) can be named.
``stages`` are the times k of x_k and u_k: 1..N without a D (F) term, 0..N-1 with one
(u_N does not exist); the default is all of them.  docs/features.md, "General constraints".
"""
from __future__ import annotations

import math

import numpy as np

from .errors import ConfigError
from .reader import IDENTIFIER, Reader, read_matrix, read_number, read_vector
from .schema import (CONSTRAINT_KEYS, MIXED_KEYS, PENALTY_KEYS, SIGNAL_KEYS, TERMINAL_KEYS,
                     TERMINAL_KINDS, PlantConfig, SignalConstraint, TerminalConfig, UNBOUNDED)


def plant_states(plant: PlantConfig, ny: int) -> int | None:
    """States a constraint's C (E, H) may name: the state_space plant's, then its
    integrators; None for a transfer function (its states are the generator's)."""
    if plant.kind != "state_space":
        return None
    return plant.A.shape[0] + (ny if plant.integrator else 0)


def parse_constraints(r: Reader, plant: PlantConfig, nu: int, ny: int, horizon: int
                      ) -> dict:
    """``modes[j].constraints`` -> the ModeConfig fields ``signals`` and ``terminal``."""
    nxp = plant_states(plant, ny)
    signals: list[SignalConstraint] = []
    if r.has("signals"):
        for name, spec in _named(r, "signals").items():
            s = Reader(spec, r.key(f"signals.{name}"), SIGNAL_KEYS)
            C = _state_row(s, "C", nxp, plant)
            D = _input_row(s, "D", nu)
            lo = s.number("min", -UNBOUNDED) if s.has("min") else -UNBOUNDED
            hi = s.number("max", UNBOUNDED) if s.has("max") else UNBOUNDED
            if not (math.isfinite(lo) or math.isfinite(hi)):
                raise ConfigError(s.path, "bounds nothing: give min, max or both")
            if not lo <= hi:
                raise ConfigError(s.key("min"), f"must be <= max ({lo} > {hi})")
            signals.append(_signal(s, name, "signals", C, D, lo, hi, horizon))
    if r.has("mixed"):
        for name, spec in _named(r, "mixed").items():
            s = Reader(spec, r.key(f"mixed.{name}"), MIXED_KEYS)
            g = read_vector(s.raw("g"), s.key("g"))
            if not s.has("E") and not s.has("F"):
                raise ConfigError(s.path, "needs E (on the states), F (on the inputs) or both")
            E = _matrix(s, "E", (g.size, nxp), plant) if s.has("E") else np.zeros((g.size, 0))
            F = (read_matrix(s.raw("F"), s.key("F"), (g.size, nu)) if s.has("F")
                 else np.zeros((g.size, 0)))
            for i in range(g.size):
                signals.append(_signal(s, f"{name}[{i}]", "mixed", E[i], F[i], -UNBOUNDED,
                                       float(g[i]), horizon))
    terminal = _terminal(r, nxp, plant) if r.has("terminal") else None
    return {"signals": tuple(signals), "terminal": terminal}


def signal_row_count(signals: tuple[SignalConstraint, ...]) -> int:
    """The QP rows of a mode's constrained signals and mixed rows: one per finite side and
    time (features/signals.py)."""
    return sum((s.last - s.first + 1) * (math.isfinite(s.lo) + math.isfinite(s.hi))
               for s in signals)


def _named(r: Reader, section: str) -> dict:
    value = r.raw(section)
    if not isinstance(value, dict) or not value:
        raise ConfigError(r.key(section), "must be a mapping of names to constraints")
    for name in value:
        if not isinstance(name, str) or not IDENTIFIER.fullmatch(name):
            raise ConfigError(r.key(section), f"names must be identifiers, got {name!r}")
    return value


def _matrix(s: Reader, name: str, shape: tuple[int, int | None], plant: PlantConfig) -> np.ndarray:
    """A matrix on the plant's states (E, H): refused on a transfer-function plant."""
    rows, nxp = shape
    if nxp is None:
        raise ConfigError(s.key(name), "names the plant's states, but a transfer-function "
                          "plant's states are the generator's realisation: write the plant "
                          "as state_space")
    M = read_matrix(s.raw(name), s.key(name))
    if M.shape[0] != rows:
        raise ConfigError(s.key(name), f"must have {rows} rows, got {M.shape[0]}")
    return _plant_columns(s.key(name), M, nxp, plant)


def _plant_columns(key: str, M: np.ndarray, nxp: int, plant: PlantConfig) -> np.ndarray:
    """M over every plant state; with integrators, M may leave their columns out (0)."""
    written = plant.A.shape[0]
    if M.shape[1] == nxp:
        return M
    if M.shape[1] == written:
        return np.hstack((M, np.zeros((M.shape[0], nxp - written))))
    extra = f" (or {written}, the integrators left out)" if nxp != written else ""
    raise ConfigError(key, f"must have {nxp} columns{extra}, one per plant state, got "
                      f"{M.shape[1]}")


def _state_row(s: Reader, name: str, nxp: int | None, plant: PlantConfig) -> np.ndarray | None:
    if not s.has(name):
        return None
    value = s.raw(name)
    rows = value if isinstance(value, list) and value and isinstance(value[0], list) else [value]
    return _matrix(Reader({name: rows}, s.path, (name,)), name, (1, nxp), plant)[0]


def _input_row(s: Reader, name: str, nu: int) -> np.ndarray | None:
    if not s.has(name):
        return None
    value = s.raw(name)
    row = value[0] if isinstance(value, list) and value and isinstance(value[0], list) else value
    return read_vector(row, s.key(name), nu)


def _signal(s: Reader, name: str, source: str, C, D, lo: float, hi: float,
            horizon: int) -> SignalConstraint:
    C = np.zeros(0) if C is None else C  # size 0: no state (input) term
    D = np.zeros(0) if D is None else D
    if not (np.any(C) or np.any(D)):
        raise ConfigError(s.path, "constrains nothing: its state and input coefficients "
                          "are all 0")
    feed = bool(np.any(D))
    first, last = (0, horizon - 1) if feed else (1, horizon)
    if s.has("stages"):
        first, last = _stages(s, first, last, feed)
    l1, l2 = _soft(s, lo, hi)
    return SignalConstraint(name=name, key=s.path, source=source, C=C, D=D, lo=lo, hi=hi,
                            first=first, last=last, soft_l1=l1, soft_l2=l2)


def _stages(s: Reader, first: int, last: int, feed: bool) -> tuple[int, int]:
    """``stages: [a, b]`` (times a..b) or one time, within first..last."""
    value = s.raw("stages")
    items = value if isinstance(value, list) else [value, value]
    if len(items) != 2:
        raise ConfigError(s.key("stages"), "must be [first, last] or one time k")
    times = []
    for i, v in enumerate(items):
        k = read_number(v, s.key("stages"))
        if k != int(k):
            raise ConfigError(s.key("stages"), f"must be whole times k, got {v!r}")
        times.append(int(k))
    a, b = times
    why = ("0..N-1: it depends on u_k, and u_N does not exist" if feed else
           "1..N: without an input term its value at time 0 is the measured state's")
    if not first <= a <= b <= last:
        raise ConfigError(s.key("stages"), f"must be a range within {first}..{last} "
                          f"(times k of {why}), got {a}..{b}")
    return a, b


def _soft(s: Reader, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """``soft: {l1, l2}``: every finite side soft alike."""
    if not s.has("soft"):
        return np.zeros(2), np.zeros(2)
    p = s.sub("soft", PENALTY_KEYS)
    l1, l2 = p.number("l1", nonnegative=True), p.number("l2", positive=True)
    sides = np.array([math.isfinite(lo), math.isfinite(hi)], float)
    return l1 * sides, l2 * sides


def _terminal(r: Reader, nxp: int | None, plant: PlantConfig) -> TerminalConfig:
    value = r.raw("terminal")
    key = r.key("terminal")
    if isinstance(value, str):
        value = {"kind": value}
    t = Reader(value, key, TERMINAL_KEYS)
    kind = t.string("kind", choices=TERMINAL_KINDS)
    H = h = None
    if kind == "polytope":
        h = read_vector(t.raw("h"), t.key("h"))
        H = _matrix(t, "H", (h.size, nxp), plant)
        if np.any(h < 0):
            raise ConfigError(t.key("h"), "must be >= 0: the set must contain the steady "
                              "state (x_N = x_s, where H (x_N - x_s) = 0)")
    else:
        for other in ("H", "h"):
            if t.has(other):
                raise ConfigError(t.key(other), f"is for kind: polytope, not {kind}")
    l1 = l2 = 0.0
    if t.has("soft"):
        p = t.sub("soft", PENALTY_KEYS)
        l1, l2 = p.number("l1", nonnegative=True), p.number("l2", positive=True)
    return TerminalConfig(kind=kind, H=H, h=h, soft_l1=l1, soft_l2=l2)


__all__ = ["parse_constraints", "plant_states", "signal_row_count", "CONSTRAINT_KEYS"]
