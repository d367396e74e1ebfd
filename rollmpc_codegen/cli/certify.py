"""``rollmpc certify``: the work certificate of a design
(:func:`rollmpc_codegen.verify.certify.certify`) as a summary on stdout, ``--json`` the
whole of it; exit 0 when the design fits its work budget on every sampled QP, 3 when it
does not (as ``rollmpc report``'s failed verdict), for CI."""
from __future__ import annotations

from ..config import ConfigError
from .options import (add_build_dir, add_command, add_config, add_outputs, add_perturbations,
                      add_precision, add_quiet, check_perturbations, check_steps, progress_of,
                      write_json)


def add_parser(sub) -> None:
    c = add_command(sub, "certify", "a work certificate: the design's QPs sampled in closed "
                    "loop against its work budget",
                    "Flies closed loops of the design as generated over random references "
                    "(inside the scenario's range and pressing the envelope, as `simulate "
                    "--flights`), solves every QP they meet in the NumPy reference, and "
                    "reports the work per QP (median, p99, p99.9, max) against the budget, "
                    "the QPs that needed the most with their state, a bound on P(TIME_LIMIT) "
                    "at a stated confidence and, when the design does not fit, what would "
                    "(docs/solver.md, \"Work certificate\").",
                    epilog="exit codes: 0 every sampled QP within the budget; 3 a sampled QP "
                    "stopped at TIME_LIMIT; 1 a tool failed; 2 bad input")
    add_config(c)
    add_precision(c)
    add_outputs(c, json="write the certificate as JSON")
    c.add_argument("--loops", type=int, default=None,
                   help="closed loops (random flights, loop i seeded --seed + i; default 20)")
    c.add_argument("--steps", type=int, default=None,
                   help="samples per loop (default 600, or 3 of the scenario's segments when "
                   "longer; at most the scenario's length)")
    c.add_argument("--flight-kinds", choices=("both", "inside", "envelope"), default="both",
                   help="the loops' references: both kinds by the seed's parity (default), "
                   "or every loop inside the scenario's range, or every loop pressing the "
                   "envelope")
    add_perturbations(c)
    c.add_argument("--confidence", type=float, default=None,
                   help="confidence 1 - beta of the bounds on P(TIME_LIMIT) (default 0.95)")
    c.add_argument("--engine", choices=("reference", "host"), default="reference",
                   help="who solves the QPs: the NumPy reference (default, no C compiler) "
                   "or the host C build (about 30 times faster, the same work bit for bit)")
    add_quiet(c)
    add_build_dir(c)
    c.set_defaults(func=run)


def run(args) -> int:
    from ..target.verdicts import EXIT_VERDICT_FAILED
    from ..verify.certify import DEFAULT_CONFIDENCE, DEFAULT_LOOPS, certify

    check_steps(args)
    check_perturbations(args)
    loops = DEFAULT_LOOPS if args.loops is None else args.loops
    confidence = DEFAULT_CONFIDENCE if args.confidence is None else args.confidence
    if loops < 1:
        raise ConfigError("--loops", f"must be >= 1, got {loops}")
    if not 0 < confidence < 1:
        raise ConfigError("--confidence", f"must be in (0, 1), got {confidence}")
    cert = certify(args.config, loops=loops, steps=args.steps, seed=args.seed,
                   kinds=args.flight_kinds, noise_std=args.noise, disturbance=args.disturbance,
                   mismatch=args.mismatch, confidence=confidence, engine=args.engine,
                   precision=args.precision, build_dir=args.build_dir,
                   progress=progress_of(args))
    print("\n".join(cert.summary_lines()))
    if args.json:
        write_json(args.json, cert.as_dict())
        print(f"rollmpc: wrote {args.json}")
    return 0 if cert.fits else EXIT_VERDICT_FAILED
