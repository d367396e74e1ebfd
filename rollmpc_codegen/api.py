"""The Python API beside the CLI: a design built in a notebook, with no YAML file.

``Mode`` and ``Design`` only assemble the nested dict that a YAML file gives (keys named as
in the README's "Configuration schema") and validate it with :func:`config.parse`, so the
checks and the ``ConfigError`` messages are the CLI's. Generation and the host build are
the CLI's too (pipeline.py, host/build.py): a design and its ``to_yaml()`` render
byte-identical files. Plants may be python-control ``TransferFunction``/``StateSpace``
objects (continuous, or discrete at the design's sample time), ``(A, B, C[, D])`` tuples
or dicts in the YAML form.
"""
from __future__ import annotations

import copy
import math
import numbers
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .config import ConfigError, ControllerConfig, parse
from .config.diagnostics import emit
from .config.reader import unknown_key
from .config.schema import MODE_KEYS

WEIGHT_KEYS = ("Q", "R", "P", "R_delta")  # Mode keywords that go to ``weights``
BOUND_KEYS = ("u_min", "u_max", "y_min", "y_max", "du_min", "du_max", "soft")  # to ``bounds``
BOUND_PAIRS = {"u_bounds": ("u_min", "u_max"), "y_bounds": ("y_min", "y_max"),
               "du_bounds": ("du_min", "du_max")}  # (lower, upper) shorthands
PASSED_KEYS = ("control_horizon", "move_blocking")  # to the mode's YAML mapping as they are
MODE_KEYWORDS = (*MODE_KEYS, "integrator", *WEIGHT_KEYS, *BOUND_KEYS, *BOUND_PAIRS)  # Mode()'s


def yaml_data(value: Any) -> Any:
    """``value`` as the plain data ``yaml.safe_load`` would give: numpy arrays and tuples
    become lists, numpy scalars Python numbers, a complex observer pole ``[re, im]``."""
    if isinstance(value, dict):
        return {str(k): yaml_data(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return yaml_data(value.tolist())
    if isinstance(value, (list, tuple)):
        return [yaml_data(v) for v in value]
    if isinstance(value, np.generic):
        return yaml_data(value.item())
    if isinstance(value, complex):
        return [value.real, value.imag]
    return value


def _is_python_control(plant: Any) -> bool:
    return type(plant).__module__.split(".")[0] == "control"


def _discrete_time(plant: Any, sample_time: float, key: str) -> bool:
    """Whether a python-control system is discrete; its dt must be the sample time."""
    dt = plant.dt
    if dt is None or dt == 0:
        return False
    if dt is True or math.isclose(dt, sample_time, rel_tol=1e-9):
        return True
    raise ConfigError(key, f"is discrete with dt = {dt!r}, but sample_time is {sample_time!r}: "
                      "resample it (control.sample_system) or give the continuous plant")


def _python_control_plant(plant: Any, sample_time: float, key: str) -> dict:
    """A python-control system as the YAML ``plant`` mapping."""
    import control

    discrete = _discrete_time(plant, sample_time, key)
    if isinstance(plant, control.TransferFunction) and not discrete:
        num = getattr(plant, "num_list", plant.num)  # python-control >= 0.10.1 / 0.10.0
        den = getattr(plant, "den_list", plant.den)
        if (plant.noutputs, plant.ninputs) == (1, 1):
            return {"transfer_function": {"num": num[0][0], "den": den[0][0]}}
        return {"transfer_function": {"num": num, "den": den}}
    if isinstance(plant, control.TransferFunction):  # the YAML has no discrete TF form
        try:
            plant = control.ss(plant)
        except Exception as exc:  # a MIMO realisation needs slycot
            raise ConfigError(key, f"cannot realise the discrete transfer function "
                              f"({exc}); give a StateSpace") from None
    if not isinstance(plant, control.StateSpace):
        raise ConfigError(key, f"must be a TransferFunction or a StateSpace, got "
                          f"{type(plant).__name__}")
    return {"state_space": {"A": plant.A, "B": plant.B, "C": plant.C, "D": plant.D,
                            "discrete": discrete}}


def plant_entry(plant: Any, sample_time: Any, key: str) -> dict:
    """The YAML ``plant`` mapping of a python-control system, an ``(A, B, C[, D])`` tuple
    (continuous), ``{num, den}``, ``{A, B, C, D, discrete}`` or the YAML mapping itself."""
    if _is_python_control(plant):
        if isinstance(sample_time, bool) or not isinstance(sample_time, numbers.Real):
            raise ConfigError("sample_time", f"must be a number, got {sample_time!r}")
        return _python_control_plant(plant, float(sample_time), key)
    if isinstance(plant, (tuple, list)) and len(plant) in (3, 4):
        return {"state_space": dict(zip("ABCD", plant))}
    if isinstance(plant, dict):
        if "num" in plant:
            return {"transfer_function": dict(plant)}
        if "A" in plant:
            return {"state_space": dict(plant)}
        return dict(plant)
    raise ConfigError(key, "must be a control.TransferFunction or StateSpace, an (A, B, C[, "
                      f"D]) tuple or a dict, got {type(plant).__name__}")


class Mode:
    """One mode of a design: a plant and its weights, bounds and observer.

    Keywords are the YAML keys of ``modes[]``: ``Q, R, P, R_delta`` (or ``weights={...}``),
    ``u_min, u_max, y_min, y_max, du_min, du_max, soft`` (or ``bounds={...}``) with the
    pairs ``u_bounds=(lo, hi)``, ``y_bounds``, ``du_bounds``; ``observer={...}``,
    ``control_horizon``, ``move_blocking``. ``actuators`` defaults to every actuator of
    the design.
    """

    def __init__(self, name: str, plant: Any, *, actuators=None, integrator=None,
                 weights: dict | None = None, bounds: dict | None = None,
                 observer: dict | None = None, **options):
        self.name = name
        self.plant = plant
        self.actuators = actuators
        self.integrator = integrator
        self.weights = dict(weights or {})
        self.bounds = dict(bounds or {})
        self.observer = observer
        self.options = {}  # control_horizon, move_blocking (parse names any unknown key)
        self.pairs = {}
        for key, value in options.items():
            if key in WEIGHT_KEYS:
                self.weights[key] = value
            elif key in BOUND_KEYS:
                self.bounds[key] = value
            elif key in BOUND_PAIRS:
                self.pairs[key] = value
            else:
                self.options[key] = value

    def entry(self, index: int, sample_time: Any, actuators) -> dict:
        """This mode as the YAML mapping ``modes[index]``."""
        key = f"modes[{index}]"
        bounds = dict(self.bounds)
        for pair, (lo, hi) in BOUND_PAIRS.items():
            if pair in self.pairs:
                value = self.pairs[pair]
                if not (isinstance(value, (tuple, list, np.ndarray)) and len(value) == 2):
                    raise ConfigError(f"{key}.bounds", f"{pair} must be a pair ({lo}, {hi}), "
                                      f"got {value!r}")
                bounds[lo], bounds[hi] = value
        for name in self.options:  # named here: parse would not suggest the API's keywords
            if name not in PASSED_KEYS:
                raise ConfigError(f"{key}.{name}", unknown_key(name, MODE_KEYWORDS))
        plant = plant_entry(self.plant, sample_time, f"{key}.plant")
        if self.integrator is not None:
            plant["integrator"] = self.integrator
        entry = {"name": self.name,
                 "actuators": actuators if self.actuators is None else self.actuators,
                 "plant": plant, "weights": self.weights, "bounds": bounds}
        if self.observer is not None:
            entry["observer"] = self.observer
        entry.update(self.options)
        return entry

    def __repr__(self) -> str:
        return f"Mode({self.name!r}, plant={type(self.plant).__name__})"


class Design:
    """A whole controller: modes, the shared signals, and any other top-level YAML key
    (``prefix, precision, scheduler, solver, simulation, units, target, runtime_bounds,
    control_horizon, move_blocking``) as keywords; ``None`` leaves a key out.

    A mode is a :class:`Mode` or its YAML mapping. Validated on construction
    (``ConfigError`` naming the key as in YAML); ``config`` is the parsed
    :class:`ControllerConfig`.
    """

    def __init__(self, sample_time: float, horizon: int, outputs, actuators, modes,
                 **options):
        if not isinstance(modes, (list, tuple)) or not modes:
            raise ConfigError("modes", "must be a non-empty list of modes")
        entries = [m.entry(i, sample_time, actuators) if isinstance(m, Mode) else m
                   for i, m in enumerate(modes)]
        data = {"sample_time": sample_time, "horizon": horizon, "outputs": outputs,
                "actuators": actuators, "modes": entries}
        data.update((k, v) for k, v in options.items() if v is not None)
        self.data = yaml_data(data)
        self.config: ControllerConfig = parse(self.data)
        self._built: dict[str, tuple] = {}  # precision -> (model, context)

    def to_dict(self) -> dict:
        """The nested dict of the YAML form (a copy)."""
        return copy.deepcopy(self.data)

    def to_yaml(self, path: str | Path | None = None) -> str:
        """The design as a YAML config for ``rollmpc``; also written to ``path`` if given."""
        text = yaml.safe_dump(self.data, sort_keys=False, default_flow_style=None)
        if path is not None:
            Path(path).write_text(text)
        return text

    def config_for(self, precision: str | None) -> ControllerConfig:
        """The config, with the precision overridden as ``--precision`` does."""
        if precision is None or precision == self.config.precision:
            return self.config
        return parse(dict(self.data, precision=precision))

    def build(self, precision: str | None = None) -> tuple:
        """(model, context) of the pipeline, computed once per precision."""
        from .pipeline import load_model_from_config

        cfg = self.config_for(precision)
        if cfg.precision not in self._built:
            self._built[cfg.precision] = load_model_from_config(cfg)
        return self._built[cfg.precision]

    def generate(self, out_dir: str | Path, precision: str | None = None,
                 force: bool = False, force_size: bool = False, float_check: bool = True,
                 build_dir: str | Path | None = None):
        """Write the generated C into ``out_dir``: the files of ``rollmpc generate`` and
        its rules (only rollmpc's own files are replaced; ``force`` as ``--force``; a
        design beyond its target is refused before the maths unless ``force_size``), its
        design warnings and, for a float build unless ``float_check`` is False, its float
        check.  Returns the :class:`~rollmpc_codegen.host.generate_run.GenerateRun`
        (path-like: its directory; ``warnings``, ``footprint``, ``float_check``); each
        warning also goes to Python's ``warnings`` as a RollmpcWarning."""
        from .host.generate_run import run_generate

        run = run_generate(self, out_dir, precision=precision, force=force,
                           force_size=force_size)
        self._built.setdefault(run.ctx["precision"], (run.model, run.ctx))
        if run.ctx["precision"] == "float" and float_check:
            run.check_float(build_dir)
        emit(run.warnings)
        return run

    def simulate(self, **options):
        """``rollmpc simulate``: :func:`~rollmpc_codegen.sim.scenario_run.run_scenario`
        with its keywords (``precision, steps, noise_std, disturbance, mismatch, seed,
        baseline, build_dir``), or with ``flights=K``
        :func:`~rollmpc_codegen.sim.flights_run.run_flights`; the run's ``summary`` is
        the ``--json`` document, its ``warnings`` what the CLI prints (also warned)."""
        if options.get("flights"):
            from .sim.flights_run import run_flights

            run = run_flights(self, **options)
        else:
            from .sim.scenario_run import run_scenario

            options.pop("flights", None)
            run = run_scenario(self, **options)
        emit(run.warnings)
        return run

    def bench(self, **options):
        """``rollmpc bench``: :func:`~rollmpc_codegen.host.bench.run_bench` with its
        keywords (``precision, variants, paper, max_qps, repeat, steps, build_dir``)."""
        from .host.bench import run_bench

        return run_bench(self, **options)

    def report(self, **options) -> dict:
        """``rollmpc report``: :func:`~rollmpc_codegen.target.report.run_report` with its
        keywords; the report dict, its ``verdicts``, ``passed`` and ``checks`` (the
        warnings, also warned)."""
        from .config.diagnostics import DesignWarning
        from .target.report import run_report

        rep = run_report(self, **options)
        emit([DesignWarning(**w) for w in rep.get("checks", [])])
        return rep

    def compile(self, precision: str | None = None, build_dir: str | Path | None = None,
                compiler: str = "gcc", opt: str = "-O2") -> "CompiledController":
        """Compile the generated C on the host and load it through cffi."""
        from .host.build import build_host_controller

        model, ctx = self.build(precision)
        return CompiledController(build_host_controller(ctx, build_dir, compiler, opt), model)

    def __repr__(self) -> str:
        c = self.config
        return (f"Design({c.prefix!r}, {c.precision}, Ts={c.sample_time}, N={c.horizon}, "
                f"modes={[m.name for m in c.modes]})")


class CompiledController:
    """The host build of a design: ``u, status = ctrl.step(y, sched, r)``.

    ``r`` is the preview r_1..r_N (N * n_outputs values, output-major per step), or one
    value per output (or a scalar) held over the horizon. ``host`` is the full
    :class:`~rollmpc_codegen.host.build.HostController` (solve_qp, info, set_bounds).
    """

    def __init__(self, host, model):
        self.host = host
        self.model = model
        self.context = host.ctx

    def _vector(self, value, sizes: tuple[int, ...], name: str) -> np.ndarray:
        arr = np.atleast_1d(np.asarray(value, dtype=float)).ravel()
        if arr.size not in sizes:
            raise ValueError(f"{name} must have {' or '.join(map(str, sizes))} values, "
                             f"got {arr.size}")
        return arr

    def step(self, y, sched=None, r=0.0) -> tuple[np.ndarray, int]:
        """One sample of ``P_step``: the command of every actuator, and the status."""
        ny, horizon = self.context["n_outputs"], self.context["horizon"]
        y = self._vector(y, (ny,), "y")
        r = self._vector(r, tuple(sorted({1, ny, ny * horizon})), "r")
        if r.size < ny * horizon:  # held over the horizon
            r = np.tile(np.broadcast_to(r, (ny,)), horizon)
        n_schedule = self.context["n_schedule"]  # without a scheduler the C ignores sched
        sched = None if sched is None or not n_schedule else self._vector(
            sched, (n_schedule,), "sched")
        status, u = self.host.step(y, sched, r)
        return u, int(status)

    def reset(self) -> None:
        """``P_init``: the initial mode, zero states and commands, cold solver."""
        self.host.init()

    def info(self) -> dict:
        """``P_last_info``: status, mode, iterations, active rows, ..."""
        return self.host.info()

    def status_message(self, status: int) -> str:
        return self.host.status_message(status)
