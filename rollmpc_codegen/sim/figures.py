"""The paper's figures as PNGs (matplotlib, Agg backend).

* Fig. 2 (:func:`plot_closed_loop`, ``rollmpc simulate --plot``): panel (a) the output y
  and the reference r with the output bounds (dash-dot, in the output's colour), with
  the actuator commands u in a subplot beneath; panel (b), with
  two modes or more only, the scheduling signal rho (the UAV's roll rate) with the eq. (3)
  thresholds, and the active mode on a second axis.  An optional baseline (the saturated
  LQR) is drawn dashed.  The labels use the config's output, actuator and signal names,
  with units only where the config's ``units`` gives them (per output when they differ).
* Fig. 3 (:func:`plot_solve_times`, ``rollmpc bench --plot``): every QP's solve time per
  solver against the sample index, log scale.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..config import ControllerConfig
from .simulate import ClosedLoopLog

def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(plt, fig, path: str | Path) -> Path:
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


MPC_STYLE = {"linestyle": "-", "linewidth": 1.2}
BASELINE_STYLE = {"linestyle": "--", "linewidth": 1.0, "alpha": 0.85}


def plot_closed_loop(path: str | Path, cfg: ControllerConfig, log: ClosedLoopLog,
                     baseline: ClosedLoopLog | None = None, title: str = "",
                     baseline_label: str = "LQR + saturation") -> Path:
    """Write Fig. 2 to ``path``; returns the path."""
    plt = _pyplot()
    fig = closed_loop_figure(plt, cfg, log, baseline, title, baseline_label)
    return _save(plt, fig, path)


def closed_loop_figure(plt, cfg: ControllerConfig, log: ClosedLoopLog,
                       baseline: ClosedLoopLog | None = None, title: str = "",
                       baseline_label: str = "LQR + saturation"):
    """Fig. 2 as a matplotlib figure: stacked axes sharing time, the outputs, the inputs
    and, with two modes or more, the scheduling panel (one mode has nothing to schedule)."""
    runs = [("MPC", log, MPC_STYLE)]
    if baseline is not None:
        runs.append((baseline_label, baseline, BASELINE_STYLE))
    scheduled = cfg.scheduler is not None
    ratios = [2.2, 1.3, 1.8] if scheduled else [2.2, 1.3]
    fig, axes = plt.subplots(len(ratios), 1, figsize=(10, 8.5 if scheduled else 6.5),
                             sharex=True, gridspec_kw={"height_ratios": ratios})
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    _draw_outputs(axes[0], cfg, log, runs, colors)
    _draw_inputs(axes[1], cfg, runs, colors)
    if scheduled:
        _draw_schedule(axes[2], cfg, runs, colors)
    axes[-1].set_xlabel("time t [s]")
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def _draw_outputs(ax_y, cfg: ControllerConfig, log: ClosedLoopLog, runs, colors) -> None:
    for o, name in enumerate(cfg.outputs):
        ax_y.plot(log.t, log.r[:, o], color="0.35", linestyle=":", linewidth=1.4,
                  label=f"r ({name})")
        for label, run, style in runs:
            ax_y.plot(run.t, run.y[:, o], color=colors[o % len(colors)], **style,
                      label=f"y ({name}), {label}")
        for v in _output_bounds(cfg, o):  # every mode's finite bounds of this output
            ax_y.axhline(v, color=colors[o % len(colors)], linewidth=0.8, linestyle="-.",
                         alpha=0.7)
    outputs = ", ".join(cfg.outputs)  # units label only: none unless `units` gives them
    ax_y.set_ylabel(f"output y, reference r{_output_units(cfg)}")
    ax_y.set_title(f"(a) tracking output y(k) = {outputs} and reference r(k) (dash-dot: "
                   "output bounds)", loc="left", fontsize=10)
    ax_y.legend(loc="upper left", fontsize=8, ncol=2)
    ax_y.grid(alpha=0.3)


def _output_bounds(cfg: ControllerConfig, o: int) -> list[float]:
    """The distinct finite bounds (hard or soft) of output ``o`` over the modes."""
    return sorted({float(v) for m in cfg.modes for v in (m.y_min[o], m.y_max[o])
                   if np.isfinite(v)})


def _output_units(cfg: ControllerConfig) -> str:
    """`` [u]`` for a unit every output shares, ``(roll deg, climb m/s)`` for mixed ones,
    "" without units."""
    shared = cfg.units.label("outputs")
    if shared or not any(cfg.units.outputs):
        return shared
    return " (" + ", ".join(f"{n} {u}" if u else n
                            for n, u in zip(cfg.outputs, cfg.units.outputs)) + ")"


def _draw_inputs(ax_u, cfg: ControllerConfig, runs, colors) -> None:
    for a, name in enumerate(cfg.actuators):
        color = colors[(a + 2) % len(colors)]
        for label, run, style in runs:
            ax_u.plot(run.t, run.u[:, a], color=color, **style, label=f"u {name}, {label}")
    limits = sorted({float(v) for m in cfg.modes for v in (*m.u_min, *m.u_max)})
    for v in limits:
        ax_u.axhline(v, color="0.6", linewidth=0.8, linestyle="-.")
    ax_u.set_ylabel(f"input u{cfg.units.label('actuators')}")
    ax_u.set_title("control inputs u(k) (dash-dot: actuator limits)", loc="left", fontsize=10)
    ax_u.legend(loc="upper left", fontsize=8, ncol=len(cfg.actuators))
    ax_u.grid(alpha=0.3)


def _draw_schedule(ax_s, cfg: ControllerConfig, runs, colors) -> None:
    sc = cfg.scheduler
    for label, run, style in runs:
        ax_s.plot(run.t, run.sched[:, 0], color=colors[4 % len(colors)], **style,
                  label=f"{sc.signal}, {label}")
    for v, eps in zip(sc.thresholds, sc.epsilons):
        ax_s.axhline(v, color="0.5", linewidth=0.8)
        for e in (-eps, eps):
            ax_s.axhline(v + e, color="0.7", linewidth=0.6, linestyle=":")
    if cfg.simulation.schedule_source == "output":  # simulate has no such signal: it fed
        fed, unit = f"{cfg.outputs[0]} as {sc.signal}", cfg.units.label("outputs")
    else:
        fed, unit = f"{sc.signal} rho", cfg.units.label("schedule")
    ax_s.set_ylabel(f"{fed}{unit}")
    ax_s.grid(alpha=0.3)
    ax_m = ax_s.twinx()
    names = [m.name for m in cfg.modes]
    for label, run, style in runs:
        ax_m.step(run.t, run.mode + 1, where="post", color="k", **{**style, "linewidth": 0.9},
                  label=f"mode j, {label}")
    ax_m.set_yticks(np.arange(1, len(names) + 1),
                    [f"{j + 1}: {n}" for j, n in enumerate(names)])
    ax_m.set_ylim(0.5, len(names) + 0.5 + 0.6 * len(names))
    ax_m.set_ylabel("mode j")
    ax_s.set_title(f"(b) {fed}(k) (solid: band thresholds of eq. 3, dotted: "
                   "+/- epsilon) and switching mode j(k)", loc="left", fontsize=10)
    h1, l1 = ax_s.get_legend_handles_labels()
    h2, l2 = ax_m.get_legend_handles_labels()
    ax_s.legend(h1 + h2, l1 + l2, loc="upper left", fontsize=8, ncol=2)


def plot_solve_times(path: str | Path, rows: list[dict], replays: dict, sample: np.ndarray,
                     ts: float) -> Path:
    """Fig. 3 style: every QP's solve time against the sample index, log scale; (a) the
    peers, (b) the generated C variants (rows with a ``[C]`` label), the default in both."""
    plt = _pyplot()
    c_rows = [r for r in rows if r["solver"].endswith("[C]")]
    peers = [r for r in rows if r not in c_rows]
    default = [r for r in c_rows if r["key"] == "default"]
    panels = [("(a) peers from PyPI (and our default)", peers + default),
              ("(b) generated C: the paper's Hildreth variants and our default", c_rows)]
    fig, axes = plt.subplots(2, 1, figsize=(10, 8.5), sharex=True, sharey=True)
    times = np.concatenate([replays[r["key"]].solver_s for r in rows])
    times = times[times > 0]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    color_of = {r["key"]: colors[i % len(colors)] for i, r in enumerate(rows)}
    for ax, (title, panel_rows) in zip(axes, panels):
        for r in panel_rows:
            ax.plot(sample + 1, replays[r["key"]].solver_s, ".", markersize=1.5,
                    color=color_of[r["key"]], label=f"{r['solver']}: {r['timer']}")
        ax.axhline(ts, color="k", linewidth=0.8, linestyle="--", label="Ts")
        ax.set_yscale("log")
        ax.set_ylabel("solve time per QP [s]")
        ax.set_title(title, loc="left", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, markerscale=6, ncol=2, loc="upper left")
    if times.size:  # headroom above the data for the legends
        axes[0].set_ylim(times.min() / 2, max(times.max(), ts) * 300)
    axes[-1].set_xlabel("sample k (the same QP sequence for every solver)")
    return _save(plt, fig, path)
