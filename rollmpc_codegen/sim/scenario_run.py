"""The paper's closed loop (section 4.1, Fig. 2) on the generated C, as one library call
(``rollmpc simulate`` prints and writes what :func:`run_scenario` returns).

The controller is the generated C, compiled on the host and called through cffi; the
plant is :class:`rollmpc_codegen.sim.scenario.SimulatedPlant`; the loop is
:func:`rollmpc_codegen.sim.simulate.run_closed_loop`; the metrics are those of
:func:`rollmpc_codegen.sim.metrics.summarize`.  The optional baseline is the saturated LQR
of :mod:`rollmpc_codegen.sim.lqr_baseline`, run on the same scenario.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..config import ControllerConfig
from ..config.diagnostics import DesignWarning, messages
from ..host.build import build_host_controller
from ..pipeline import config_label, load_model
from ..qp.sanity import design_warnings
from .metrics import summarize, work_stats
from .infeasible_rows import infeasible_keys
from .run_checks import scenario_checks
from .scenario import plant_mismatch, scenario_reference
from .simulate import ClosedLoopLog, run_closed_loop, start_phase

BASELINES = ("lqr",)


@dataclass
class ScenarioRun:
    """One closed loop: ``summary`` is the JSON document (the run's settings and every
    metric, with ``baseline`` holding the baseline's), the logs are per sample,
    ``warnings`` what the CLI prints under its summary (also ``summary["checks"]``)."""

    config: ControllerConfig
    ctx: dict
    log: ClosedLoopLog
    summary: dict
    baseline_log: ClosedLoopLog | None = None
    warnings: list[DesignWarning] = field(default_factory=list)


def run_scenario(config, *, precision: str | None = None,
                 steps: int | None = None, noise_std: float = 0.0, disturbance: float = 0.0,
                 mismatch: float = 0.0, seed: int = 0, baseline: str | None = None,
                 build_dir: str | Path | None = None, progress=None) -> ScenarioRun:
    """Simulate ``steps`` samples (default: the whole scenario) of the generated C for
    ``config`` (a file, a ControllerConfig or a Design: pipeline.load_config), with
    seeded measurement noise, a constant input disturbance and a plant
    mismatch of up to ``mismatch`` (a fraction, sim/mismatch.py) (``run_closed_loop``);
    ``baseline="lqr"`` also runs the saturated LQR."""
    if baseline is not None and baseline not in BASELINES:
        raise ValueError(f"unknown baseline {baseline!r}; choose from {', '.join(BASELINES)}")
    model, ctx = load_model(config, precision)
    cfg = model.config
    steps = steps if steps is not None else len(scenario_reference(cfg))
    true_plant = plant_mismatch(cfg, mismatch, seed)

    def run(controller, label: str) -> ClosedLoopLog:
        return run_closed_loop(cfg, controller, steps=steps, noise_std=noise_std,
                               disturbance=disturbance, seed=seed, mismatch=true_plant,
                               progress=start_phase(progress, steps, label),
                               info=controller.info)

    controller = build_host_controller(ctx, Path(build_dir) if build_dir else None)
    log = run(controller, f"simulate ({ctx['precision']})")
    design = design_warnings(model)
    summary = {"config": config_label(config), "precision": ctx["precision"],
               "solver": dict(ctx["solver"]), "modes": [m.name for m in cfg.modes],
               "sample_time": cfg.sample_time, "horizon": cfg.horizon,
               "noise_std": noise_std, "disturbance": disturbance, "mismatch": mismatch,
               "plant_mismatch": None if true_plant is None else true_plant.as_dict(),
               "seed": seed,
               # generate's warnings (a loop that diverges where no bound is active, ...)
               "design_warnings": messages(design),
               **summarize(cfg, log),
               "work": work_stats(log.work, ctx["solver"]["work_budget"])}
    base_log = None
    if baseline == "lqr":
        from .lqr_baseline import LqrController

        base_log = run(LqrController(model, ctx), "LQR baseline")
        summary["baseline"] = {"kind": "lqr_saturated", **summarize(cfg, base_log)}
    found = scenario_checks(cfg, summary, log.status, log.mode, design,
                            infeasible_keys(model, ctx, log, scenario_reference(cfg)))
    summary["checks"] = [w.as_dict() for w in found]
    return ScenarioRun(config=cfg, ctx=ctx, log=log, summary=summary, baseline_log=base_log,
                       warnings=found)
