"""``rollmpc identify``: trim and linearise a JSBSim aircraft at one or more airspeeds and
write the roll controller's config (:func:`rollmpc_codegen.flight.identify.identify_config`;
one mode per airspeed, scheduled on the measured airspeed)."""
from __future__ import annotations

from pathlib import Path

from ..config.errors import ConfigError
from ..flight.aircraft import DEFAULT_AIRCRAFT, DEFAULT_ALTITUDE_FT
from .options import add_command, add_quiet


def add_parser(sub) -> None:
    i = add_command(sub, "identify", "write a roll controller config from a JSBSim aircraft "
                    "(needs the flight extra)", "Trims the aircraft at each airspeed, "
                    "linearises it and writes a config with one mode per airspeed, switched "
                    "on the measured airspeed (docs/flight.md).")
    i.add_argument("--aircraft", default=DEFAULT_AIRCRAFT,
                   help=f"a JSBSim aircraft of the jsbsim wheel (default {DEFAULT_AIRCRAFT})")
    i.add_argument("--airspeed", type=float, action="append", required=True,
                   help="trim airspeed in kts, once per mode; the first is the scheduler's "
                   "initial mode")
    i.add_argument("--altitude", type=float, default=DEFAULT_ALTITUDE_FT,
                   help=f"trim altitude in ft (default {DEFAULT_ALTITUDE_FT:g})")
    i.add_argument("--latency", type=int, default=0,
                   help="samples of sensor delay to model (fly it with --delay of as many)")
    i.add_argument("-o", "--output", required=True, help="the config file to write")
    i.add_argument("--force", action="store_true", help="overwrite an existing file")
    add_quiet(i)
    i.set_defaults(func=run)


def run(args) -> int:
    import sys

    from ..flight.aircraft import require_jsbsim
    from ..flight.identify import identify_config, mode_name

    out = Path(args.output)
    if out.is_dir() or (out.exists() and not args.force):
        raise ConfigError("--output", f"{out} exists (--force overwrites a file)")
    if any(not 0 < v < float("inf") for v in args.airspeed) or not 0 <= args.altitude < 1e6:
        raise ConfigError("--airspeed/--altitude", "must be positive and finite")
    if args.latency < 0:
        raise ConfigError("--latency", f"must be >= 0, got {args.latency}")
    require_jsbsim()

    def say(text: str) -> None:
        if not args.quiet:
            print(text, file=sys.stderr)

    text, models, checks = identify_config(args.aircraft, args.airspeed, args.altitude,
                                           args.latency, progress=say)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    for m, c in zip(models, checks):
        print(f"  {mode_name(m)}: trim {m.trim.airspeed_kts:.1f} kts, aileron "
              f"{m.trim.aileron_deg:.3f} deg; doublet: linear model vs JSBSim roll error RMS "
              f"{c['rms_error_deg']:.3f} deg, max {c['max_error_deg']:.3f} deg (peak roll "
              f"{c['peak_roll_deg']:.2f} deg)")
    print(f"rollmpc: wrote {out} ({len(models)} mode{'s' if len(models) > 1 else ''})")
    return 0
