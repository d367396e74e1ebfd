"""``scheduler``: k bands with hysteresis, or the two-mode shorthand of eq. (3)."""
from __future__ import annotations

from dataclasses import replace

from .errors import ConfigError
from .reader import IDENTIFIER, Reader, check_length
from .schema import BAND_KEYS, DEFAULT_EPSILON, SHORTHAND_KEYS, ModeConfig, SchedulerConfig


def parse_scheduler(r: Reader, modes: tuple[ModeConfig, ...]) -> SchedulerConfig:
    """``scheduler``: ``bands`` (k bands, any number of modes) or the two-mode shorthand
    ``lower, upper, inside, outside`` of eq. (3), translated into the three bands
    (outside, inside, outside)."""
    names = [m.name for m in modes]

    def mode_index(reader: Reader, key: str) -> int:
        name = reader.string(key)
        if name not in names:
            raise ConfigError(reader.key(key), f"unknown mode {name!r}; modes are "
                              f"{', '.join(names)}")
        return names.index(name)

    signal = r.string("signal")
    if not IDENTIFIER.fullmatch(signal):  # it is written into C comments of the generated code
        raise ConfigError(r.key("signal"), f"must be an identifier-like name, got {signal!r}")
    shorthand = [k for k in SHORTHAND_KEYS if k in r.data]
    if r.has("bands"):
        if shorthand:
            raise ConfigError(r.key(shorthand[0]), "give either bands or the two-mode "
                              "shorthand (lower, upper, inside, outside), not both")
        epsilon = r.number("epsilon", DEFAULT_EPSILON, nonnegative=True)
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
        epsilon = r.number("epsilon", DEFAULT_EPSILON, nonnegative=True)
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
    return replace(sc, initial=initial)


def _bands(r: Reader, epsilon: float, mode_index) -> tuple[list, list, list, list]:
    """``scheduler.bands``: each ``{mode, below, epsilon}``; the last band has no ``below``.

    Returns the thresholds, their margins, the key each margin came from, and the band modes.
    """
    raw = r.raw("bands")
    key = r.key("bands")
    if not isinstance(raw, list) or len(raw) < 2:
        raise ConfigError(key, "must be a list of at least two bands (one mode needs no "
                          "scheduler)")
    check_length(raw, key)
    thresholds: list[float] = []
    epsilons: list[float] = []
    eps_keys: list[str] = []
    band_modes: list[int] = []
    for i, item in enumerate(raw):
        b = Reader(item, f"{key}[{i}]", BAND_KEYS)
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
    if len(set(band_modes)) == 1:
        raise ConfigError(key, "every band has the same mode: one mode needs no scheduler")
    for i in range(1, len(band_modes)):
        if band_modes[i] == band_modes[i - 1]:
            raise ConfigError(f"{key}[{i}].mode", f"same mode as {key}[{i - 1}]: merge the "
                              "two bands")
    return thresholds, epsilons, eps_keys, band_modes

