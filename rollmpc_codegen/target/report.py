"""``rollmpc report``: flash, RAM, stack and cycles of the generated controller on the
emulated core of its part (parts.py; ``part`` overrides the config's), bit-exact against
the host build.

:func:`run_report` takes keywords, returns the report as a dict and prints nothing (its
progress goes to an optional callback factory, see ``sim.simulate.start_phase``):

1. a host run records every step (:mod:`rollmpc_codegen.target.replay`);
2. the hardest steps and a sampled sweep are chosen for counting;
3. the target image replays the run on Unicorn, compared bit for bit with the host, and
   the chosen steps' instructions and cycles are counted
   (:mod:`rollmpc_codegen.target.measure` assembles the figures).

The run is the config's scenario, or with ``flights`` that many random flights; either
perturbed by measurement noise, an input disturbance and a plant mismatch
(:mod:`rollmpc_codegen.target.flights`).

With ``horizons`` the measurement is repeated for the config with the horizon overridden,
and the growth of each figure in N is fitted (:mod:`rollmpc_codegen.target.horizons`).
"""
from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from .. import config as config_mod
from ..extras import installed
from ..host.build_cache import private_root
from ..pipeline import load_config, load_model
from . import flight_replay
from ..sim.flight_plan import FlightPlan
from .horizons import horizon_table
from .build import build_target, target_layout
from .measure import measure
from .verdicts import conclude

TARGET_MODULES = (("unicorn", "unicorn"), ("capstone", "capstone"), ("elftools", "pyelftools"))


def run_report(config, *, precision: str | None = None, part: str | None = None,
               horizons: Iterable[int] | None = None, steps: int | None = None,
               flights: int = 0, seed: int = 0, noise_std: float = 0.0,
               disturbance: float = 0.0, mismatch: float = 0.0, kinds: str = "both",
               sample_every: int = 20, hardest: int = 10, host_repeats: int = 5,
               extra_cflags: tuple[str, ...] = (), build_dir: str | Path | None = None,
               flight: str | Path | None = None, peer: str | None = None,
               progress=None) -> dict:
    """The report of ``config`` (a file, a ControllerConfig or a Design:
    pipeline.load_config): the keys of :func:`rollmpc_codegen.target.measure.measure`
    with its ``verdicts``, ``passed`` and ``checks`` (verdicts.py), or with ``horizons``
    ``{"horizons": horizon_table(...)}`` (a file or a Design).

    ``part`` replaces the config's target: section by that part's (parts.py; config.load).
    ``steps`` samples of the scenario, or of each of ``flights`` random flights of the
    ``kinds`` of flight_plan.py, are replayed (default: the scenario's length); ``seed``,
    ``noise_std``, ``disturbance`` and ``mismatch`` perturb them
    (:class:`~rollmpc_codegen.sim.flight_plan.FlightPlan`).
    Cycles are counted on every ``sample_every``-th step and on the ``hardest`` steps,
    ranked by the smallest host solve time of ``host_repeats`` runs; ``extra_cflags`` are
    appended to the target's flags. ``flight``: replay the first ``steps`` samples of that
    CSV of ``rollmpc fly`` instead (:mod:`.flight_replay`); the report then has ``flight``
    (its path, samples and ``flight_replay.commands_match``). ``peer="daqp"``: DAQP's
    own C in single precision replays the scenario's QPs on the same emulated target
    (:mod:`.peer_daqp`); the report then has ``peer`` beside its own ``by_mode``.
    """
    for module, package in TARGET_MODULES:
        if not installed(module):
            raise RuntimeError(f"{package} is missing; install with: pip install "
                               "'rollmpc-codegen[target]'")
    root = private_root(build_dir or None)  # it receives configs too, not only builds
    plan = FlightPlan(flights=flights, seed=seed, noise_std=noise_std,
                      disturbance=disturbance, mismatch=mismatch, kinds=kinds)
    options = {"steps": steps, "sample_every": sample_every, "hardest": hardest,
               "extra_cflags": tuple(extra_cflags), "host_repeats": host_repeats,
               "plan": plan}
    if flight is not None and (horizons or flights or noise_std or disturbance or mismatch):
        raise config_mod.ConfigError("--flight", "replays one recorded flight; not with "
                                     "--horizons, --flights or perturbations")
    if peer is not None and (peer not in PEERS or horizons or flights or flight is not None):
        raise config_mod.ConfigError("--peer", f"one of {', '.join(PEERS)}, on the scenario "
                                     "only (not with --horizons, --flights or --flight)")
    if horizons:
        path = yaml_file(config, root)
        load_config(path, precision, part)  # validate before the long run
        return {"horizons": horizon_table(path, sorted(set(horizons)), precision, root,
                                          progress, part=part, **options)}
    model, ctx = load_model(config, precision, part)
    if flight is None:
        report = measure(model, ctx, root, progress=progress, **options)
        if peer is not None:
            report["peer"] = peer_cycles(model, ctx, root, steps, progress)
        return conclude(report, model.config, precision)
    inputs = flight_replay.read_flight_inputs(flight, ctx, steps)
    layout = target_layout(build_target(ctx, root, extra_cflags=tuple(extra_cflags)), ctx)
    record = flight_replay.record_flight(ctx, inputs, root, progress, host_repeats, layout)
    report = measure(model, ctx, root, progress=progress, record=record, **options)
    report["flight"] = {"path": str(flight), "samples": len(inputs.y),
                        **flight_replay.commands_match(inputs, record)}
    return conclude(report, model.config, precision)


def yaml_file(config, root: Path) -> Path:
    """``--horizons`` edits the YAML: a file as it is, a Design as its to_yaml() in
    ``root``; a bare ControllerConfig has no YAML form."""
    if isinstance(config, (str, Path)):
        return Path(config)
    if not callable(getattr(config, "to_yaml", None)):
        raise config_mod.ConfigError("horizons", "needs a config file or a Design")
    path = Path(root) / "design.yaml"
    config.to_yaml(path)
    return path


PEERS = ("daqp",)


def peer_cycles(model, ctx: dict, root: Path, steps: int | None, progress=None) -> dict:
    """DAQP on the emulated target over the QPs the scenario's closed loop solves."""
    from ..host.bench_record import record_qp_sequence
    from ..host.build import build_host_controller
    from ..sim.simulate import start_phase
    from .peer_daqp import daqp_cycles

    from ..sim.scenario import scenario_reference

    total = steps or len(scenario_reference(model.config))
    sequence = record_qp_sequence(model, build_host_controller(ctx, root), steps,
                                  start_phase(progress, total, "report: QPs for the peer"))
    replay = start_phase(progress, len(sequence.mode), "report: DAQP on the target")
    return {"name": "daqp", **daqp_cycles(model, sequence, replay, build_root=root)}
