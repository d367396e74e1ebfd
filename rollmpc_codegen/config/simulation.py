"""``simulation`` and ``units``: what ``rollmpc simulate/bench/report`` feed and label.
The generated C never sees them."""
from __future__ import annotations

from .errors import ConfigError
from .reader import Reader, check_length, read_vector
from .schema import NO_UNIT, REFERENCE_KEYS, SCHEDULE_SOURCES, SimulationConfig, UnitsConfig


def parse_simulation(sim: Reader, n_outputs: int) -> SimulationConfig:
    """``simulation``: the scheduling signal's source and the reference scenario (its
    segment against the sample time: :func:`check_segment`, once the sample time is
    known to be plausible)."""
    schedule_source = sim.string("schedule_source", SimulationConfig.schedule_source,
                                 choices=SCHEDULE_SOURCES)
    levels, segment = (_reference(sim.sub("reference", REFERENCE_KEYS), n_outputs)
                       if sim.has("reference") else (None, None))
    return SimulationConfig(schedule_source=schedule_source, reference_levels=levels,
                            reference_segment_s=segment)


def check_segment(simulation: SimulationConfig, sample_time: float) -> None:
    """A reference level must last a sample at least.  Checked after
    config/sample_time.py, so that a sample time in the wrong unit is blamed on
    ``sample_time``, not on the segment it outlasts."""
    segment = simulation.reference_segment_s
    if segment is not None and round(segment / sample_time) < 1:
        raise ConfigError("simulation.reference.segment", f"must be at least sample_time "
                          f"({sample_time})")


def _reference(r: Reader, n_outputs: int) -> tuple[tuple[tuple[float, ...], ...], float]:
    """``simulation.reference``: levels (a scalar is applied to every output) and segment."""
    raw = r.raw("levels")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(r.key("levels"), "must be a non-empty list of levels")
    check_length(raw, r.key("levels"))
    levels = tuple(tuple(read_vector(v, f"{r.key('levels')}[{i}]", n_outputs))
                   for i, v in enumerate(raw))
    return levels, r.number("segment", positive=True)


def parse_units(u: Reader, outputs: tuple[str, ...],
                actuators: tuple[str, ...]) -> UnitsConfig:
    """``units: {outputs, actuators, schedule}``: a unit string per signal (one string for
    all outputs / actuators is allowed); every entry optional."""
    def per_signal(name: str, count: int) -> tuple[str, ...]:
        value = u.raw(name, NO_UNIT)
        value = [value] * count if isinstance(value, str) else value
        if not isinstance(value, list) or len(value) != count or not all(
                isinstance(v, str) for v in value):
            raise ConfigError(u.key(name), f"must be a unit string or a list of {count} "
                              f"(one per {name[:-1]})")
        return tuple(value)

    return UnitsConfig(outputs=per_signal("outputs", len(outputs)),
                       actuators=per_signal("actuators", len(actuators)),
                       schedule=u.string("schedule", UnitsConfig.schedule))

