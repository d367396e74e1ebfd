"""``rollmpc identify``: trim and linearise a JSBSim aircraft at one or more airspeeds and
write the roll controller's config (:func:`rollmpc_codegen.flight.identify_config.
identify_config`; one mode per airspeed, scheduled on the measured airspeed, with the
aircraft and its envelope in its ``aircraft`` section)."""
from __future__ import annotations

from pathlib import Path

from ..config.errors import ConfigError
from ..flight.aircraft import (DEFAULT_AIRCRAFT, DEFAULT_ALTITUDE_FT, FLAPS_PROPERTY,
                               GEAR_PROPERTY, MIXTURE_PROPERTY)
from ..parts import DEFAULT_PART, PARTS
from .options import add_command, add_quiet


def add_parser(sub) -> None:
    i = add_command(sub, "identify", "write a roll controller config from a JSBSim aircraft "
                    "(needs the flight extra)", "Trims the aircraft at each airspeed, "
                    "linearises it and writes a config with one mode per airspeed, switched "
                    "on the measured airspeed, and the aircraft's envelope (docs/flight.md).")
    i.add_argument("--aircraft", default=DEFAULT_AIRCRAFT,
                   help=f"a JSBSim aircraft of the jsbsim wheel (default {DEFAULT_AIRCRAFT})")
    i.add_argument("--airspeed", type=float, action="append", required=True,
                   help="trim airspeed in kts, once per mode; the first is the scheduler's "
                   "initial mode")
    i.add_argument("--altitude", type=float, default=DEFAULT_ALTITUDE_FT,
                   help=f"trim altitude in ft (default {DEFAULT_ALTITUDE_FT:g})")
    i.add_argument("--latency", type=int, default=0,
                   help="samples of sensor delay to model (fly it with --delay of as many)")
    i.add_argument("--gear", choices=["up", "down"], default=None,
                   help=f"landing gear for the trims and flights ({GEAR_PROPERTY}; default: "
                   "the aircraft's)")
    i.add_argument("--flaps", type=float, default=None,
                   help=f"flap command 0..1 ({FLAPS_PROPERTY})")
    i.add_argument("--mixture", type=float, default=None,
                   help=f"every engine's mixture 0..1 ({MIXTURE_PROPERTY})")
    i.add_argument("--set", action="append", default=[], metavar="PROPERTY=VALUE",
                   help="any JSBSim property, set after the engines start and before each "
                   "trim, held in flight (repeatable; [*] in a name: every engine)")
    i.add_argument("--part", default=DEFAULT_PART,
                   help=f"the part the image is sized for, written as target.part (default "
                   f"{DEFAULT_PART}; one of {', '.join(PARTS)})")
    i.add_argument("-o", "--output", required=True, help="the config file to write")
    i.add_argument("--force", action="store_true", help="overwrite an existing file")
    add_quiet(i)
    i.set_defaults(func=run)


def settings_of(args) -> list[tuple[str, float]]:
    """The JSBSim settings of --gear, --flaps, --mixture and --set, in that order."""
    out = []
    if args.gear is not None:
        out.append((GEAR_PROPERTY, 1.0 if args.gear == "down" else 0.0))
    for key, prop in (("flaps", FLAPS_PROPERTY), ("mixture", MIXTURE_PROPERTY)):
        value = getattr(args, key)
        if value is not None:
            if not 0 <= value <= 1:
                raise ConfigError(f"--{key}", f"must be in [0, 1], got {value}")
            out.append((prop, value))
    for item in args.set:
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not sep or not name.strip() or not abs(number) < float("inf"):
            raise ConfigError("--set", f"{item!r}: write PROPERTY=NUMBER")
        out.append((name.strip(), number))
    return out


def run(args) -> int:
    import sys

    from ..flight.aircraft import require_jsbsim
    from ..flight.identify import mode_name
    from ..flight.identify_config import identify_config

    out = Path(args.output)
    if out.is_dir() or (out.exists() and not args.force):
        raise ConfigError("--output", f"{out} exists (--force overwrites a file)")
    if any(not 0 < v < float("inf") for v in args.airspeed) or not 0 <= args.altitude < 1e6:
        raise ConfigError("--airspeed/--altitude", "must be positive and finite")
    if args.latency < 0:
        raise ConfigError("--latency", f"must be >= 0, got {args.latency}")
    if args.part not in PARTS:
        raise ConfigError("--part", f"unknown part {args.part!r}; one of {', '.join(PARTS)}")
    settings = settings_of(args)
    require_jsbsim()

    def say(text: str) -> None:
        if not args.quiet:
            print(text, file=sys.stderr)

    result = identify_config(args.aircraft, args.airspeed, args.altitude, args.latency,
                             settings, args.part, progress=say)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(result.text)
    for m, c, d in zip(result.models, result.checks, result.delay_margins):
        print(f"  {mode_name(m)}: trim {m.trim.airspeed_kts:.1f} kts, aileron "
              f"{m.trim.aileron_deg:.3f} deg; doublet: linear model vs JSBSim roll error RMS "
              f"{c['rms_error_deg']:.3f} deg, max {c['max_error_deg']:.3f} deg (peak roll "
              f"{c['peak_roll_deg']:.2f} deg); delay margin "
              f"{'> 30' if d is None else d} samples")
    for w in result.warnings:
        print(f"rollmpc: warning: {w.message}", file=sys.stderr)
    n = len(result.models)
    print(f"rollmpc: wrote {out} ({n} mode{'s' if n > 1 else ''})")
    return 0
