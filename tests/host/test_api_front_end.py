"""The Python API as complete as the CLI (docs/checks.md), on the drone of
tests/data/newuser/drone_alt.py: every warning the CLI prints reaches an API user as
data (``.warnings``, DesignWarnings) and through Python's ``warnings``; a Design
simulates, benches and reports itself, with the library's documents; a misspelt keyword
names the keyword meant."""
from __future__ import annotations

import json
import sys
import warnings

import pytest

from conftest import ROOT
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.config import ConfigError, DesignWarning, RollmpcWarning
from rollmpc_codegen.sim.scenario_run import run_scenario

NEWUSER = ROOT / "tests" / "data" / "newuser"
sys.path.insert(0, str(NEWUSER))
import drone_alt  # noqa: E402

ABOVE_REST = {"y_bounds": ([1.0, -2.0], [10.0, 3.0])}  # z >= 1 m: not met from rest


@pytest.fixture(scope="module")
def drone():
    return drone_alt.design()


def test_generate_returns_and_warns_what_the_cli_prints(tmp_path, capsys):
    design = drone_alt.design(mode=ABOVE_REST)
    with pytest.warns(RollmpcWarning, match=r"z >= 1 m \(bounds.y_min\) cannot be met from "
                      r"rest.*\[bound_unreachable_from_rest\]"):
        run = design.generate(tmp_path / "api")
    assert [(w.code, w.key) for w in run.warnings] == [
        ("bound_unreachable_from_rest", "modes[0].bounds.y_min")]
    assert (tmp_path / "api" / "drone.h").is_file() and run.path == tmp_path / "api"
    assert run.footprint.step_units > 0
    config = tmp_path / "drone.yaml"
    design.to_yaml(config)
    assert main(["generate", str(config), "-o", str(tmp_path / "cli")]) == 0
    assert capsys.readouterr().err.splitlines() == [f"rollmpc: warning: {w.message}"
                                                   for w in run.warnings]


def test_a_float_generate_runs_the_float_check_and_names_what_double_costs(tmp_path, drone):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        run = drone.generate(tmp_path / "f32", precision="float",
                             build_dir=tmp_path / "build")
    assert run.float_check is not None and run.float_check.unsafe  # P = 1000 Q: 0.11 off
    (found,) = run.warnings
    assert (found.code, found.key) == ("float_inaccurate", "precision")
    assert "double is soft-float, 7-22 times the float build's cycles" in found.message
    assert [str(w.message) for w in seen] == [f"{found.message} [float_inaccurate]"]
    assert not (tmp_path / "f32b").exists()
    drone.generate(tmp_path / "f32b", precision="float", float_check=False)


def test_simulate_returns_the_document_of_the_library_and_the_cli(tmp_path, drone):
    run = drone.simulate(steps=300, build_dir=tmp_path / "b")
    config = tmp_path / "drone.yaml"
    drone.to_yaml(config)
    by_file = run_scenario(config, steps=300, build_dir=tmp_path / "b")
    by_config = run_scenario(drone.config, steps=300, build_dir=tmp_path / "b")
    for other in (by_file, by_config):
        for key in ("segments", "status_counts", "work", "constraint_violations", "checks"):
            assert run.summary[key] == other.summary[key], key
    assert run.summary["config"] == "drone (Python API)"
    assert by_file.summary["config"] == str(config)
    assert run.warnings == [] and run.summary["checks"] == []


def test_simulate_warns_of_infeasible_samples_and_suggests_soft_bounds(tmp_path, drone):
    """Hard vertical-speed bounds under noise, a mismatched plant and a disturbance:
    INFEASIBLE samples and the bound passed, with only a TIME_LIMIT warning (if any)."""
    with pytest.warns(RollmpcWarning, match=r"\[infeasible_samples\]"):
        run = drone.simulate(steps=400, noise_std=0.01, mismatch=0.2, disturbance=1.0,
                             build_dir=tmp_path / "b")
    (found,) = [w for w in run.warnings if w.code == "infeasible_samples"]
    counts = run.summary["status_counts"]
    assert counts["infeasible"] > 0 and found.key == "modes[0].bounds.soft"
    assert found.message.startswith(f"{counts['infeasible']} of 400 samples")
    assert "passed them by up to vz " in found.message
    assert "modes[0].bounds.soft: {y_min: {l1: 0, l2: 1000}, y_max: {l1: 0, l2: 1000}}" \
        in found.message
    assert DesignWarning(**run.summary["checks"][0]) == found


def test_flights_through_the_api(tmp_path, drone):
    run = drone.simulate(flights=2, steps=100, build_dir=tmp_path / "b")
    assert len(run.summary["flights"]) == 2 and isinstance(run.warnings, list)


def test_bench_through_the_api(tmp_path, drone):
    pytest.importorskip("quadprog", reason="install with: pip install 'rollmpc-codegen[peers]'")
    result = drone.bench(variants=["default"], steps=100, build_dir=tmp_path / "b")
    assert result.summary["config"] == "drone (Python API)"
    assert [r["key"] for r in result.summary["rows"]][:1] == ["default"]


def test_report_through_the_api(tmp_path, drone):
    pytest.importorskip("unicorn", reason="install with: pip install 'rollmpc-codegen[target]'")
    pytest.importorskip("elftools", reason="install with: pip install 'rollmpc-codegen[target]'")
    with pytest.warns(RollmpcWarning, match=r"\[soft_float_double\]"):
        rep = drone.report(steps=40, sample_every=20, hardest=1, host_repeats=1,
                           build_dir=tmp_path / "b")
    assert rep["verdicts"]["bit_exact"] and "sample_time" in rep["verdicts"]
    assert [c["code"] for c in rep["checks"]] == ["soft_float_double"]
    json.dumps(rep)  # the --json document


@pytest.mark.parametrize("keyword, meant", [("u_bound", "u_bounds"), ("du_bonds", "du_bounds"),
                                            ("R_detla", "R_delta")])
def test_a_misspelt_mode_keyword_names_the_keyword_meant(keyword, meant):
    with pytest.raises(ConfigError) as exc:
        drone_alt.design(mode={keyword: (-1.0, 1.0)})
    assert str(exc.value) == f"modes[0].{keyword}: unknown key (did you mean {meant}?)"
