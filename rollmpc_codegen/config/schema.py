"""The configuration's schema: its frozen dataclasses, the keys of each YAML section, its
choices and limits, and every default of a key, declared once.

A key's default is the default of its dataclass field; the few keys without a field of
their own (``prefix``, ``precision``, ``scheduler.epsilon``, an absent bound, a solver
tolerance left to the precision) have a named default below.  The parsers read them from
here, and so does every later stage (codegen/context.py: the precision's tolerances).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from functools import cached_property

import numpy as np

from .aircraft_types import AIRCRAFT_KEYS, AircraftConfig  # noqa: F401  (the keys: re-exported)
from .canonical import OMIT_AT_DEFAULT, canonical_json, config_digest
from .constraint_types import SignalConstraint, TerminalConfig
from .keys import section_keys
from ..parts import CORES, DEFAULT_PART, PARTS, Core

SOLVER_METHODS = ("hildreth", "hildreth_plus", "hildreth_plus_prime")
PRECISIONS = ("double", "float")
SCHEDULE_SOURCES = ("output_rate", "output")
OBSERVER_KINDS = ("poles", "kalman")
DISTURBANCE_MODELS = ("none", "input", "output")
# The C indexes QP rows and variables with int16_t and counts iterations with int.
MAX_ROWS = 32767
MAX_C_INT = 2**31 - 1
FLOAT_MAX = float(np.finfo(np.float32).max)

# --------------------------------------------------------------------------- hostile input
# Limits that keep a hostile or mistaken file from costing minutes or gigabytes
# (docs/reliability.md, "Hostile input").  The config file is read up to MAX_CONFIG_BYTES;
# its YAML may hold MAX_YAML_NODES nodes, nested MAX_YAML_DEPTH deep, and its aliases may
# repeat MAX_ALIAS_NODES nodes in all (an alias bomb repeats billions).
MAX_CONFIG_BYTES = 1 << 20
MAX_YAML_NODES = 100_000
MAX_YAML_DEPTH = 32
MAX_ALIAS_NODES = 10_000
MAX_LIST_LENGTH = 256  # entries of any list the reader converts, checked before it does
MAX_STATES = 256  # of a mode's prediction model: its observer and PBH tests cost O(nx^4)
# The generated data of all modes (flash) and one P_ctrl instance (RAM), predicted before
# the maths (qp/sizes.py): beyond the memory of any microcontroller.
MAX_STORED_BYTES = 16 << 20
MAX_STRUCT_BYTES = 4 << 20
# the dense N ny x N ny, N nu x N nu and N ny x N nu matrices condensing builds, blocked or not
MAX_CONDENSING_BYTES = 512 << 20
# The prefix names the generated files, <prefix>.h among them, so it must not be a
# header the generated C or its users include: <prefix>.h would shadow it on the include
# path.  Every standard C header (C89 to C23), and common POSIX, toolchain and MCU ones.
PREFIX_PATTERN = r"[a-z][a-z0-9_]{0,30}"  # a lower-case C identifier (full match)
C_STANDARD_HEADERS = (
    "assert", "complex", "ctype", "errno", "fenv", "float", "inttypes", "iso646", "limits",
    "locale", "math", "setjmp", "signal", "stdalign", "stdarg", "stdatomic", "stdbit",
    "stdbool", "stdckdint", "stddef", "stdint", "stdio", "stdlib", "stdnoreturn", "string",
    "tgmath", "threads", "time", "uchar", "wchar", "wctype")
SYSTEM_HEADERS = (
    "alloca", "arm_acle", "arm_math", "arm_neon", "cmsis_compiler", "cmsis_gcc", "dirent",
    "dlfcn", "endian", "fcntl", "features", "freertos", "getopt", "libgen", "main", "malloc",
    "memory", "poll", "pthread", "sched", "semaphore", "strings", "syslog", "termios",
    "unistd")
RESERVED_PREFIXES = C_STANDARD_HEADERS + SYSTEM_HEADERS

# --------------------------------------------------------------------------- defaults
DEFAULT_PREFIX = "rollmpc"
DEFAULT_PRECISION = "double"
# the target's clock (`target.cpu_mhz`): `rollmpc report`'s cycle budget per sample and
# what `solver.work_budget: auto` follows (qp/work.py derives the budget); without
# target.part, the default part's core and clock (parts.py)
DEFAULT_CORE = PARTS[DEFAULT_PART].core.name
DEFAULT_CPU_MHZ = PARTS[DEFAULT_PART].cpu_mhz
WORK_BUDGET_AUTO = "auto"  # solver.work_budget: derived from the sample time and the clock
DEFAULT_EPSILON = 0.5  # scheduler.epsilon: the hysteresis margin of every threshold
UNBOUNDED = math.inf  # an absent output or Δu bound: -UNBOUNDED .. UNBOUNDED, no QP rows
NO_UNIT = ""  # units: a signal without a unit (none is shown)
# simulation.reference: the closed-loop scenario of the paper's section 4.1, these levels
# on every output, each held PAPER_SEGMENT_S seconds
PAPER_LEVELS_DEG = (0.0, -20.0, 20.0, -40.0, 40.0, 0.0)
PAPER_SEGMENT_S = 10.0
# modes[].observer.innovation_limit: the default is this many spans of the output's
# expected range (default_innovation_limit)
INNOVATION_LIMIT_SPANS = 10.0
# ...and where the config gives an output no range (no finite bound, a zero reference), the
# parser leaves this mark and the pipeline derives the limit from the model (model/reach.py)
DERIVED_FROM_MODEL = math.nan


def storage_range(precision: str) -> tuple[float, float]:
    """(smallest normal, largest finite) magnitude of the storage precision."""
    info = np.finfo(np.float32 if precision == "float" else np.float64)
    return float(info.tiny), float(info.max)


def default_feasibility_tol(precision: str) -> float:
    """Relative primal feasibility tolerance: tol * max(1, |gamma_r|)."""
    return 1e-9 if precision == "double" else 1e-4


def default_innovation_limit(y_min: np.ndarray, y_max: np.ndarray,
                             levels: np.ndarray) -> np.ndarray:
    """Per output, the largest plausible innovation |y - C x̂| (docs/features.md,
    "Measurement plausibility"): INNOVATION_LIMIT_SPANS times the span of the output's
    expected range, the hull of 0 (the estimate after P_init), its finite bounds and, when
    a side is unbounded, the scenario's reference ``levels`` (levels x outputs).  While the
    measurement and the prediction both lie in that range, no innovation exceeds its span.
    0 where nothing gives a range (the model's reach then gives one, model/reach.py), inf
    where it overflows (bounds near the largest double: the parser refuses it)."""
    out = np.empty(len(y_min))
    for a, bounds in enumerate(zip(y_min, y_max)):
        values = [0.0, *(b for b in bounds if math.isfinite(b))]
        if len(values) < 3:  # a side without a bound: the reference spans it
            values += list(levels[:, a])
        with np.errstate(over="ignore"):  # an overflow is the inf the parser refuses
            out[a] = INNOVATION_LIMIT_SPANS * (max(values) - min(values))
    return out


def default_dependence_tol(precision: str) -> float:
    """A row is dependent on the working set when its pivot H_pp - H_pW H_WW^-1 H_Wp is
    below tol * H_pp (about 1e6 roundoffs of the storage precision)."""
    return 1e-10 if precision == "double" else 1e-5


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
    # observer.innovation_limit: per output, |y - C x̂| beyond it is clipped to it (+inf:
    # never); the parser fills in default_innovation_limit, DERIVED_FROM_MODEL (NaN) where
    # only the model gives a range (the pipeline derives those entries, model/reach.py)
    innovation_limit: np.ndarray | None = None  # (ny,)
    # modes[].constraints (features/signals.py): constrained signals and mixed rows, one
    # scalar signal each, and the terminal constraint
    signals: tuple[SignalConstraint, ...] = field(default=(), metadata=OMIT_AT_DEFAULT)
    terminal: TerminalConfig | None = field(default=None, metadata=OMIT_AT_DEFAULT)

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
    # work units a solve may spend (docs/solver.md "Work budget"), or WORK_BUDGET_AUTO:
    # budget_share of the sample time at target.cpu_mhz (qp/work.py)
    work_budget: int | str = WORK_BUDGET_AUTO
    budget_share: float = 0.5


@dataclass(frozen=True)
class SimulationConfig:
    schedule_source: str = "output_rate"
    # the piecewise-constant reference of ``rollmpc simulate/bench/report``: one row of
    # n_outputs values per level, each held reference_segment_s seconds; None -> the
    # paper's scenario (scenario.paper_reference, applied to every output)
    reference_levels: tuple[tuple[float, ...], ...] | None = None
    reference_segment_s: float | None = None

    def levels(self, n_outputs: int) -> np.ndarray:
        """The scenario's reference levels, one row of ``n_outputs`` values per level."""
        if self.reference_levels is None:
            return np.repeat(np.asarray(PAPER_LEVELS_DEG)[:, None], n_outputs, axis=1)
        return np.asarray(self.reference_levels, dtype=float)

    @property
    def segment_s(self) -> float:
        """How long each level is held (s)."""
        return PAPER_SEGMENT_S if self.reference_segment_s is None else self.reference_segment_s


@dataclass(frozen=True)
class UnitsConfig:
    """Units of the signals, for labels only (``rollmpc simulate``'s summary and --plot);
    "" = no unit shown.  The top-level ``units`` key; the generated C never sees them."""

    outputs: tuple[str, ...] = ()  # one per output, or () for none
    actuators: tuple[str, ...] = ()  # one per actuator, or () for none
    schedule: str = NO_UNIT  # the scheduling signal's unit

    def label(self, signals: str) -> str:
        """`` [u]`` when every one of the ``signals`` (outputs, actuators or schedule) has
        the unit u, else "" (no unit, or mixed units)."""
        value = getattr(self, signals)
        found = {value} if isinstance(value, str) else set(value)
        return f" [{found.pop()}]" if len(found) == 1 and NO_UNIT not in found else ""


# What `rollmpc generate` refuses (unless --force-size) when the target: section leaves
# flash_kib / ram_kib out (qp/footprint.py): the largest declared part's (parts.py).
DEFAULT_FLASH_LIMIT_KIB = max(p.flash.kib for p in PARTS.values())
DEFAULT_RAM_LIMIT_KIB = max(p.ram.kib for p in PARTS.values())


@dataclass(frozen=True)
class TargetConfig:
    """The microcontroller ``rollmpc report`` judges the design on and ``rollmpc
    generate`` checks its predicted size against (the top-level ``target`` key); the
    generated C sees only its work budget (``solver.work_budget: auto``).  ``None``: no
    verdict on that figure in the report, the DEFAULT_*_LIMIT_KIB above at generation."""

    cpu_mhz: float = DEFAULT_CPU_MHZ  # core clock: a sample has cpu_mhz * 1e6 * Ts cycles
    flash_kib: float | None = None  # flash the image must fit (KiB)
    ram_kib: float | None = None  # static RAM the image, and the instance alone, must fit
    part: str | None = field(default=None, metadata=OMIT_AT_DEFAULT)  # parts.PARTS; None: unnamed
    core: str = field(default=DEFAULT_CORE, metadata=OMIT_AT_DEFAULT)  # parts.CORES

    @property
    def core_decl(self) -> Core:
        """The core's declaration: its flags, FPU, cycle model and calibrations."""
        return CORES[self.core]

    @property
    def label(self) -> str:
        """The part (or the core) and the clock, for people."""
        core = self.core_decl.label
        what = f"{self.part.upper()} ({core})" if self.part else f"a {core}"
        return f"{what} at {self.cpu_mhz:g} MHz"


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
    target: TargetConfig = TargetConfig()  # what `rollmpc report` judges on
    aircraft: AircraftConfig | None = field(default=None, metadata=OMIT_AT_DEFAULT)  # identify

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
    def feasibility_tol(self) -> float:
        """The solver's relative feasibility tolerance: the configured one, else the
        precision's default."""
        tol = self.solver.feasibility_tol
        return default_feasibility_tol(self.precision) if tol is None else tol

    @property
    def n_schedule(self) -> int:
        return 0 if self.scheduler is None else 1

    @property
    def cycles_per_sample(self) -> int:
        """The cycle budget of one step: one sample time at ``target.cpu_mhz``."""
        return int(round(self.target.cpu_mhz * 1e6 * self.sample_time))


# --------------------------------------------------------------------------- keys
# The keys each YAML section accepts, declared with their defaults and meanings in keys.py
# (docs/config.md is generated from there); the reader reports any other key before it
# reads anything of that section.
TOP_KEYS = section_keys("")
MODE_KEYS = section_keys("modes[]")
PLANT_KEYS = section_keys("modes[].plant")
TRANSFER_FUNCTION_KEYS = section_keys("modes[].plant.transfer_function")
STATE_SPACE_KEYS = section_keys("modes[].plant.state_space")
WEIGHT_KEYS = section_keys("modes[].weights")
BOUND_KEYS = section_keys("modes[].bounds")
SOFT_KEYS = section_keys("modes[].bounds.soft")
PENALTY_KEYS = section_keys("modes[].bounds.soft.<side>")  # bounds.soft.y_min / y_max
CONSTRAINT_KEYS = section_keys("modes[].constraints")
SIGNAL_KEYS = section_keys("modes[].constraints.signals.<name>")
MIXED_KEYS = section_keys("modes[].constraints.mixed.<name>")
TERMINAL_KEYS = section_keys("modes[].constraints.terminal")
TERMINAL_KINDS = ("lqr_invariant", "polytope", "equality")
OBSERVER_KEYS = section_keys("modes[].observer")
SHORTHAND_KEYS = section_keys("scheduler", group="shorthand")  # the two-mode form
SCHEDULER_KEYS = section_keys("scheduler")
BAND_KEYS = section_keys("scheduler.bands[]")
SOLVER_KEYS = tuple(f.name for f in fields(SolverConfig))  # one key per setting
SIMULATION_KEYS = section_keys("simulation")
REFERENCE_KEYS = section_keys("simulation.reference")
UNITS_KEYS = tuple(f.name for f in fields(UnitsConfig))
TARGET_KEYS = tuple(f.name for f in fields(TargetConfig))
