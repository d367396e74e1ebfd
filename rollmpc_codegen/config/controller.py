"""The top level of a configuration: its own keys, then each section in turn, then the
checks across sections, into one :class:`ControllerConfig`."""
from __future__ import annotations

import re
from typing import Any

from ..codegen.c_names import prefix_collisions
from ..features.move_blocking import blocks_of
from .checks import (check_horizon, check_literal, check_rate_bounds, check_representable,
                     check_schedule_source, check_unique_names)
from .aircraft import parse_aircraft
from .errors import ConfigError
from .mode import parse_mode
from .reader import Reader
from .scheduler import parse_scheduler
from .schema import (AIRCRAFT_KEYS, DEFAULT_PRECISION, DEFAULT_PREFIX, MAX_ROWS, MODE_KEYS,
                     PRECISIONS, PREFIX_PATTERN, RESERVED_PREFIXES, SCHEDULER_KEYS,
                     SIMULATION_KEYS, SOLVER_KEYS, TARGET_KEYS, TOP_KEYS, UNITS_KEYS,
                     ControllerConfig, UnitsConfig)
from .sample_time import check_sample_time
from .simulation import check_segment, parse_simulation, parse_units
from .solver import parse_solver
from .target import parse_target


def parse(data: Any) -> ControllerConfig:
    """Validate a parsed YAML document into a :class:`ControllerConfig`."""
    r = Reader(data, "", TOP_KEYS)
    prefix = r.string("prefix", DEFAULT_PREFIX)
    if not re.fullmatch(PREFIX_PATTERN, prefix):
        raise ConfigError("prefix", "must be a lower-case C identifier of at most 31 "
                          f"characters, got {prefix!r}")
    if prefix in RESERVED_PREFIXES:
        raise ConfigError("prefix", f"{prefix!r} would write {prefix}.h, which shadows the "
                          f"system header <{prefix}.h>; choose another prefix")
    clash = prefix_collisions(prefix)
    if clash:
        more = f" (and {len(clash) - 1} more)" if len(clash) > 1 else ""
        raise ConfigError("prefix", f"{prefix!r} would define {clash[0]}{more}, a name of "
                          "the C, POSIX or newlib library: a build that sees its header "
                          "fails or links the wrong function; choose another prefix")
    precision = r.string("precision", DEFAULT_PRECISION, choices=PRECISIONS)
    sample_time = r.number("sample_time", positive=True)
    check_literal(precision, "sample_time", sample_time)  # the scenario divides by it
    horizon = r.integer("horizon", minimum=1)
    if horizon > MAX_ROWS:  # before anything is sized by it (check_horizon: the exact rows)
        raise ConfigError("horizon", f"too long: {horizon} stages need more than the "
                          f"{MAX_ROWS} QP rows and row quantities the C can index")
    outputs = r.names("outputs")
    actuators = r.names("actuators")
    raw_modes = r.raw("modes")
    if not isinstance(raw_modes, list) or not raw_modes:
        raise ConfigError("modes", "must be a non-empty list of modes")
    # before the modes: an output without bounds takes its default innovation limit from
    # the scenario's reference levels
    simulation = parse_simulation(r.sub("simulation", SIMULATION_KEYS, {}), len(outputs))
    default_blocks = blocks_of(r.raw("control_horizon", None), r.raw("move_blocking", None),
                               horizon, "")
    modes = tuple(parse_mode(Reader(m, f"modes[{i}]", MODE_KEYS), outputs, actuators, horizon,
                             default_blocks, simulation.levels(len(outputs)))
                  for i, m in enumerate(raw_modes))
    check_sample_time(sample_time, modes)  # a wrong unit, before anything is blamed for it
    check_segment(simulation, sample_time)
    check_horizon(horizon, modes)
    check_unique_names(modes)
    if len(modes) == 1:
        if r.has("scheduler"):
            raise ConfigError("scheduler", "a single-mode controller has no scheduler")
        scheduler = None
    else:
        scheduler = parse_scheduler(r.sub("scheduler", SCHEDULER_KEYS), modes)
    solver = parse_solver(r.sub("solver", SOLVER_KEYS, {}))
    runtime_bounds = r.boolean("runtime_bounds", ControllerConfig.runtime_bounds)
    check_rate_bounds(runtime_bounds, modes)
    units = (parse_units(r.sub("units", UNITS_KEYS), outputs, actuators)
             if r.has("units") else UnitsConfig())
    target = parse_target(r.sub("target", TARGET_KEYS, {}))
    aircraft = (parse_aircraft(r.sub("aircraft", AIRCRAFT_KEYS), len(modes))
                if r.has("aircraft") else None)
    check_representable(precision, modes, scheduler, solver)
    check_schedule_source(simulation, scheduler, modes)
    return ControllerConfig(prefix=prefix, precision=precision, sample_time=sample_time,
                            horizon=horizon, outputs=outputs, actuators=actuators, modes=modes,
                            scheduler=scheduler, solver=solver, simulation=simulation,
                            runtime_bounds=runtime_bounds, units=units, target=target,
                            aircraft=aircraft)
