"""Stage 1 of the pipeline: YAML -> validated, frozen configuration dataclasses.

Every problem is reported as a single :class:`ConfigError` whose text names the
offending key (``modes[1].weights.P: must be a positive number``).  Nothing
downstream re-validates raw YAML; the later stages (plant, mpc, observer) raise
``ConfigError`` too when a *mathematical* property fails (an uncontrollable mode,
an indefinite Hessian, ...), always naming the key that caused it.
"""
from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .canonical import canonical_json, config_digest

SOLVER_METHODS = ("hildreth", "hildreth_plus", "hildreth_plus_prime")
PRECISIONS = ("double", "float")
SCHEDULE_SOURCES = ("output_rate", "output")
# The C indexes QP rows and variables with int16_t and counts iterations with int.
MAX_ROWS = 32767
MAX_C_INT = 2**31 - 1
FLOAT_MAX = float(np.finfo(np.float32).max)


class ConfigError(ValueError):
    """A configuration problem, reported as one line: ``<key>: <problem>``."""

    def __init__(self, key: str, problem: str):
        # the CLI promises exactly one line on stderr, whatever the YAML text contained
        key, problem = (" ".join(str(t).splitlines()) for t in (key, problem))
        super().__init__(f"{key}: {problem}")
        self.key = key
        self.problem = problem


# --------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True)
class PlantConfig:
    """A continuous or discrete LTI plant of one mode (before any realisation)."""

    kind: str  # "transfer_function" | "state_space"
    num: tuple[float, ...] = ()
    den: tuple[float, ...] = ()
    A: np.ndarray | None = None
    B: np.ndarray | None = None
    C: np.ndarray | None = None
    D: np.ndarray | None = None
    discrete: bool = False  # state space only: already sampled at sample_time
    integrator: bool = False  # append 1/s to every output (eq. 1)
    # transfer-function matrix (ny x nu): ((num_ij, den_ij) per input j) per output i;
    # None for the SISO form (num, den above) and for state space
    tf_matrix: tuple[tuple[tuple[tuple[float, ...], tuple[float, ...]], ...], ...] | None = None


@dataclass(frozen=True)
class ModeConfig:
    name: str
    actuators: tuple[str, ...]
    plant: PlantConfig
    Q: np.ndarray  # ny x ny stage output weight
    R: np.ndarray  # nu x nu input weight
    P: np.ndarray  # ny x ny terminal output weight
    u_min: np.ndarray
    u_max: np.ndarray
    y_min: np.ndarray  # -inf where unbounded
    y_max: np.ndarray
    observer_poles: tuple[complex, ...] | None  # None -> documented default
    observer_kind: str = "poles"  # "poles" (placement) | "kalman" (steady-state Kalman)
    observer_Qn: np.ndarray | None = None  # kalman: input-noise covariance (nu x nu)
    observer_Rn: np.ndarray | None = None  # kalman: measurement-noise covariance (ny x ny)
    observer_Qd: np.ndarray | None = None  # kalman + disturbance: its random-walk covariance
    disturbance: str = "none"  # offset-free model: "none" | "input" | "output"
    # Δu weighting (nu x nu PSD): (u_k - u_{k-1})' R_delta (u_k - u_{k-1}) over the
    # horizon, u_{-1} = the previous command (input_rate); None when absent or zero
    R_delta: np.ndarray | None = None
    # Δu constraints (input-rate limits, input_rate): du_min <= u_k - u_{k-1} <= du_max,
    # k = 0..N-1, u_{-1} = the previous command; +-inf = absent (no rows)
    du_min: np.ndarray | None = None
    du_max: np.ndarray | None = None
    # move blocking (move_blocking.py): block lengths summing to the horizon, from the
    # mode's or the top level's control_horizon / move_blocking; None = one block per stage
    blocks: tuple[int, ...] | None = None
    # soft output bounds (soft_constraints.py), ``bounds.soft``: per output (rows) and side
    # (column 0 = y_min, 1 = y_max), the penalty l1 s + l2 s^2 of the slack s >= 0 added
    # to J; l2 = 0 keeps that bound hard. None: every bound is hard
    soft_l1: np.ndarray | None = None  # (ny, 2)
    soft_l2: np.ndarray | None = None  # (ny, 2)

    @property
    def has_rate_bounds(self) -> bool:
        """Whether the mode has any finite Δu bound (then u_prev is part of the state)."""
        return self.du_min is not None and bool(
            np.any(np.isfinite(self.du_min)) or np.any(np.isfinite(self.du_max)))


@dataclass(frozen=True)
class SchedulerConfig:
    """Band scheduling with hysteresis, the generalisation of eq. (3) (docs/features.md).

    k bands split the signal at k-1 increasing thresholds t_1 < .. < t_{k-1}: band b is
    t_{b-1} <= s < t_b (t_0 = -inf, t_k = +inf) and is served by one mode (``band_modes``
    lists them from the lowest band, 0-based, as every tuple here).  The active mode becomes
    band b's mode only when s is inside band b by more than the margin of each of its
    thresholds, t_{b-1} + eps_{b-1} < s < t_b - eps_b; within a margin of a threshold the
    current mode is kept.  The two-mode shorthand (lower, upper, inside, outside) is the
    three bands (outside, inside, outside), which is eq. (3) exactly.
    """

    signal: str
    thresholds: tuple[float, ...]  # k-1, strictly increasing
    epsilons: tuple[float, ...]  # k-1 hysteresis margins, one per threshold
    band_modes: tuple[int, ...]  # k mode indices, one per band (a mode may serve several)
    initial: int  # mode index at P_init

    @property
    def below(self) -> tuple[float, ...]:
        """t_i - eps_i: s below it is firmly below threshold i (computed once, in double)."""
        return tuple(t - e for t, e in zip(self.thresholds, self.epsilons))

    @property
    def above(self) -> tuple[float, ...]:
        """t_i + eps_i: s above it is firmly above threshold i."""
        return tuple(t + e for t, e in zip(self.thresholds, self.epsilons))

    def band_of(self, value: float) -> int:
        """The band containing ``value`` (t_{b-1} <= value < t_b), without hysteresis."""
        return sum(1 for t in self.thresholds if value >= t)


@dataclass(frozen=True)
class SolverConfig:
    method: str = "hildreth_plus_prime"
    omega: float = 1.2
    sigma: float = 0.2
    delta: float = 1e-13
    max_iterations: int = 1000
    warm_start: bool = True
    polish: bool = True
    polish_first: bool = True
    polish_every: int = 10
    polish_max: int = 8
    feasibility_tol: float | None = None  # None -> precision default
    active_set: bool = True  # dual active-set (Goldfarb-Idnani) solve before any sweep
    active_set_max: int = 500  # its cap on add/drop steps
    dependence_tol: float | None = None  # None -> precision default


@dataclass(frozen=True)
class SimulationConfig:
    schedule_source: str = "output_rate"
    # the piecewise-constant reference of ``rollmpc simulate/bench/report``: one row of
    # n_outputs values per level, each held reference_segment_s seconds; None -> the
    # paper's scenario (scenario.paper_reference, applied to every output)
    reference_levels: tuple[tuple[float, ...], ...] | None = None
    reference_segment_s: float | None = None


@dataclass(frozen=True)
class UnitsConfig:
    """Units of the signals, for labels only (``rollmpc simulate``'s summary and --plot);
    "" = no unit shown.  The top-level ``units`` key; the generated C never sees them."""

    outputs: tuple[str, ...] = ()  # one per output, or () for none
    actuators: tuple[str, ...] = ()  # one per actuator, or () for none
    schedule: str = ""  # the scheduling signal's unit

    def label(self, signals: str) -> str:
        """`` [u]`` when every one of the ``signals`` (outputs, actuators or schedule) has
        the unit u, else "" (no unit, or mixed units)."""
        value = getattr(self, signals)
        found = {value} if isinstance(value, str) else set(value)
        return f" [{found.pop()}]" if len(found) == 1 and "" not in found else ""


@dataclass(frozen=True, eq=False)
class ControllerConfig:
    prefix: str
    precision: str
    sample_time: float
    horizon: int
    outputs: tuple[str, ...]
    actuators: tuple[str, ...]
    modes: tuple[ModeConfig, ...]
    scheduler: SchedulerConfig | None
    solver: SolverConfig
    simulation: SimulationConfig
    # the instance carries the input/output bounds, changeable by P_set_bounds() between
    # samples (runtime_bounds.py; docs/features.md "Run-time bounds"); False: baked in
    runtime_bounds: bool = False
    units: UnitsConfig = UnitsConfig()  # labels only (the top-level `units` key)

    @cached_property
    def config_hash(self) -> str:
        """The hash of the effective configuration (canonical.py), stamped into the C."""
        return config_digest(self)

    def __eq__(self, other: object) -> bool:
        # field by field would compare numpy arrays; the canonical text compares exactly
        if not isinstance(other, ControllerConfig):
            return NotImplemented
        return canonical_json(self) == canonical_json(other)

    def __hash__(self) -> int:
        return hash(self.config_hash)

    @property
    def n_outputs(self) -> int:
        return len(self.outputs)

    @property
    def n_schedule(self) -> int:
        return 0 if self.scheduler is None else 1


# --------------------------------------------------------------------------- readers
class _Reader:
    """Typed access to one YAML mapping; every failure names its full key path."""

    def __init__(self, data: Any, path: str):
        if not isinstance(data, dict):
            raise ConfigError(path or "<top>", "must be a mapping")
        self.data = data
        self.path = path
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        """Is an optional key given?  ``key:`` with no value counts as absent, as in raw()."""
        self.used.add(name)
        return self.data.get(name) is not None

    def raw(self, name: str, default: Any = ..., required: bool = True) -> Any:
        self.used.add(name)
        if name not in self.data or self.data[name] is None:
            if default is not ...:
                return default
            raise ConfigError(self.key(name), "missing required key")
        return self.data[name]

    def number(self, name: str, default: Any = ..., positive: bool = False,
               nonnegative: bool = False) -> float:
        value = self.raw(name, default)
        return _number(value, self.key(name), positive=positive, nonnegative=nonnegative)

    def integer(self, name: str, default: Any = ..., minimum: int | None = None,
                maximum: int | None = None) -> int:
        value = self.raw(name, default)
        if isinstance(value, float) or (isinstance(value, str) and "e" in value.lower()):
            # whole numbers written as 1e6 / 1.0e6 (YAML 1.1 reads the latter as a string)
            try:
                as_float = float(value)
            except ValueError:
                as_float = math.nan
            if math.isfinite(as_float) and as_float == int(as_float):
                value = int(as_float)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(self.key(name), f"must be an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise ConfigError(self.key(name), f"must be >= {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise ConfigError(self.key(name), f"must be <= {maximum}, got {value}")
        return value

    def boolean(self, name: str, default: Any = ...) -> bool:
        value = self.raw(name, default)
        if not isinstance(value, bool):
            raise ConfigError(self.key(name), f"must be true or false, got {value!r}")
        return value

    def string(self, name: str, default: Any = ..., choices: tuple[str, ...] | None = None) -> str:
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise ConfigError(self.key(name), f"must be a string, got {value!r}")
        if choices is not None and value not in choices:
            raise ConfigError(self.key(name), f"must be one of {', '.join(choices)}; got {value!r}")
        return value

    def names(self, name: str) -> tuple[str, ...]:
        value = self.raw(name)
        if not isinstance(value, list) or not value:
            raise ConfigError(self.key(name), "must be a non-empty list of names")
        for i, item in enumerate(value):
            if not isinstance(item, str) or not _IDENT.match(item):
                raise ConfigError(f"{self.key(name)}[{i}]",
                                  f"must be a C identifier-like name, got {item!r}")
        if len(set(value)) != len(value):
            raise ConfigError(self.key(name), "names must be unique")
        return tuple(value)

    def sub(self, name: str, default: Any = ...) -> "_Reader":
        value = self.raw(name, default)
        return _Reader(value, self.key(name))

    def finish(self) -> None:
        # str(): YAML keys may be ints, bools or null, which do not sort with strings
        unknown = sorted(set(self.data) - self.used, key=str)
        if unknown:
            raise ConfigError(self.key(str(unknown[0])), "unknown key")


_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _number(value: Any, key: str, positive: bool = False, nonnegative: bool = False) -> float:
    if isinstance(value, str):
        # PyYAML (YAML 1.1) reads 1.0e6 -- no sign in the exponent -- as a string
        try:
            value = float(value.strip())
        except ValueError:
            raise ConfigError(key, f"must be a number, got {value!r}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(key, f"must be a number, got {value!r}")
    try:
        value = float(value)
    except OverflowError:  # an integer literal with hundreds of digits
        raise ConfigError(key, "must be finite, got a number too large for a double") from None
    if not math.isfinite(value):
        raise ConfigError(key, f"must be finite, got {value!r}")
    if positive and value <= 0:
        raise ConfigError(key, f"must be > 0, got {value!r}")
    if nonnegative and value < 0:
        raise ConfigError(key, f"must be >= 0, got {value!r}")
    return value


def _vector(value: Any, key: str, length: int | None = None, allow_inf: bool = False) -> np.ndarray:
    """A scalar (broadcast to ``length``) or a list of numbers."""
    items = value if isinstance(value, list) else [value]
    if length is not None and not isinstance(value, list):
        items = items * length
    out = []
    for i, item in enumerate(items):
        k = f"{key}[{i}]" if isinstance(value, list) else key
        if allow_inf and isinstance(item, str) and item.strip() in ("inf", "+inf", "-inf"):
            out.append(float(item))
            continue
        if allow_inf and isinstance(item, float) and math.isinf(item):
            out.append(item)
            continue
        out.append(_number(item, k))
    if length is not None and len(out) != length:
        raise ConfigError(key, f"must have {length} entries, got {len(out)}")
    if not out:
        raise ConfigError(key, "must not be empty")
    return np.array(out, dtype=float)


def _matrix(value: Any, key: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A matrix given as a list of rows; a scalar means scalar * identity (square shapes)."""
    if shape is not None and not isinstance(value, list):
        if shape[0] != shape[1]:
            raise ConfigError(key, f"must be a {shape[0]}x{shape[1]} matrix")
        return _number(value, key) * np.eye(shape[0])
    if shape is not None and isinstance(value, list) and value and not isinstance(value[0], list):
        # a flat list is a diagonal for square weights
        if shape[0] == shape[1] and len(value) == shape[0]:
            return np.diag(_vector(value, key))
    if not isinstance(value, list) or not value or not all(isinstance(r, list) for r in value):
        raise ConfigError(key, "must be a matrix given as a list of rows")
    rows = [_vector(r, f"{key}[{i}]") for i, r in enumerate(value)]
    if len({len(r) for r in rows}) != 1:
        raise ConfigError(key, "rows must all have the same length")
    mat = np.array(rows)
    if shape is not None and mat.shape != shape:
        raise ConfigError(key, f"must be {shape[0]}x{shape[1]}, got {mat.shape[0]}x{mat.shape[1]}")
    return mat


def _psd(mat: np.ndarray, key: str, strict: bool) -> np.ndarray:
    if not np.allclose(mat, mat.T, rtol=0, atol=1e-12 * max(1.0, np.abs(mat).max())):
        raise ConfigError(key, "must be symmetric")
    eig = np.linalg.eigvalsh(mat)
    if strict and eig.min() <= 0:
        raise ConfigError(key, "must be positive definite")
    if not strict and eig.min() < -1e-12 * max(1.0, eig.max()):
        raise ConfigError(key, "must be positive semidefinite")
    return mat


# --------------------------------------------------------------------------- sections
def _is_rows(value: Any) -> bool:
    """A non-empty list of lists: the matrix form of a transfer function."""
    return isinstance(value, list) and bool(value) and all(isinstance(v, list) for v in value)


def _tf_element(num_raw: Any, den_raw: Any, knum: str, kden: str, integrator: bool,
                allow_zero: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """One transfer function num/den (coefficients, highest power first), checked."""
    num = np.trim_zeros(_vector(num_raw, knum), "f")
    den = np.trim_zeros(_vector(den_raw, kden), "f")
    if den.size == 0:
        raise ConfigError(kden, "must not be all zeros")
    if num.size == 0:
        if allow_zero:  # a zero element of a matrix: no coupling
            return (0.0,), tuple(den)
        raise ConfigError(knum, "must not be all zeros")
    if num.size > den.size:
        raise ConfigError(knum, "improper transfer function (deg num > deg den)")
    if num.size == den.size and not integrator:
        raise ConfigError(knum, "transfer function has feedthrough; MPC needs a "
                          "strictly proper plant (deg num < deg den) or integrator: true")
    if den.size < 2 and not integrator:
        raise ConfigError(kden, "a static gain has no state; use integrator: true")
    return tuple(num), tuple(den)


def _tf_matrix(tf: _Reader, integrator: bool):
    """``num``: rows (outputs) of elements (inputs), each a coefficient list or a number;
    ``den``: the same shape, or one coefficient list shared by every element."""
    num_rows, den_raw = tf.raw("num"), tf.raw("den")
    knum, kden = tf.key("num"), tf.key("den")
    width = len(num_rows[0])
    for i, row in enumerate(num_rows):
        if len(row) != width or not row:
            raise ConfigError(f"{knum}[{i}]", f"must have {width} elements (one per input)")
    common = not _is_rows(den_raw)
    if not common and (len(den_raw) != len(num_rows)
                       or any(not isinstance(row, list) or len(row) != width
                              for row in den_raw)):
        raise ConfigError(kden, f"must have the shape of num ({len(num_rows)}x{width}) or be "
                          "one coefficient list (a common denominator)")
    matrix = []
    for i, row in enumerate(num_rows):
        matrix.append(tuple(
            _tf_element(n, den_raw if common else den_raw[i][j], f"{knum}[{i}][{j}]",
                        kden if common else f"{kden}[{i}][{j}]", integrator, allow_zero=True)
            for j, n in enumerate(row)))
    if all(n == (0.0,) for row in matrix for n, _ in row):
        raise ConfigError(knum, "must not be all zeros")
    return tuple(matrix)


def _plant(r: _Reader) -> PlantConfig:
    kinds = [k for k in ("transfer_function", "state_space") if r.has(k)]
    if len(kinds) != 1:
        raise ConfigError(r.path, "give exactly one of transfer_function or state_space")
    integrator = r.boolean("integrator", False)
    if kinds[0] == "transfer_function":
        tf = r.sub("transfer_function")
        if _is_rows(tf.raw("num")):  # the matrix form: one row per output
            matrix = _tf_matrix(tf, integrator)
            tf.finish()
            r.finish()
            return PlantConfig(kind="transfer_function", tf_matrix=matrix,
                               integrator=integrator)
        num, den = _tf_element(tf.raw("num"), tf.raw("den"), tf.key("num"), tf.key("den"),
                               integrator, allow_zero=False)
        tf.finish()
        r.finish()
        return PlantConfig(kind="transfer_function", num=num, den=den, integrator=integrator)
    ss = r.sub("state_space")
    A = _matrix(ss.raw("A"), ss.key("A"))
    nx = A.shape[0]
    if A.shape != (nx, nx):
        raise ConfigError(ss.key("A"), "must be square")
    B = _matrix(ss.raw("B"), ss.key("B"))
    if B.shape[0] != nx:
        raise ConfigError(ss.key("B"), f"must have {nx} rows (the size of A)")
    C = _matrix(ss.raw("C"), ss.key("C"))
    if C.shape[1] != nx:
        raise ConfigError(ss.key("C"), f"must have {nx} columns (the size of A)")
    D = _matrix(ss.raw("D", [[0.0] * B.shape[1]] * C.shape[0]), ss.key("D"),
                shape=(C.shape[0], B.shape[1]))
    if np.any(D != 0) and not integrator:
        raise ConfigError(ss.key("D"), "must be zero: MPC needs a strictly proper plant "
                          "(or integrator: true)")
    discrete = ss.boolean("discrete", False)
    ss.finish()
    if discrete and integrator:
        raise ConfigError(r.key("integrator"), "only for continuous plants")
    r.finish()
    return PlantConfig(kind="state_space", A=A, B=B, C=C, D=D, discrete=discrete,
                       integrator=integrator)


def _mode(r: _Reader, outputs: tuple[str, ...], actuators: tuple[str, ...], horizon: int,
          default_blocks: tuple[int, ...] | None) -> ModeConfig:
    from ..features.move_blocking import blocks_of, is_blocked  # (it imports ConfigError from here)
    name = r.string("name")
    if not _IDENT.match(name):
        raise ConfigError(r.key("name"), f"must be an identifier-like name, got {name!r}")
    acts = r.names("actuators")
    for i, a in enumerate(acts):
        if a not in actuators:
            raise ConfigError(f"{r.key('actuators')}[{i}]", f"unknown actuator {a!r}; "
                              f"declared actuators are {', '.join(actuators)}")
    plant = _plant(r.sub("plant"))
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
    w = r.sub("weights")
    Q = _psd(_matrix(w.raw("Q"), w.key("Q"), (ny, ny)), w.key("Q"), strict=False)
    R = _matrix(w.raw("R"), w.key("R"), (nu, nu))
    P = _psd(_matrix(w.raw("P", w.raw("Q")), w.key("P"), (ny, ny)), w.key("P"), strict=False)
    R_delta = (_psd(_matrix(w.raw("R_delta"), w.key("R_delta"), (nu, nu)), w.key("R_delta"),
                    strict=False) if w.has("R_delta") else None)
    if R_delta is not None and not np.any(R_delta):
        R_delta = None  # zero: no Δu term, no previous-input states
    # R may be singular (e.g. 0: pure Δu weighting) when R_delta keeps Psi definite
    delta_definite = R_delta is not None and np.linalg.eigvalsh(R_delta).min() > 0
    R = _psd(R, w.key("R"), strict=not delta_definite)
    w.finish()
    b = r.sub("bounds")
    u_min = _vector(b.raw("u_min"), b.key("u_min"), nu)
    u_max = _vector(b.raw("u_max"), b.key("u_max"), nu)
    _check_contains_zero(b, "u", u_min, u_max, "the bounds must contain 0 (the inactive "
                         "actuator command)")
    y_min = _vector(b.raw("y_min", -math.inf), b.key("y_min"), ny, allow_inf=True)
    y_max = _vector(b.raw("y_max", math.inf), b.key("y_max"), ny, allow_inf=True)
    for i in range(ny):
        if not y_min[i] < y_max[i]:
            raise ConfigError(b.key("y_min"), f"must be < y_max (entry {i})")
    du_min, du_max = _rate_bounds(b, nu)
    soft = _soft_bounds(b.sub("soft"), y_min, y_max) if b.has("soft") else {}
    b.finish()
    observer = _observer(r.sub("observer"), nu, ny) if r.has("observer") else {}
    blocks = blocks_of(r.raw("control_horizon", None), r.raw("move_blocking", None), horizon,
                       r.path)
    blocks = default_blocks if blocks is None else blocks
    r.finish()
    return ModeConfig(name=name, actuators=acts, plant=plant, Q=Q, R=R, P=P, R_delta=R_delta,
                      blocks=blocks if is_blocked(blocks) else None,
                      u_min=u_min, u_max=u_max, y_min=y_min, y_max=y_max,
                      du_min=du_min, du_max=du_max, observer_poles=observer.pop("poles", None),
                      **soft, **observer)


def _check_contains_zero(b: _Reader, name: str, lo, hi, why: str) -> None:
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


def _rate_bounds(b: _Reader, nu: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``bounds.du_min``/``du_max`` (Δu constraints; None when neither key is given).
    Holding the input must be allowed, so du_min <= 0 <= du_max."""
    if not (b.has("du_min") or b.has("du_max")):
        return None, None
    du_min = _vector(b.raw("du_min", -math.inf), b.key("du_min"), nu, allow_inf=True)
    du_max = _vector(b.raw("du_max", math.inf), b.key("du_max"), nu, allow_inf=True)
    _check_contains_zero(b, "du", du_min, du_max, "holding the input (Δu = 0) must be allowed")
    return du_min, du_max


def _soft_bounds(s: _Reader, y_min: np.ndarray, y_max: np.ndarray) -> dict:
    """``bounds.soft.y_min``/``y_max``: ``{l1, l2}`` (scalars or one entry per output) of the
    slack penalty l1 s + l2 s^2 (soft_constraints.py). l2 > 0 softens that output's bound,
    l2 = 0 (with l1 = 0) keeps it hard; a soft entry needs a finite bound."""
    ny = y_min.size
    l1, l2 = np.zeros((ny, 2)), np.zeros((ny, 2))
    for side, (name, bound) in enumerate((("y_min", y_min), ("y_max", y_max))):
        if not s.has(name):
            continue
        p = s.sub(name)
        a = _vector(p.raw("l1"), p.key("l1"), ny)
        c = _vector(p.raw("l2"), p.key("l2"), ny)
        p.finish()
        for i in range(ny):
            if a[i] < 0.0:
                raise ConfigError(p.key("l1"), f"must be >= 0 (entry {i}: {a[i]})")
            if c[i] < 0.0:
                raise ConfigError(p.key("l2"), f"must be >= 0 (entry {i}: {c[i]})")
            if c[i] == 0.0 and a[i] != 0.0:
                raise ConfigError(p.key("l2"), f"must be > 0 where l1 is (entry {i}): the "
                                  "solver needs the quadratic term; l1 = l2 = 0 keeps the bound hard")
            if c[i] > 0.0 and not np.isfinite(bound[i]):
                raise ConfigError(s.key(name), f"output {i} has no finite {name} to soften")
        l1[:, side], l2[:, side] = a, c
    s.finish()
    if not np.any(l2 > 0.0):
        raise ConfigError(s.path, "softens no bound (give y_min or y_max with l2 > 0)")
    return {"soft_l1": l1, "soft_l2": l2}


OBSERVER_KINDS = ("poles", "kalman")
DISTURBANCE_MODELS = ("none", "input", "output")


def _poles(o: _Reader) -> tuple[complex, ...]:
    raw = o.raw("poles")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(o.key("poles"), "must be a non-empty list")
    parsed = []
    for i, p in enumerate(raw):
        k = f"{o.key('poles')}[{i}]"
        if isinstance(p, list) and len(p) == 2:
            parsed.append(complex(_number(p[0], k), _number(p[1], k)))
        else:
            parsed.append(complex(_number(p, k), 0.0))
        if abs(parsed[-1]) >= 1.0:
            raise ConfigError(k, f"observer pole {p!r} is not inside the unit circle")
    return tuple(parsed)


def _observer(o: _Reader, nu: int, ny: int) -> dict:
    """``modes[].observer``: pole placement (default) or a steady-state Kalman filter, and
    the optional disturbance model of offset-free tracking (docs/features.md)."""
    kind = o.string("kind", "poles", choices=OBSERVER_KINDS)
    disturbance = o.string("disturbance", "none", choices=DISTURBANCE_MODELS)
    out: dict = {"observer_kind": kind, "disturbance": disturbance}
    kalman_keys = [k for k in ("Qn", "Rn", "Qd") if o.has(k)]
    if kind == "poles":
        if kalman_keys:
            raise ConfigError(o.key(kalman_keys[0]), "only with kind: kalman")
        if o.has("poles"):
            out["poles"] = _poles(o)
    else:
        if o.has("poles"):
            raise ConfigError(o.key("poles"), "only with kind: poles (the Kalman filter "
                              "places its own poles)")
        out["observer_Qn"] = _psd(_matrix(o.raw("Qn"), o.key("Qn"), (nu, nu)), o.key("Qn"),
                                  strict=False)
        out["observer_Rn"] = _psd(_matrix(o.raw("Rn"), o.key("Rn"), (ny, ny)), o.key("Rn"),
                                  strict=True)
        if disturbance != "none":
            nd = nu if disturbance == "input" else ny
            out["observer_Qd"] = _psd(_matrix(o.raw("Qd"), o.key("Qd"), (nd, nd)),
                                      o.key("Qd"), strict=True)
        elif o.has("Qd"):
            raise ConfigError(o.key("Qd"), "only with a disturbance model (disturbance: "
                              "input or output)")
    o.finish()
    return out


_SHORTHAND_KEYS = ("lower", "upper", "inside", "outside")


def _scheduler(r: _Reader, modes: tuple[ModeConfig, ...]) -> SchedulerConfig:
    """``scheduler``: ``bands`` (k bands, any number of modes) or the two-mode shorthand
    ``lower, upper, inside, outside`` of eq. (3), translated into the three bands
    (outside, inside, outside)."""
    names = [m.name for m in modes]

    def mode_index(reader: _Reader, key: str) -> int:
        name = reader.string(key)
        if name not in names:
            raise ConfigError(reader.key(key), f"unknown mode {name!r}; modes are "
                              f"{', '.join(names)}")
        return names.index(name)

    signal = r.string("signal")
    if not _IDENT.match(signal):  # it is written into C comments of the generated code
        raise ConfigError(r.key("signal"), f"must be an identifier-like name, got {signal!r}")
    shorthand = [k for k in _SHORTHAND_KEYS if k in r.data]
    if r.has("bands"):
        if shorthand:
            raise ConfigError(r.key(shorthand[0]), "give either bands or the two-mode "
                              "shorthand (lower, upper, inside, outside), not both")
        epsilon = r.number("epsilon", 0.5, nonnegative=True)
        thresholds, epsilons, eps_keys, band_modes = _bands(r, epsilon, mode_index)
        unused_hint = ""
        default_initial = None
    else:
        if not shorthand:
            raise ConfigError(r.key("bands"), "missing required key (or the two-mode "
                              "shorthand lower, upper, inside, outside)")
        lower = r.number("lower")
        upper = r.number("upper")
        if not lower < upper:
            raise ConfigError(r.key("lower"), f"must be < upper ({lower} >= {upper})")
        epsilon = r.number("epsilon", 0.5, nonnegative=True)
        if 2 * epsilon >= upper - lower:
            raise ConfigError(r.key("epsilon"), "the hysteresis margin leaves no inside band "
                              "(need 2*epsilon < upper - lower)")
        inside = mode_index(r, "inside")
        outside = mode_index(r, "outside")
        if inside == outside:
            raise ConfigError(r.key("outside"), "must differ from inside")
        thresholds, epsilons = [lower, upper], [epsilon, epsilon]
        eps_keys = [r.key("epsilon")] * 2
        band_modes = [outside, inside, outside]
        unused_hint = " (the lower/upper shorthand schedules two modes: use bands)"
        default_initial = inside
    for b in range(1, len(thresholds)):  # the middle bands need a region beyond the margins
        if not thresholds[b - 1] + epsilons[b - 1] < thresholds[b] - epsilons[b]:
            key = eps_keys[b] if eps_keys[b] != r.key("epsilon") else eps_keys[b - 1]
            raise ConfigError(key, f"too big for the band {thresholds[b - 1]} .. "
                              f"{thresholds[b]}: its hysteresis margins leave no region "
                              f"where that band's mode is chosen")
    for j, name in enumerate(names):
        if j not in band_modes:
            raise ConfigError(r.key("bands") if not unused_hint else r.path,
                              f"mode {name!r} (modes[{j}]) serves no band{unused_hint}")
    sc = SchedulerConfig(signal=signal, thresholds=tuple(thresholds),
                         epsilons=tuple(epsilons), band_modes=tuple(band_modes), initial=-1)
    if r.has("initial"):
        initial = mode_index(r, "initial")
    else:  # the shorthand's inside mode, else the mode of the band that contains 0
        initial = default_initial if default_initial is not None else band_modes[sc.band_of(0.0)]
    r.finish()
    return replace(sc, initial=initial)


def _bands(r: _Reader, epsilon: float, mode_index) -> tuple[list, list, list, list]:
    """``scheduler.bands``: each ``{mode, below, epsilon}``; the last band has no ``below``.

    Returns the thresholds, their margins, the key each margin came from, and the band modes.
    """
    raw = r.raw("bands")
    key = r.key("bands")
    if not isinstance(raw, list) or len(raw) < 2:
        raise ConfigError(key, "must be a list of at least two bands (one mode needs no "
                          "scheduler)")
    thresholds: list[float] = []
    epsilons: list[float] = []
    eps_keys: list[str] = []
    band_modes: list[int] = []
    for i, item in enumerate(raw):
        b = _Reader(item, f"{key}[{i}]")
        band_modes.append(mode_index(b, "mode"))
        if i == len(raw) - 1:
            if b.has("below"):
                raise ConfigError(b.key("below"), "the last band is unbounded above: "
                                  "remove below")
            if b.has("epsilon"):
                raise ConfigError(b.key("epsilon"), "the last band has no threshold "
                                  "(epsilon is the margin of below)")
        else:
            t = b.number("below")
            if thresholds and not t > thresholds[-1]:
                raise ConfigError(b.key("below"), f"thresholds must increase: {t} is not "
                                  f"above {thresholds[-1]} ({key}[{i - 1}].below)")
            thresholds.append(t)
            if b.has("epsilon"):
                epsilons.append(b.number("epsilon", nonnegative=True))
                eps_keys.append(b.key("epsilon"))
            else:
                epsilons.append(epsilon)
                eps_keys.append(r.key("epsilon"))
        b.finish()
    if len(set(band_modes)) == 1:
        raise ConfigError(key, "every band has the same mode: one mode needs no scheduler")
    for i in range(1, len(band_modes)):
        if band_modes[i] == band_modes[i - 1]:
            raise ConfigError(f"{key}[{i}].mode", f"same mode as {key}[{i - 1}]: merge the "
                              "two bands")
    return thresholds, epsilons, eps_keys, band_modes


def _solver(r: _Reader) -> SolverConfig:
    d = SolverConfig()
    method = r.string("method", d.method, choices=SOLVER_METHODS)
    omega = r.number("omega", d.omega)
    if not 0.0 < omega < 2.0:
        raise ConfigError(r.key("omega"), f"SOR needs 0 < omega < 2, got {omega}")
    sigma = r.number("sigma", d.sigma, nonnegative=True)
    delta = r.number("delta", d.delta, positive=True)
    max_iterations = r.integer("max_iterations", d.max_iterations, minimum=1, maximum=MAX_C_INT)
    warm_start = r.boolean("warm_start", d.warm_start)
    polish = r.boolean("polish", d.polish)
    polish_first = r.boolean("polish_first", d.polish_first)
    polish_every = r.integer("polish_every", d.polish_every, minimum=1, maximum=MAX_C_INT)
    polish_max = r.integer("polish_max", d.polish_max, minimum=1, maximum=MAX_C_INT)
    tol = r.number("feasibility_tol", None, positive=True) if r.has("feasibility_tol") else None
    active_set = r.boolean("active_set", d.active_set)
    active_set_max = r.integer("active_set_max", d.active_set_max, minimum=1,
                               maximum=MAX_C_INT)
    dep_tol = (r.number("dependence_tol", None, positive=True)
               if r.has("dependence_tol") else None)
    if dep_tol is not None and not dep_tol < 1.0:
        raise ConfigError(r.key("dependence_tol"), f"must be < 1, got {dep_tol}")
    if active_set and not polish and r.has("active_set"):
        raise ConfigError(r.key("active_set"), "needs polish: true (its working set is "
                          "finished by the polish step)")
    r.finish()
    return SolverConfig(method=method, omega=omega, sigma=sigma, delta=delta,
                        max_iterations=max_iterations, warm_start=warm_start, polish=polish,
                        polish_first=polish_first,
                        polish_every=polish_every, polish_max=polish_max,
                        feasibility_tol=tol, active_set=active_set,
                        active_set_max=active_set_max, dependence_tol=dep_tol)


def _reference(r: _Reader, n_outputs: int,
               sample_time: float) -> tuple[tuple[tuple[float, ...], ...], float]:
    """``simulation.reference``: levels (a scalar is applied to every output) and segment."""
    raw = r.raw("levels")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(r.key("levels"), "must be a non-empty list of levels")
    levels = tuple(tuple(_vector(v, f"{r.key('levels')}[{i}]", n_outputs))
                   for i, v in enumerate(raw))
    segment = r.number("segment", positive=True)
    if round(segment / sample_time) < 1:
        raise ConfigError(r.key("segment"), f"must be at least sample_time ({sample_time})")
    r.finish()
    return levels, segment


def _check_horizon(horizon: int, modes: tuple[ModeConfig, ...]) -> None:
    """Reject a horizon whose QP overflows the C's int16 row tables *before* building it.

    The row count is that of mpc._constraints: 2 nu box rows per stage and one row per
    finite output bound on stages 1..N.  Checking after condensing is too late: a typo
    like ``horizon: 100000`` would first allocate and fill N^2-sized matrices for hours.
    """
    for i, m in enumerate(modes):
        moves = horizon if m.blocks is None else len(m.blocks)  # input rows: per block
        rows = (moves * 2 * len(m.actuators) + horizon * (int(np.isfinite(m.y_min).sum())
                                                          + int(np.isfinite(m.y_max).sum())))
        if rows > MAX_ROWS:
            raise ConfigError("horizon", f"too long: modes[{i}] would have {rows} QP rows; "
                              f"at most {MAX_ROWS} supported")


def _check_range(precision: str, modes: tuple[ModeConfig, ...],
                 scheduler: SchedulerConfig | None, solver: SolverConfig) -> None:
    """Every number the C stores as a literal must be finite in the storage precision.

    Otherwise the failure surfaces much later, as a non-finite literal while rendering.
    """
    limit = FLOAT_MAX if precision == "float" else sys.float_info.max
    values: list[tuple[str, Any]] = []
    for i, m in enumerate(modes):
        k = f"modes[{i}]"
        values += [(f"{k}.weights.Q", m.Q), (f"{k}.weights.R", m.R), (f"{k}.weights.P", m.P),
                   (f"{k}.bounds.u_min", m.u_min), (f"{k}.bounds.u_max", m.u_max),
                   # infinite output bounds mean "unbounded" and are never written
                   (f"{k}.bounds.y_min", m.y_min[np.isfinite(m.y_min)]),
                   (f"{k}.bounds.y_max", m.y_max[np.isfinite(m.y_max)])]
        if m.du_min is not None:
            values += [(f"{k}.bounds.du_min", m.du_min[np.isfinite(m.du_min)]),
                       (f"{k}.bounds.du_max", m.du_max[np.isfinite(m.du_max)])]
    if scheduler is not None:  # the C stores every threshold -/+ its epsilon
        values += [("scheduler", scheduler.below), ("scheduler", scheduler.above)]
    values += [("solver.sigma", solver.sigma), ("solver.delta", solver.delta),
               ("solver.feasibility_tol", solver.feasibility_tol or 0.0)]
    for key, value in values:
        arr = np.abs(np.asarray(value, dtype=float))
        if arr.size and not arr.max() <= limit:
            raise ConfigError(key, f"a value of magnitude {arr.max():.3g} does not fit in "
                              f"{precision} precision (max {limit:.3g})")
    if scheduler is not None and precision == "float":
        # rounded to float, every middle band must keep a region where its mode is chosen
        below, above = np.float32(scheduler.below), np.float32(scheduler.above)
        if not np.all(above[:-1] < below[1:]):
            raise ConfigError("scheduler", "in float precision the thresholds -/+ epsilon "
                              "leave a band with no region where its mode is chosen")


def _units(u: _Reader, outputs: tuple[str, ...], actuators: tuple[str, ...]) -> UnitsConfig:
    """``units: {outputs, actuators, schedule}``: a unit string per signal (one string for
    all outputs / actuators is allowed); every entry optional."""
    def per_signal(name: str, count: int) -> tuple[str, ...]:
        value = u.raw(name, "")
        value = [value] * count if isinstance(value, str) else value
        if not isinstance(value, list) or len(value) != count or not all(
                isinstance(v, str) for v in value):
            raise ConfigError(u.key(name), f"must be a unit string or a list of {count} "
                              f"(one per {name[:-1]})")
        return tuple(value)

    units = UnitsConfig(outputs=per_signal("outputs", len(outputs)),
                        actuators=per_signal("actuators", len(actuators)),
                        schedule=u.string("schedule", ""))
    u.finish()
    return units


def parse(data: Any) -> ControllerConfig:
    """Validate a parsed YAML document into a :class:`ControllerConfig`."""
    r = _Reader(data, "")
    prefix = r.string("prefix", "rollmpc")
    if not re.match(r"^[a-z][a-z0-9_]{0,30}$", prefix):
        raise ConfigError("prefix", "must be a lower-case C identifier of at most 31 "
                          f"characters, got {prefix!r}")
    precision = r.string("precision", "double", choices=PRECISIONS)
    sample_time = r.number("sample_time", positive=True)
    horizon = r.integer("horizon", minimum=1)
    outputs = r.names("outputs")
    actuators = r.names("actuators")
    raw_modes = r.raw("modes")
    if not isinstance(raw_modes, list) or not raw_modes:
        raise ConfigError("modes", "must be a non-empty list of modes")
    from ..features.move_blocking import blocks_of  # (it imports ConfigError from here)
    default_blocks = blocks_of(r.raw("control_horizon", None), r.raw("move_blocking", None),
                               horizon, "")
    modes = tuple(_mode(_Reader(m, f"modes[{i}]"), outputs, actuators, horizon, default_blocks)
                  for i, m in enumerate(raw_modes))
    _check_horizon(horizon, modes)
    names = [m.name for m in modes]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise ConfigError(f"modes[{i}].name", f"duplicate mode name {n!r}")
    if len(modes) == 1:
        if r.has("scheduler"):
            raise ConfigError("scheduler", "a single-mode controller has no scheduler")
        scheduler = None
    else:
        scheduler = _scheduler(r.sub("scheduler"), modes)
    solver = _solver(r.sub("solver", {}))
    runtime_bounds = r.boolean("runtime_bounds", False)
    rate = [i for i, m in enumerate(modes) if m.has_rate_bounds]
    if runtime_bounds and rate:
        raise ConfigError("runtime_bounds", f"is not supported with Δu bounds (modes[{rate[0]}]"
                          ".bounds.du_min/du_max): their rows are not updatable at run time")
    for i, m in enumerate(modes):
        if m.has_rate_bounds and m.blocks is not None:
            raise ConfigError(f"modes[{i}].bounds.du_min", "Δu bounds are not supported with "
                              "move blocking / a control horizon (rate rows are built per "
                              "stage); remove one of them")
    sim = r.sub("simulation", {})
    schedule_source = sim.string("schedule_source", "output_rate", choices=SCHEDULE_SOURCES)
    levels, segment = (_reference(sim.sub("reference"), len(outputs), sample_time)
                       if sim.has("reference") else (None, None))
    simulation = SimulationConfig(schedule_source=schedule_source, reference_levels=levels,
                                  reference_segment_s=segment)
    sim.finish()
    units = _units(r.sub("units"), outputs, actuators) if r.has("units") else UnitsConfig()
    r.finish()
    _check_range(precision, modes, scheduler, solver)
    if simulation.schedule_source == "output_rate" and scheduler is not None:
        for i, m in enumerate(modes):
            if not m.plant.integrator:
                raise ConfigError(f"modes[{i}].plant.integrator",
                                  "simulation.schedule_source output_rate needs integrator: true")
    return ControllerConfig(prefix=prefix, precision=precision, sample_time=sample_time,
                            horizon=horizon, outputs=outputs, actuators=actuators, modes=modes,
                            scheduler=scheduler, solver=solver, simulation=simulation,
                            runtime_bounds=runtime_bounds, units=units)


def _yaml_problem(exc: yaml.YAMLError) -> tuple[str, str]:
    """(where, what) of a PyYAML error; its str() spans several lines, so not that."""
    if isinstance(exc, yaml.reader.ReaderError):  # a control character; it has no mark
        what = f"{exc.reason} (#x{exc.character:04x})"
        return f"<yaml character {exc.position + 1}>", f"not valid YAML: {what}"
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f"<yaml line {mark.line + 1}>" if mark else "<yaml>"
    what = getattr(exc, "problem", None) or getattr(exc, "context", None) or type(exc).__name__
    return where, f"not valid YAML: {what}"


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects a key given twice in one mapping (PyYAML keeps the last)."""


def _unique_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:  # an unhashable key: construct_mapping reports it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _unique_mapping)


def load(path: str | Path, precision: str | None = None) -> ControllerConfig:
    """Read and validate a YAML file; ``precision`` overrides the file's setting."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read: {exc.strerror}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(str(path), f"not UTF-8 text (byte {exc.start})") from None
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as exc:
        raise ConfigError(*_yaml_problem(exc)) from None
    if data is None:
        raise ConfigError("<top>", "the file is empty")
    if precision is not None:
        if precision not in PRECISIONS:
            raise ConfigError("precision", f"must be one of {', '.join(PRECISIONS)}")
        if isinstance(data, dict):
            data = dict(data, precision=precision)
    return parse(data)
