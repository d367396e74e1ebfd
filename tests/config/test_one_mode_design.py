"""A one-mode design as a new user writes it: its actuators named once (``modes[].actuators``
defaults to every actuator), and Fig. 2 without the scheduling panel it has no use for."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from rollmpc_codegen.config import load
from rollmpc_codegen.pipeline import load_model
from rollmpc_codegen.sim.simulate import ClosedLoopLog

from conftest import UAV, cli, config_error

DESIGN = """\
prefix: pitch
sample_time: 0.02
horizon: 25
outputs: [pitch]
actuators: [elevator, canard]
modes:
  - name: cruise
{actuators}    plant:
      transfer_function: {{num: [[-2.0, 1.2]], den: [1, 3.0, 6.0]}}
      integrator: true
    weights: {{Q: 5, R: 1}}
    bounds: {{u_min: -20, u_max: 20}}
simulation:
  reference: {{segment: 2.0, levels: [0, 5, -5]}}
"""


def _design(tmp_path, actuators: str, name: str):
    path = tmp_path / f"{name}.yaml"
    path.write_text(DESIGN.format(actuators=actuators))
    return path


def test_one_mode_names_its_actuators_once(tmp_path):
    implicit = _design(tmp_path, "", "implicit")
    explicit = _design(tmp_path, "    actuators: [elevator, canard]\n", "explicit")
    a, b = load(implicit), load(explicit)
    assert a.modes[0].actuators == ("elevator", "canard")
    assert a == b and a.config_hash == b.config_hash  # the same design, the same C
    assert load_model(implicit)[1] == load_model(explicit)[1]
    reordered = load(_design(tmp_path, "    actuators: [canard, elevator]\n", "reordered"))
    assert reordered.modes[0].actuators == ("canard", "elevator")
    assert reordered.config_hash != a.config_hash  # a mode's own order still counts


def test_modes_still_need_declared_actuators(tmp_path):
    bad = _design(tmp_path, "    actuators: [rudder]\n", "bad")
    assert str(config_error(bad)) == ("modes[0].actuators[0]: unknown actuator 'rudder'; "
                                      "declared actuators are elevator, canard")


def test_simulate_lists_each_actuator_once(tmp_path):
    code, out, err = cli(["simulate", str(_design(tmp_path, "", "once")), "--quiet"])
    assert code == 0, err
    line = next(ln for ln in out.splitlines() if "max |u|" in ln)
    listed = line.split(": ", 1)[1].split(";")[0]
    assert [part.split()[0] for part in listed.split(", ")] == ["elevator", "canard"]


def _log(cfg, K: int = 50) -> ClosedLoopLog:
    na, ns = len(cfg.actuators), cfg.n_schedule
    t = np.arange(K) * cfg.sample_time
    return ClosedLoopLog(t=t, r=np.ones((K, cfg.n_outputs)), y=np.ones((K, cfg.n_outputs)),
                         sched=np.zeros((K, ns)), u=np.zeros((K, na)),
                         mode=np.zeros(K, int), status=np.zeros(K, int),
                         iterations=np.zeros(K, int), solve_us=np.zeros(K))


@pytest.mark.parametrize("which, axes, panel_b", [("one", 2, False), ("uav", 4, True)])
def test_fig2_draws_the_scheduling_panel_only_with_modes_to_schedule(tmp_path, which, axes,
                                                                      panel_b):
    pytest.importorskip("matplotlib", reason="install with: pip install 'rollmpc-codegen[plot]'")
    from rollmpc_codegen.sim.figures import _pyplot, closed_loop_figure

    cfg = load(_design(tmp_path, "", "fig") if which == "one" else UAV)
    plt = _pyplot()
    fig = closed_loop_figure(plt, cfg, _log(cfg), baseline=_log(cfg))
    titles = [ax.get_title(loc="left") for ax in fig.axes]
    assert len(fig.axes) == axes  # the UAV's panel (b) has the mode on a twin axis
    assert any(t.startswith("(b) roll_rate rho(k)") for t in titles) == panel_b
    assert titles[0].startswith("(a) tracking output") and titles[1].startswith("control inputs")
    assert fig.axes[-1 if which == "one" else 2].get_xlabel() == "time t [s]"
    legend = [t.get_text() for t in fig.axes[1].get_legend().get_texts()]
    assert legend == [f"u {a}, {run}" for a in cfg.actuators
                      for run in ("MPC", "LQR + saturation")]
    plt.close(fig)
