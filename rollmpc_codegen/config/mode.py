"""``modes[]``: one mode's actuators, plant, weights, bounds (hard, soft and Δu),
observer (:mod:`.observer`) and move blocking."""
from __future__ import annotations

import numpy as np

from ..features.move_blocking import blocks_of, is_blocked
from .errors import ConfigError
from .constraints import parse_constraints
from .observer import parse_innovation_limit, parse_observer
from .plant import parse_plant
from .reader import IDENTIFIER, Reader, check_psd, read_matrix, read_vector
from .schema import (BOUND_KEYS, CONSTRAINT_KEYS, OBSERVER_KEYS, PENALTY_KEYS, PLANT_KEYS, SOFT_KEYS, UNBOUNDED,
                     WEIGHT_KEYS, ModeConfig)


def parse_mode(r: Reader, outputs: tuple[str, ...], actuators: tuple[str, ...], horizon: int,
               default_blocks: tuple[int, ...] | None, levels: np.ndarray) -> ModeConfig:
    """``modes[i]``; ``default_blocks`` is the top level's move blocking (None: none),
    ``levels`` the scenario's reference levels (levels x outputs)."""
    name = r.string("name")
    if not IDENTIFIER.fullmatch(name):
        raise ConfigError(r.key("name"), f"must be an identifier-like name, got {name!r}")
    # a mode drives a subset of the physical actuators, in its own input order (B's
    # columns); absent, it drives every one in the top-level order (a one-mode design)
    acts = r.names("actuators") if r.has("actuators") else actuators
    for i, a in enumerate(acts):
        if a not in actuators:
            raise ConfigError(f"{r.key('actuators')}[{i}]", f"unknown actuator {a!r}; "
                              f"declared actuators are {', '.join(actuators)}")
    plant = parse_plant(r.sub("plant", PLANT_KEYS))
    nu, ny = len(acts), len(outputs)
    if plant.kind == "transfer_function" and plant.tf_matrix is None and (nu, ny) != (1, 1):
        raise ConfigError(r.key("plant.transfer_function"),
                          f"is SISO but the mode has {nu} actuators and {ny} outputs; give "
                          "num/den as matrices (one row per output, one element per input)")
    if plant.tf_matrix is not None:
        shape = (len(plant.tf_matrix), len(plant.tf_matrix[0]))
        if shape != (ny, nu):
            raise ConfigError(r.key("plant.transfer_function.num"),
                              f"must be {ny}x{nu} (one row per output, one element per mode "
                              f"actuator), got {shape[0]}x{shape[1]}")
    if plant.kind == "state_space":
        if plant.B.shape[1] != nu:
            raise ConfigError(r.key("plant.state_space.B"),
                              f"must have {nu} columns (one per mode actuator)")
        if plant.C.shape[0] != ny:
            raise ConfigError(r.key("plant.state_space.C"),
                              f"must have {ny} rows (one per output)")
    weights = _weights(r.sub("weights", WEIGHT_KEYS), nu, ny)
    bounds = _bounds(r.sub("bounds", BOUND_KEYS), nu, ny)
    o = r.sub("observer", OBSERVER_KEYS) if r.has("observer") else None
    observer = parse_observer(o, nu, ny) if o is not None else {}
    observer["innovation_limit"] = parse_innovation_limit(
        o, r.key("observer.innovation_limit"), outputs, bounds["y_min"], bounds["y_max"], levels)
    blocks = blocks_of(r.raw("control_horizon", None), r.raw("move_blocking", None), horizon,
                       r.path)
    blocks = default_blocks if blocks is None else blocks
    constraints = (parse_constraints(r.sub("constraints", CONSTRAINT_KEYS), plant, nu, ny,
                                     horizon) if r.has("constraints") else {})
    return ModeConfig(**constraints, name=name, actuators=acts, plant=plant,
                      blocks=blocks if is_blocked(blocks) else None,
                      observer_poles=observer.pop("poles", None),
                      **weights, **bounds, **observer)


def _weights(w: Reader, nu: int, ny: int) -> dict:
    """``weights``: Q, R, P (default: Q) and the Δu weight R_delta."""
    Q = w.psd("Q", (ny, ny), strict=False)
    R = read_matrix(w.raw("R"), w.key("R"), (nu, nu))
    P = w.psd("P", (ny, ny), strict=False, default=w.raw("Q"))
    R_delta = w.psd("R_delta", (nu, nu), strict=False) if w.has("R_delta") else None
    if R_delta is not None and not np.any(R_delta):
        R_delta = None  # zero: no Δu term, no previous-input states
    # R may be singular (e.g. 0: pure Δu weighting) when R_delta keeps Psi definite
    delta_definite = R_delta is not None and np.linalg.eigvalsh(R_delta).min() > 0
    R = check_psd(R, w.key("R"), strict=not delta_definite)
    return {"Q": Q, "R": R, "P": P, "R_delta": R_delta}


def _bounds(b: Reader, nu: int, ny: int) -> dict:
    """``bounds``: input bounds, output bounds (default: none), their soft penalties and
    the Δu bounds."""
    u_min = read_vector(b.raw("u_min"), b.key("u_min"), nu)
    u_max = read_vector(b.raw("u_max"), b.key("u_max"), nu)
    _check_contains_zero(b, "u", u_min, u_max, "the bounds must contain 0 (the inactive "
                         "actuator command)")
    y_min = read_vector(b.raw("y_min", -UNBOUNDED), b.key("y_min"), ny, allow_inf=True)
    y_max = read_vector(b.raw("y_max", UNBOUNDED), b.key("y_max"), ny, allow_inf=True)
    for i in range(ny):
        if not y_min[i] < y_max[i]:
            raise ConfigError(b.key("y_min"), f"must be < y_max (entry {i})")
    du_min, du_max = _rate_bounds(b, nu)
    soft = _soft_bounds(b.sub("soft", SOFT_KEYS), y_min, y_max) if b.has("soft") else {}
    return {"u_min": u_min, "u_max": u_max, "y_min": y_min, "y_max": y_max,
            "du_min": du_min, "du_max": du_max, **soft}


def _check_contains_zero(b: Reader, name: str, lo, hi, why: str) -> None:
    """lo < hi and lo <= 0 <= hi entry by entry; the error names the bound on the wrong
    side of 0 (``<name>_min`` or ``<name>_max``), not always the lower one."""
    for i, (a, c) in enumerate(zip(lo, hi)):
        if not a < c:
            raise ConfigError(b.key(f"{name}_min"), f"must be < {name}_max (entry {i}: "
                              f"{a} >= {c})")
        if a > 0.0:
            raise ConfigError(b.key(f"{name}_min"), f"must be <= 0: {why}, got {a}")
        if c < 0.0:
            raise ConfigError(b.key(f"{name}_max"), f"must be >= 0: {why}, got {c}")


def _rate_bounds(b: Reader, nu: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``bounds.du_min``/``du_max`` (Δu constraints; None when neither key is given).
    Holding the input must be allowed, so du_min <= 0 <= du_max."""
    if not (b.has("du_min") or b.has("du_max")):
        return None, None
    du_min = read_vector(b.raw("du_min", -UNBOUNDED), b.key("du_min"), nu, allow_inf=True)
    du_max = read_vector(b.raw("du_max", UNBOUNDED), b.key("du_max"), nu, allow_inf=True)
    _check_contains_zero(b, "du", du_min, du_max, "holding the input (Δu = 0) must be allowed")
    return du_min, du_max


def _soft_bounds(s: Reader, y_min: np.ndarray, y_max: np.ndarray) -> dict:
    """``bounds.soft.y_min``/``y_max``: ``{l1, l2}`` (scalars or one entry per output) of the
    slack penalty l1 s + l2 s^2 (soft_constraints.py). l2 > 0 softens that output's bound,
    l2 = 0 (with l1 = 0) keeps it hard; a soft entry needs a finite bound."""
    ny = y_min.size
    l1, l2 = np.zeros((ny, 2)), np.zeros((ny, 2))
    for side, (name, bound) in enumerate((("y_min", y_min), ("y_max", y_max))):
        if not s.has(name):
            continue
        p = s.sub(name, PENALTY_KEYS)
        a = read_vector(p.raw("l1"), p.key("l1"), ny)
        c = read_vector(p.raw("l2"), p.key("l2"), ny)
        for i in range(ny):
            if a[i] < 0.0:
                raise ConfigError(p.key("l1"), f"must be >= 0 (entry {i}: {a[i]})")
            if c[i] < 0.0:
                raise ConfigError(p.key("l2"), f"must be >= 0 (entry {i}: {c[i]})")
            if c[i] == 0.0 and a[i] != 0.0:
                raise ConfigError(p.key("l2"), f"must be > 0 where l1 is (entry {i}): the "
                                  "solver needs the quadratic term; l1 = l2 = 0 keeps the "
                                  "bound hard")
            if c[i] > 0.0 and not np.isfinite(bound[i]):
                raise ConfigError(s.key(name), f"output {i} has no finite {name} to soften")
        l1[:, side], l2[:, side] = a, c
    if not np.any(l2 > 0.0):
        raise ConfigError(s.path, "softens no bound (give y_min or y_max with l2 > 0)")
    return {"soft_l1": l1, "soft_l2": l2}
