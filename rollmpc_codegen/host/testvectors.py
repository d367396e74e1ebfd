"""Emit a self-contained host C test: generated sources + reference vectors + main().

The vectors come from the NumPy reference (never from the C): a recorded closed loop of
the scenario (inputs y, sched and the reference record; expected u and status per step)
and QP solves from states along it, saturated ones included.  ``make ctest`` builds and
runs the program with the C compiler alone.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..reference.controller import ControllerRef
from ..pipeline import load_model
from ..codegen.output import check_output_dir, write_output
from ..codegen.render import render_sources, render_template
from ..sim.scenario import scenario_reference
from ..sim.simulate import run_closed_loop
from ..reference.solver import SolverRef


def saturated_samples(cfg, log, modes) -> np.ndarray:
    """Samples at which the active mode (``modes[k]``) commands an actuator at one of its
    own bounds (to 1e-6 relative: the command is the bound rounded to the precision)."""
    hits = []
    for k, j in enumerate(modes):
        m = cfg.modes[j]
        u = log.u[k, [cfg.actuators.index(a) for a in m.actuators]]
        hits.append(np.any(np.isclose(u, m.u_min, rtol=1e-6, atol=0)
                           | np.isclose(u, m.u_max, rtol=1e-6, atol=0)))
    return np.flatnonzero(hits)


def qp_cases_from_log(model, ctx, log, xs, count: int = 12) -> list[dict]:
    """QP solves at states of the closed loop, spread over the constrained samples."""
    N, ny = ctx["horizon"], ctx["n_outputs"]
    ref = log.r[:, 0] if ny == 1 else log.r
    constrained = saturated_samples(model.config, log, [mode for mode, _ in xs])
    picks = np.unique(np.concatenate((constrained[:: max(1, len(constrained) // count)][:count],
                                      [0, len(log.t) // 2])))
    cases = []
    for k in picks:
        mode, x = xs[k]
        idx = np.minimum(np.arange(k + 1, k + N + 1), len(ref) - 1)
        r = np.repeat(ref[idx], ny) if ny == 1 else ref[idx].ravel()
        solver = SolverRef(model.modes[mode].data, ctx["solver"],
                           build_rate_rows=ctx["has_rate_rows"])  # as the C's inputs_only()
        status, U, its, _, _ = solver.solve_mode(x, r)
        cases.append({"mode": int(mode), "x": x, "r": r.astype(x.dtype), "U": U,
                      "status": int(status), "iterations": int(its), "n": int(U.size)})
    return cases


def write_test_vectors(config: str | Path, out_dir: str | Path, precision: str | None = None,
                       steps: int | None = None, force: bool = False) -> Path:
    """Generated sources + ``<prefix>_test_vectors.c`` in ``out_dir`` (codegen/output.py):
    ``steps`` closed-loop samples (None: the whole scenario)."""
    check_output_dir(out_dir, force)
    model, ctx = load_model(config, precision)
    ref_ctrl = ControllerRef(ctx, [m.data for m in model.modes])
    xs = []

    class Recorder:
        def step(self, y, s, r):
            xs.append((ref_ctrl.mode if ctx["scheduler"] is None else
                       ref_ctrl.schedule(ref_ctrl.dt(s[0])), None))
            mode = xs[-1][0]
            x_before = ref_ctrl.xhat[mode].copy()
            xs[-1] = (mode, x_before)
            return ref_ctrl.step(y, s, r)

    log = run_closed_loop(model.config, Recorder(), steps=steps)
    dt = model.dtype
    reference = scenario_reference(model.config)  # (samples, n_outputs)
    program = render_template(
        ctx, "host/test_vectors.c.j2", steps=len(log.t), ref_len=len(reference),
        ref=reference.ravel().astype(dt),
        y=log.y.astype(dt), sched=log.sched.astype(dt),
        u=np.array(log.u_raw, dtype=dt), status=log.status,
        qp_cases=qp_cases_from_log(model, ctx, log, xs))
    # the config header, which completes the tree, stays the last file (codegen/output.py)
    return write_output({f"{ctx['prefix']}_test_vectors.c": program, **render_sources(ctx)},
                        out_dir, force)
