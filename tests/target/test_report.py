"""rollmpc report: the target image runs on the emulated Cortex-M4F bit for bit like the
host float build, the JSON carries the promised keys, and the cycle counts are positive
and identical run to run."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import UAV, require_tool

ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"
REPORT_KEYS = ("flash_bytes", "ram_bytes", "stack_bytes", "worst_step_instructions",
               "worst_step_cycles", "median_step_cycles", "cpu_mhz_needed",
               "bit_exact_vs_host", "worst_step_top_functions")


@pytest.fixture
def target_tools():
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")


@pytest.fixture(scope="module")
def float_model():
    from rollmpc_codegen.pipeline import load_model

    return load_model(UAV, "float")


def test_report_json_keys_and_bit_exact(target_tools, tmp_path, build_root, capsys):
    """960 steps: the first reference step enters the preview at step 900 and saturates
    the ailerons over the whole horizon."""
    from rollmpc_codegen.cli.main import main

    out = tmp_path / "report.json"
    assert main(["report", str(UAV), "--precision", "float", "--steps", "960",
                 "--sample-every", "160", "--hardest", "3", "--json", str(out), "--quiet",
                 "--build-dir", str(build_root)]) == 0
    rep = json.loads(out.read_text())
    for key in REPORT_KEYS:
        assert key in rep, key
    assert rep["bit_exact_vs_host"] is True and rep["state_bit_exact"] is True
    assert rep["steps_emulated"] == 960 and rep["mismatches"] == 0
    assert rep["worst_step"] >= 900  # a constrained step, not the quiet first 9 s
    assert rep["worst_step_cycles"] > rep["median_step_cycles"] > 0
    assert rep["worst_step_cycles"] >= rep["worst_step_instructions"] > 0
    assert rep["cpu_mhz_needed"] == pytest.approx(rep["worst_step_cycles"] / 0.01 / 1e6,
                                                  abs=0.01)
    assert rep["ram_bytes"] >= rep["ctrl_bytes"] > 0 and rep["flash_bytes"] > 100_000
    assert rep["stack_bytes"] > 0 and rep["stack_path"][0] == "rollmpc_step"
    # the static worst path bounds the stack the emulated run really used
    assert 0 < rep["stack_measured_bytes"] <= rep["stack_entry_bytes"]
    shares = [f["share"] for f in rep["worst_step_top_functions"]]
    other = rep["worst_step_other_functions_share"]  # the functions past the top 20
    assert shares == sorted(shares, reverse=True) and other >= 0
    assert sum(shares) + other == pytest.approx(1.0, abs=0.002)
    text = capsys.readouterr().out
    assert "168 MHz" in text and "bit-exact vs host: yes" in text
    # every replayed step's status (uav_roll's own budget: no TIME_LIMIT), and no warning
    assert rep["statuses"] == {"optimal": 960} and rep["longest_time_limit_run"] == 0
    assert "solver statuses over 960 steps: optimal 960" in text and "warning" not in text


def test_summary_names_the_longest_time_limit_run():
    """The report's summary line gives the longest run of TIME_LIMIT samples, and its
    warning says when one outlasted the last plan (horizon - 1 samples)."""
    from rollmpc_codegen.cli.report import summary_text

    rep = {"budget": {"worst_fits": True, "cpu_mhz": 168, "worst_load_percent": 40.0,
                      "cycles_per_sample": 1_680_000},
           "worst_step_top_functions": [], "worst_flight": None, "worst_step": 7,
           "precision": "float", "horizon": 30, "toolchain": "gcc", "flash_bytes": 1,
           "ram_bytes": 1, "ctrl_bytes": 1, "stack_bytes": 1, "stack_measured_bytes": 1,
           "stack_entry_bytes": 1, "steps_emulated": 100, "steps_counted": 10,
           "hardest_steps": [], "sample_every": 20, "bit_exact_vs_host": True,
           "worst_step_mode": 0, "worst_step_cycles": 1, "worst_step_instructions": 1,
           "median_step_cycles": 1, "cpu_mhz_needed": 1.0, "sample_time": 0.01,
           "statuses": {"optimal": 60, "time_limit": 40}, "goals": {}}
    from rollmpc_codegen.config import load
    from rollmpc_codegen.target.verdicts import conclude

    def text(longest: int) -> str:  # the report's warnings are concluded from its figures
        return summary_text(conclude(dict(rep, longest_time_limit_run=longest), load(UAV),
                                     "float"))

    short, long = text(29), text(30)
    assert "over 100 steps: optimal 60, time_limit 40 (longest TIME_LIMIT run 29)" in short
    assert "outlasted" not in short
    assert "The longest run, 30 samples, outlasted the last plan (it covers 29)" in long


def test_emulated_cycles_are_deterministic(target_tools, float_model, build_root):
    from rollmpc_codegen.target.replay import record_host_run, replay_on_target
    from rollmpc_codegen.target.build import build_target

    model, ctx = float_model
    build = build_target(ctx, build_root)
    record = record_host_run(model, ctx, build_root, steps=942, progress=False)
    counted = {0, 940, 941}
    runs = [replay_on_target(build, ctx, record, counted, progress=False) for _ in range(2)]
    for run in runs:
        assert not run.mismatches and run.state_equal
        assert set(run.counts) == counted
        assert all(c.cycles > c.instructions > 0 for c in run.counts.values())
    for k in counted:
        a, b = runs[0].counts[k], runs[1].counts[k]
        assert (a.instructions, a.cycles, a.by_function) == (b.instructions, b.cycles,
                                                             b.by_function)
    # a saturated step costs more than the unconstrained first one
    assert runs[0].counts[941].cycles > runs[0].counts[0].cycles


@pytest.mark.parametrize("name, ops, cycles", [
    ("vdiv", "s0, s1, s2", 14), ("vsqrt", "s0, s0", 14), ("vfma", "s0, s1, s2", 3),
    ("vldr", "s0, [r3, #4]", 2), ("ldrd", "r2, r3, [r0]", 3), ("push", "{r4, r5, r6, lr}", 5),
    ("vldmia", "r3!, {s14, s15}", 3), ("vpush", "{d8, d9}", 5), ("vmov", "r0, s0", 2),
    ("vmov", "s0, s1", 1), ("sdiv", "r0, r1, r2", 12), ("add", "r0, r1", 1)])
def test_cycle_weights_follow_the_table(name, ops, cycles):
    pytest.importorskip("capstone", reason="pip install 'rollmpc-codegen[target]'")
    from rollmpc_codegen.target.cycle_models import instruction_cycles

    assert instruction_cycles(name, ops) == cycles


@pytest.mark.slow  # three horizons on the emulator (the refused horizon is listed in make test)
def test_horizon_table_and_fits(target_tools, tmp_path, build_root, capsys):
    from rollmpc_codegen.cli.main import main

    out = tmp_path / "h.json"
    assert main(["report", str(UAV), "--precision", "float", "--horizons", "10,20",
                 "--steps", "60", "--sample-every", "30", "--hardest", "1", "--quiet",
                 "--json", str(out), "--build-dir", str(build_root)]) == 0
    table = json.loads(out.read_text())["horizons"]
    rows = table["rows"]
    assert [r["horizon"] for r in rows] == [10, 20]
    assert rows[1]["flash_bytes"] > rows[0]["flash_bytes"] > 0
    assert all(r["bit_exact_vs_host"] and r["generation_s"] > 0 for r in rows)
    assert table["fits"]["flash_bytes"]["exponent"] > 0
    assert all(p["horizons_that_fit_memory"] == [10, 20] for p in table["parts"])
    assert "| 20 |" in capsys.readouterr().out


@pytest.mark.slow
def test_horizon_the_generator_refuses_is_listed(target_tools, tmp_path, build_root, capsys):
    """uav_roll's explicit work budget (100,000 units) is below the unconstrained step of
    N = 300: that row is refused with the generator's reason, N = 10 still measured."""
    from rollmpc_codegen.cli.main import main

    out = tmp_path / "h.json"
    assert main(["report", str(UAV), "--precision", "float", "--horizons", "10,300",
                 "--steps", "30", "--sample-every", "30", "--hardest", "1", "--quiet",
                 "--json", str(out), "--build-dir", str(build_root)]) == 0
    table = json.loads(out.read_text())["horizons"]
    assert [r["horizon"] for r in table["rows"]] == [10]
    assert [r["horizon"] for r in table["refused"]] == [300]
    assert "work_budget" in table["refused"][0]["error"]
    assert "N = 300: not generated: solver.work_budget" in capsys.readouterr().out


@pytest.mark.parametrize("args", [["--horizons", "10,x"], ["--steps", "0"]])
def test_bad_report_arguments_give_one_line(args, capsys):
    from rollmpc_codegen.cli.main import main

    assert main(["report", str(UAV), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rollmpc: error:")


def test_instance_layout_matches_the_host(target_tools, float_model, build_root):
    """The final-state comparison of replay_on_target relies on identical struct layouts."""
    from rollmpc_codegen.host.build import build_host_controller
    from rollmpc_codegen.target.emulate import CortexM
    from rollmpc_codegen.target.build import build_target

    model, ctx = float_model
    build = build_target(ctx, build_root)
    em = CortexM(build.elf, build.core)
    size, real, _, _, wide = np.frombuffer(em.read("rollmpc_target_layout"), np.uint32)
    host = build_host_controller(ctx, build_root)
    assert size == host.lib.rollmpc_ctrl_size() and real == 4
    assert wide == 1  # a float tree on the M4F's FPU: the wide kernels (internal.h.j2)


def test_kernel_charges_cover_their_cycles(target_tools):
    """The Cholesky and the triangular solves alone on the emulated M4F never take more
    cycles per operation than their work charge buys (qp/work.py's calibration)."""
    from rollmpc_codegen.parts import CORTEX_M4F
    from rollmpc_codegen.qp.work import CHOL_UNITS_PER_OP, TRI_UNITS_PER_OP
    from rollmpc_codegen.target.kernel_cycles import kernel_cycles

    CYCLES_PER_WORK_UNIT = CORTEX_M4F.cycles_per_work_unit("float")
    rows = kernel_cycles(UAV, orders=(5, 20, 60))
    assert [r["order"] for r in rows] == [5, 20, 60]
    for r in rows:  # measured 7.36 / 11.53 at order 5, 5.33 / 9.59 at 60
        assert r["per_chol_op"] <= CYCLES_PER_WORK_UNIT * CHOL_UNITS_PER_OP[0] / CHOL_UNITS_PER_OP[1]
        assert r["per_tri_op"] <= CYCLES_PER_WORK_UNIT * TRI_UNITS_PER_OP[0] / TRI_UNITS_PER_OP[1]
    assert rows[-1]["per_chol_op"] < rows[0]["per_chol_op"]  # the blocked kernel pays at size


def test_kernel_cycles_names_a_bad_config_in_one_line(tmp_path, capsys):
    """The measurement tool's own CLI: --help, and a missing config as exit 2, no traceback."""
    from rollmpc_codegen.target.kernel_cycles import main

    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    assert stop.value.code == 0 and "config" in capsys.readouterr().out
    assert main([str(tmp_path / "absent.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "absent.yaml: cannot read" in err


def test_instances_equal_but_for_the_sign_of_nan():
    """report's instance check takes a NaN for a NaN whatever its sign (x86 makes -NaN
    where the M4F makes +NaN: "bit-exact vs host: NO (0 mismatches)" on a diverged run),
    and any other difference as one."""
    from rollmpc_codegen.target.replay import same_state

    f4 = np.dtype(np.float32)
    host = np.array([1.0, np.nan, 3.0], f4).tobytes() + b"\x01\x00"
    neg = np.frombuffer(host[4:8], np.uint32)[0] | np.uint32(0x80000000)
    target = host[:4] + np.uint32(neg).tobytes() + host[8:]
    assert host != target and same_state(host, target, f4)
    assert not same_state(host, target[:8] + np.float32(3.5).tobytes() + host[12:], f4)
    assert not same_state(host, host[:-1] + b"\x02", f4)  # a byte past the last real
    assert same_state(host, host, f4) and not same_state(host, host[:-2], f4)
