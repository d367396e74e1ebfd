"""Small CLI cleanups: units and names in `rollmpc simulate`'s summary and --plot labels
(the top-level `units` key), the test-vector QP picks at each mode's own bounds, and a
build failure's command printed once."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from conftest import ROOT, UAV, cli, config_error
from rollmpc_codegen.sim import figures as paper_figures
from rollmpc_codegen.sim import scenario_run as simulate_cli
from rollmpc_codegen.host.build import BuildError
from rollmpc_codegen.config import UnitsConfig, load
from rollmpc_codegen.sim.simulate import ClosedLoopLog
from rollmpc_codegen.host.testvectors import saturated_samples

CHAIN = ROOT / "examples" / "chain_of_masses.yaml"
ZONES = ROOT / "examples" / "thermal_zones.yaml"


def test_units_config_and_labels():
    assert load(UAV).units == UnitsConfig(outputs=("deg",), actuators=("deg", "deg"),
                                          schedule="deg/s")
    assert load(CHAIN).units == UnitsConfig()  # none given: no unit anywhere
    assert UnitsConfig().label("outputs") == "" and UnitsConfig().label("schedule") == ""
    mixed = UnitsConfig(outputs=("K", "W"), actuators=("kW", ""), schedule="K/s")
    assert mixed.label("outputs") == "" and mixed.label("actuators") == ""
    assert mixed.label("schedule") == " [K/s]"


@pytest.mark.parametrize("units, key", [
    ({"outputs": ["K"]}, "units.outputs"),
    ({"actuators": 3}, "units.actuators"),
    ({"schedule": ["a"]}, "units.schedule"),
    ({"output": "K"}, "units.output"),
])
def test_units_errors_name_the_key(tmp_path, units, key):
    data = yaml.safe_load(ZONES.read_text())
    data["units"] = units
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    err = config_error(path)
    assert err.key == key


def _log(cfg, K: int = 30) -> ClosedLoopLog:
    ny, na = cfg.n_outputs, len(cfg.actuators)
    return ClosedLoopLog(t=np.arange(K) * cfg.sample_time, r=np.zeros((K, ny)),
                         y=np.zeros((K, ny)), sched=np.zeros((K, cfg.n_schedule)),
                         u=np.zeros((K, na)), status=np.zeros(K, int), mode=np.zeros(K, int),
                         iterations=np.zeros(K, int), solve_us=np.zeros(K))


@pytest.mark.parametrize("config, texts, absent", [
    (UAV, ["output y, reference r [deg]", "input u [deg]", "roll_rate rho [deg/s]",
           "y(k) = roll and"], []),
    (CHAIN, ["output y, reference r", "input u", "y(k) = p1, p2, p3, p4, p5, p6 and"],
     ["deg", "roll"]),
    # schedule_source: output: simulate feeds the roll angle as the airspeed, and says so
    (ROOT / "examples" / "c172_roll.yaml", ["roll as airspeed [deg]"], ["airspeed rho"]),
])
def test_plot_labels_use_names_and_units(tmp_path, monkeypatch, config, texts, absent):
    pytest.importorskip("matplotlib", reason="install with: pip install 'rollmpc-codegen[plot]'")
    seen = []

    def capture(plt, fig, path):
        for ax in fig.axes:
            seen.extend([ax.get_ylabel(), ax.get_title(loc="left")])
        plt.close(fig)
        return path

    monkeypatch.setattr(paper_figures, "_save", capture)
    cfg = load(config)
    paper_figures.plot_closed_loop(tmp_path / "f.png", cfg, _log(cfg))
    joined = " | ".join(seen)
    for t in texts:
        assert t in joined, joined
    for t in absent:
        assert t not in joined, joined


def test_summary_without_units_has_no_deg(tmp_path):
    rc, out, err = cli(["simulate", str(CHAIN), "--quiet", "--steps", "5"])
    assert rc == 0, err
    assert "settled |y - r| per segment: " in out and "max |u|: " in out
    assert "deg" not in out


def test_saturated_samples_use_each_modes_bounds():
    cfg = load(ROOT / "examples" / "three_drives.yaml")  # |u| <= 1 on every drive
    log = _log(cfg, 6)
    modes = [0, 0, 1, 2, 2, 1]
    log.u[1, 0] = float(np.float32(-1.0))  # fine at its lower bound
    log.u[2, 1] = 0.999  # medium inside its bounds
    log.u[3, 2] = 1.0  # coarse at its upper bound
    log.u[5, 0] = 1.0  # an actuator the active mode (medium) does not drive
    assert saturated_samples(cfg, log, modes).tolist() == [1, 3]
    chain = load(CHAIN)  # |u| <= 0.5: not a UAV threshold of 15
    log = _log(chain, 3)
    log.u[2, 3] = float(np.float32(0.5))
    assert saturated_samples(chain, log, [0, 0, 0]).tolist() == [2]


def test_build_failure_prints_the_command_once(tmp_path, monkeypatch):
    def fail(*_args, **_kw):
        raise BuildError("gcc -O2 -o libx.so x.c\nx.c:1:1: error: expected ';'")

    monkeypatch.setattr(simulate_cli, "build_host_controller", fail)
    rc, _, err = cli(["simulate", str(CHAIN), "--quiet", "--steps", "2"])
    assert rc != 0 and rc != 2
    assert err.count("gcc -O2 -o libx.so x.c") == 1, err
    assert err.splitlines()[0] == "rollmpc: error: build failed: gcc -O2 -o libx.so x.c"
    assert "x.c:1:1: error: expected ';'" in err
