"""rollmpc report on randomized flights and its verdict on the config's own sample time
and ``target:`` section: flights with distinct,
seeded references, replayed bit for bit and deterministic; the overall worst step named
by flight and step; the plant mismatch within its stated fraction."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from conftest import UAV
from test_report import target_tools  # noqa: F401 (the fixture: skip without the tools)


@pytest.fixture(scope="module")
def slow_uav(tmp_path_factory):
    """The paper's plant at Ts = 20 ms, N = 20, on an 84 MHz part without memory limits;
    its scenario is one 0.5 s segment, so a 100-sample flight has 4 levels."""
    data = yaml.safe_load(UAV.read_text())
    data.update(sample_time=0.02, horizon=20, target={"cpu_mhz": 84},
                simulation=dict(data["simulation"], reference={"levels": [0], "segment": 0.5}))
    path = tmp_path_factory.mktemp("flights") / "uav_slow.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _report(config, build_root, sample_every: int = 10, **options):
    from rollmpc_codegen.target.report import run_report

    return run_report(config, precision="float", steps=100, sample_every=sample_every,
                      hardest=2, host_repeats=1, build_dir=build_root, **options)


@pytest.mark.slow
def test_flights_are_seeded_distinct_and_name_the_overall_worst(target_tools, slow_uav,
                                                                 build_root):
    # every step counted: the hardest steps are ranked by the (noisy) host clock
    options = {"flights": 2, "seed": 5, "noise_std": 0.05, "disturbance": 0.2,
               "mismatch": 0.2, "sample_every": 1}
    rep = _report(slow_uav, build_root, **options)
    flights = rep["flights"]
    assert [f["flight"] for f in flights] == [0, 1] and [f["seed"] for f in flights] == [5, 6]
    assert rep["perturbations"] == {"flights": 2, "seed": 5, "noise_std": 0.05,
                                    "disturbance": 0.2, "mismatch": 0.2, "kinds": "both"}
    levels = [np.array(f["levels"]) for f in flights]
    assert all(lv.shape == (4, 1) for lv in levels)
    assert not np.array_equal(levels[0], levels[1])  # distinct reference sequences
    # an odd seed presses the envelope (up to the hard ±270 deg), an even one stays within
    # the scenario's range
    assert [f["kind"] for f in flights] == ["envelope", "inside"]
    assert np.all(np.abs(levels[0]) <= 270) and np.all(np.abs(levels[1]) <= 40)
    assert list(rep["by_kind"]) == ["inside", "envelope"]
    assert rep["by_kind"]["envelope"]["worst_flight"] == 0
    assert sum(k["worst_step_cycles"] == rep["worst_step_cycles"]
               for k in rep["by_kind"].values()) >= 1
    for f in flights:
        assert f["bit_exact_vs_host"] is True and f["mismatches"] == 0
        assert f["steps"] == f["steps_counted"] == 100
        assert f["worst_step_cycles"] >= f["median_step_cycles"] > 0
        gains = np.array(f["plant_mismatch"]["gain"] + f["plant_mismatch"]["poles"])
        assert np.all(np.abs(gains - 1) <= 0.2) and np.any(gains != 1)
    assert rep["bit_exact_vs_host"] is True and rep["steps_emulated"] == 200
    # each flight's statuses, and the report's over both flights
    assert all(sum(f["statuses"].values()) == 100 for f in flights)
    assert sum(rep["statuses"].values()) == 200
    assert all(rep["statuses"].get(k, 0) == sum(f["statuses"].get(k, 0) for f in flights)
               for k in rep["statuses"])
    # the overall worst is the largest of the flights' worsts, and names where it was
    assert rep["worst_step_cycles"] == max(f["worst_step_cycles"] for f in flights)
    worst = flights[rep["worst_flight"]]
    assert (worst["worst_step"], worst["worst_step_cycles"]) == (rep["worst_step"],
                                                                 rep["worst_step_cycles"])
    pooled = rep["median_step_cycles"]
    assert min(f["median_step_cycles"] for f in flights) <= pooled <= max(
        f["median_step_cycles"] for f in flights)
    # the same seed flies the same flights to the same cycle
    again = _report(slow_uav, build_root, **options)
    assert again["flights"] == flights and again["worst_step_cycles"] == rep["worst_step_cycles"]
    # flight i of seed S is flight 0 of seed S + i
    alone = _report(slow_uav, build_root, **dict(options, flights=1, seed=6))
    assert alone["flights"][0] == dict(flights[1], flight=0)


def test_budget_uses_the_configs_sample_time_and_clock(target_tools, slow_uav, build_root):
    """The verdict is the worst step against the config's own Ts (20 ms) and clock (84 MHz),
    not the paper's 10 ms at 168 MHz; the clock the report says it needs is where the worst
    step starts to fit. No flash or RAM limit is declared: no memory verdict."""
    from rollmpc_codegen.config import TargetConfig, load
    from rollmpc_codegen.target.measure import budget_verdict

    rep = _report(slow_uav, build_root)
    cfg, worst = load(slow_uav), rep["worst_step_cycles"]
    assert rep["budget"] == budget_verdict(cfg, worst)
    paper = dataclasses.replace(cfg, sample_time=0.01, target=TargetConfig(cpu_mhz=168.0))
    assert rep["budget"] != budget_verdict(paper, worst)
    def at(mhz):  # the config's sample time at another clock
        return budget_verdict(dataclasses.replace(cfg, target=TargetConfig(cpu_mhz=mhz)), worst)

    needed = rep["cpu_mhz_needed"]  # rounded to 0.01 MHz
    assert at(needed + 0.01)["worst_fits"] and not at(needed - 0.01)["worst_fits"]
    assert rep["goals"] == {}
    assert rep["worst_flight"] is None and "flights" not in rep


def test_the_verdict_follows_the_sample_time_and_the_clock():
    """A step that fits in 20 ms at 84 MHz does not in 10 ms, nor at half the clock, where
    it takes twice the share of the sample."""
    from rollmpc_codegen.config import TargetConfig, load
    from rollmpc_codegen.target.measure import budget_verdict

    cfg = dataclasses.replace(load(UAV), sample_time=0.02, target=TargetConfig(cpu_mhz=84.0))
    step = 1_000_000
    fits = budget_verdict(cfg, step)
    shorter = budget_verdict(dataclasses.replace(cfg, sample_time=0.01), step)
    slower = budget_verdict(dataclasses.replace(cfg, target=TargetConfig(cpu_mhz=42.0)), step)
    assert fits["worst_fits"] and not shorter["worst_fits"] and not slower["worst_fits"]
    assert slower["worst_load_percent"] == shorter["worst_load_percent"] == pytest.approx(
        2 * fits["worst_load_percent"], abs=0.1)
    assert (fits["sample_time"], fits["cpu_mhz"]) == (0.02, 84.0)


def test_the_paper_config_declares_its_memory_goals():
    from rollmpc_codegen.config import TargetConfig, load
    from rollmpc_codegen.target.measure import memory_goals

    cfg = load(UAV)
    assert cfg.target == TargetConfig(cpu_mhz=168.0, flash_kib=256.0, ram_kib=32.0)
    assert memory_goals(cfg, 262_144, 32_769, 32_768) == {
        "flash_bytes<=262144": True, "ram_bytes<=32768": False, "ctrl_bytes<=32768": True}
    plain = dataclasses.replace(cfg, target=TargetConfig())
    assert memory_goals(plain, 10**9, 10**9, 10**9) == {}
    assert plain.config_hash != cfg.config_hash  # the target section is hashed


@pytest.mark.parametrize("target, message", [
    ({"cpu_mzh": 100}, "target.cpu_mzh: unknown key (did you mean cpu_mhz?)"),
    ({"cpu_mhz": 0}, "target.cpu_mhz: must be > 0, got 0.0"),
    ({"ram_kib": "lots"}, "target.ram_kib: must be a number, got 'lots'")])
def test_target_section_errors_name_the_key(target, message):
    from rollmpc_codegen.config import ConfigError
    from rollmpc_codegen.config.controller import parse

    data = dict(yaml.safe_load(UAV.read_text()), target=target)
    with pytest.raises(ConfigError) as err:
        parse(data)
    assert str(err.value) == message


def _rate_dc_gain(channel, steps: int = 2000) -> float:
    """The pre-integrator output (roll rate) after a long unit input."""
    x = np.zeros(channel.A.shape[0])
    for _ in range(steps):
        x = channel.A @ x + channel.B[:, 0]
    return float(channel.Cr[0] @ x + channel.Dr[0, 0])


def test_mismatch_scales_gain_and_poles_within_the_fraction():
    from rollmpc_codegen.config import load
    from rollmpc_codegen.sim.scenario import SimulatedPlant, plant_mismatch

    cfg = load(UAV)
    mismatch = plant_mismatch(cfg, 0.2, seed=3)
    factors = np.array(mismatch.gain + mismatch.poles)
    assert factors.shape == (4,) and np.all(np.abs(factors - 1) <= 0.2)
    assert np.all(factors != 1)
    assert plant_mismatch(cfg, 0.2, seed=3) == mismatch and plant_mismatch(cfg, 0.0, 3) is None
    nominal, perturbed = SimulatedPlant(cfg), SimulatedPlant(cfg, mismatch)
    for j, (a, b) in enumerate(zip(nominal.channels, perturbed.channels)):
        poles_a = np.sort_complex(np.log(np.linalg.eigvals(a.A).astype(complex)))
        poles_b = np.sort_complex(np.log(np.linalg.eigvals(b.A).astype(complex)))
        np.testing.assert_allclose(poles_b, mismatch.poles[j] * poles_a, rtol=1e-9, atol=1e-12)
        assert _rate_dc_gain(b) == pytest.approx(mismatch.gain[j] * _rate_dc_gain(a),
                                                 rel=1e-9)


def test_mismatch_of_a_discrete_plant_goes_through_its_continuous_equivalent():
    """A discrete plant (the ZOH of G) perturbed equals G perturbed, then sampled."""
    from rollmpc_codegen.config import PlantConfig, load
    from rollmpc_codegen.model.plant import g_realisation, with_integrator, zoh
    from rollmpc_codegen.sim.mismatch import PlantMismatch

    cfg = load(UAV)
    mode = cfg.modes[1]
    A, B, C, D = g_realisation(mode.plant)
    sampled = zoh(with_integrator(A, B, C, D, False), cfg.sample_time)
    continuous = dataclasses.replace(mode, plant=dataclasses.replace(mode.plant,
                                                                     integrator=False))
    discrete = dataclasses.replace(mode, plant=PlantConfig(
        kind="state_space", A=sampled.A, B=sampled.B, C=sampled.C, D=np.zeros((1, 1)),
        discrete=True))
    mismatch = PlantMismatch(gain=(1.1,), poles=(0.85,))
    want, got = (mismatch.plant(0, m, cfg.sample_time) for m in (continuous, discrete))
    for name in ("A", "B", "C"):
        np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=1e-8,
                                   atol=1e-12)


@pytest.mark.parametrize("args", [["--flights", "-1"], ["--mismatch", "1"],
                                  ["--noise", "-0.1"]])
def test_bad_flight_arguments_give_one_line(args, capsys):
    from rollmpc_codegen.cli.main import main

    assert main(["report", str(UAV), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"rollmpc: error: {args[0]}")
