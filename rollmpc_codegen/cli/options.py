"""The option groups several ``rollmpc`` subcommands share, and their checks.

Only argparse and the standard library are imported here: building the parser must stay
fast, the library is imported by the subcommand that runs.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..config import PRECISIONS, ConfigError


def add_command(sub, name: str, summary: str, description: str, epilog: str = ""):
    """A subcommand's parser: ``summary`` is its line in ``rollmpc --help``,
    ``description`` the paragraph of ``rollmpc NAME --help`` (every option has a help)."""
    return sub.add_parser(name, help=summary, description=f"{summary[0].upper()}{summary[1:]}. "
                          f"{description}", epilog=epilog or EXIT_CODES)


EXIT_CODES = ("exit codes: 0 done; 1 a tool failed (the C compiler, ...); 2 bad input (the "
              "config or an argument: one line naming the key)")


def add_config(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", help="the design: a YAML configuration (README, "
                   "\"Configuration schema\")")


def add_precision(p: argparse.ArgumentParser) -> None:
    p.add_argument("--precision", choices=PRECISIONS, default=None,
                   help="override the config's precision")


def add_part(p: argparse.ArgumentParser) -> None:
    p.add_argument("--part", default=None,
                   help="judge the design on this part instead of the config's target: "
                   "section (its core, clock, flash and RAM; docs/target.md \"Parts\"), "
                   "e.g. stm32f427, stm32f765, stm32h743, stm32l562")


def add_build_dir(p: argparse.ArgumentParser) -> None:
    p.add_argument("--build-dir", default=None,
                   help="scratch directory for the host C builds (default: "
                   "$XDG_CACHE_HOME/rollmpc/build or ~/.cache/rollmpc/build, cached by "
                   "content hash; must be writable by you only)")


def add_force(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true",
                   help="also write into a directory rollmpc did not write: files named like "
                   "a generated file are overwritten, no other file is touched")


def add_quiet(p: argparse.ArgumentParser, help: str = "no progress on stderr") -> None:
    p.add_argument("-q", "--quiet", action="store_true", help=help)


def progress_of(args):
    """The progress factory the library functions take: a bar on stderr unless --quiet."""
    from ..sim.simulate import progress_printer

    return None if args.quiet else progress_printer


def add_outputs(p: argparse.ArgumentParser, **helps: str) -> None:
    """The files a run writes besides its stdout: ``--<name>`` for each of ``helps``
    (json, csv, plot), with the subcommand's own help text."""
    for name, text in helps.items():
        p.add_argument(f"--{name}", help=text)


def check_outputs(args, names: tuple[str, ...]) -> None:
    """Fail before any work when an output path is a directory."""
    for opt in names:
        target = getattr(args, opt)
        if target is not None and Path(target).is_dir():
            raise ConfigError(f"--{opt}", f"{target} is a directory")


def add_perturbations(p: argparse.ArgumentParser) -> None:
    """What the simulated plant is perturbed by (sim/simulate.py, sim/mismatch.py)."""
    p.add_argument("--noise", type=float, default=0.0, help="measurement noise std (output units)")
    p.add_argument("--disturbance", type=float, default=0.0,
                   help="constant input disturbance on every actuator (actuator units)")
    p.add_argument("--mismatch", type=float, default=0.0,
                   help="plant mismatch F in [0, 1): each mode's plant gain and poles scaled "
                   "by 1 + d, d uniform in [-F, F] from the seed")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise and the mismatch")


def check_perturbations(args) -> None:
    if not args.noise >= 0:
        raise ConfigError("--noise", f"must be >= 0, got {args.noise}")
    if not abs(args.disturbance) < float("inf"):
        raise ConfigError("--disturbance", f"must be finite, got {args.disturbance}")
    if not 0 <= args.mismatch < 1:
        raise ConfigError("--mismatch", f"must be in [0, 1), got {args.mismatch}")


FLIGHTS_HELP = ("fly K random flights instead of the scenario, flight i seeded with --seed "
                "+ i: an even seed draws its levels within the range the scenario spans "
                "inside the output bounds, an odd seed presses the envelope (half its levels "
                "beyond that range, up to the hard output bounds and past the soft ones; "
                "docs/solver.md, \"Random flights\"); the figures are given by kind too")


def add_flights(p: argparse.ArgumentParser, what: str) -> None:
    """``--flights K`` and ``--flight-kinds`` (sim/flight_plan.py); ``what``: the
    subcommand's own figures per flight."""
    p.add_argument("--flights", type=int, default=0, help=f"{FLIGHTS_HELP}; {what}")
    p.add_argument("--flight-kinds", choices=("both", "inside", "envelope"), default="both",
                   help="with --flights: both kinds by the seed's parity (default), or every "
                   "flight inside, or every flight pressing the envelope")


def check_flights(args) -> None:
    if args.flights < 0:
        raise ConfigError("--flights", f"must be >= 0, got {args.flights}")


def check_steps(args) -> None:
    if args.steps is not None and args.steps < 1:
        raise ConfigError("--steps", f"must be >= 1, got {args.steps}")


def require_plot(args) -> None:
    """``--plot`` needs matplotlib: fail before any work (one line, exit 1)."""
    if args.plot:
        from ..extras import require_module

        require_module("matplotlib", "plot", "--plot")


def write_json(path: str | Path, data: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path
