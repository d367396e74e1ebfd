"""Exit codes a CI job can gate on (docs/checks.md, "Exit codes"): ``rollmpc report``
exits 3 when a verdict fails (Ts, flash, RAM, bit-exactness) and with ``--check`` when it
warns; a double report without ``--precision`` says it emulates soft-float double.  The
firmware build refuses an image beyond the design's target: section (firmware.mk)."""
from __future__ import annotations

import json
import re
import subprocess

import pytest
import yaml

from conftest import ROOT, require_tool
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.cli.report import exit_code
from rollmpc_codegen.config import load
from rollmpc_codegen.target.verdicts import EXIT_VERDICT_FAILED, conclude

NEWUSER = ROOT / "tests" / "data" / "newuser"
ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"


def figures(worst_fits=True, goals=None, bit_exact=True, statuses=None) -> dict:
    """The figures of a report that verdicts.conclude reads."""
    return {"budget": {"worst_fits": worst_fits}, "goals": goals or {},
            "bit_exact_vs_host": bit_exact, "statuses": statuses or {"optimal": 10},
            "longest_time_limit_run": 0, "horizon": 50}


SHIP = load(NEWUSER / "ship_heading.yaml")


@pytest.mark.parametrize("rep, failed", [
    (figures(), []),
    (figures(worst_fits=False), ["sample_time"]),
    (figures(goals={"flash_bytes<=131072": False, "ram_bytes<=32768": True,
                    "ctrl_bytes<=32768": True}), ["flash"]),
    (figures(goals={"ram_bytes<=32768": True, "ctrl_bytes<=32768": False}), ["instance"]),
    (figures(bit_exact=False), ["bit_exact"]),
], ids=["met", "ts", "flash", "instance", "bit-exact"])
def test_a_failed_verdict_exits_3(rep, failed):
    conclude(rep, SHIP, "float")
    assert [k for k, v in rep["verdicts"].items() if not v] == failed
    assert exit_code(rep, check=False) == (EXIT_VERDICT_FAILED if failed else 0)


def test_check_fails_on_a_warning_too():
    rep = conclude(figures(statuses={"optimal": 8, "time_limit": 2}), SHIP, "float")
    assert rep["passed"] and [c["code"] for c in rep["checks"]] == ["time_limit"]
    assert exit_code(rep, check=False) == 0
    assert exit_code(rep, check=True) == EXIT_VERDICT_FAILED
    assert exit_code({"horizons": {}}, check=True) == 0  # a table, no verdict


def test_a_double_report_without_precision_says_what_it_emulates():
    (found,) = conclude(figures(), SHIP, None)["checks"]
    assert found["code"] == "soft_float_double" and found["key"] == "precision"
    assert found["message"].endswith("the target runs the float build: --precision float")
    assert conclude(figures(), SHIP, "double")["checks"] == []  # asked for


def test_a_budget_past_the_sample_fails_the_report(tmp_path, capsys):
    """tests/data/newuser/buck.yaml at 168 MHz with a budget set by hand past its sample
    (generate warns: at most 700 units): the worst step is past the 8,400 cycles of 50 us
    (it printed "DOES NOT fit" and exited 0)."""
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")
    config = tmp_path / "buck.yaml"
    config.write_text((NEWUSER / "buck.yaml").read_text().replace(
        "solver: {budget_share: 0.9}", "solver: {work_budget: 700}"))
    out = tmp_path / "rep.json"
    code = main(["report", str(config), "--precision", "float", "--steps",
                 "120", "--sample-every", "60", "--hardest", "2", "--host-repeats", "1",
                 "--quiet", "--json", str(out), "--build-dir", str(tmp_path / "b")])
    rep = json.loads(out.read_text())
    assert code == EXIT_VERDICT_FAILED and rep["verdicts"]["sample_time"] is False
    assert "  verdict: FAILED (sample_time) (sample_time, bit_exact)" in capsys.readouterr().out


@pytest.mark.parametrize("config", ["newuser/buck", "fast/gridinv", "fast/dcmotor_cur",
                                    "fast/boost", "fast/ups_lc", "fast/pmsm_cur"])
def test_the_auto_budget_keeps_a_small_fast_design_within_its_share(config, tmp_path):
    """Converters and current loops at 10-20 kHz (n = 3-8): their costs outside the
    solver's count and the calls around each small unit of work took the buck's worst
    step (n = 4) to 144 % of its 50 us before the budget left them out
    (STEP_FIXED_UNITS) and afford() charged them (UNIT_CALL_WORK); measured 65-89 % of
    the sample, each within its budget_share."""
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")
    path = ROOT / "tests" / "data" / f"{config}.yaml"
    share = yaml.safe_load(path.read_text())["solver"]["budget_share"]
    out = tmp_path / "rep.json"
    main(["report", str(path), "--precision", "float", "--host-repeats", "1",
          "--quiet", "--json", str(out), "--build-dir", str(tmp_path / "b")])
    rep = json.loads(out.read_text())
    assert rep["bit_exact_vs_host"] and rep["statuses"]["time_limit"] > 0  # the budget binds
    assert rep["budget"]["worst_load_percent"] <= 100 * share


def test_the_firmware_build_refuses_an_image_beyond_the_target(tmp_path):
    """The ship with target.flash_kib = 40 (generated with --force-size): the linked image
    is refused and removed; FW_FORCE_SIZE=1 keeps it with a warning."""
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    data = (NEWUSER / "ship_heading.yaml").read_text().replace(
        "target: {cpu_mhz: 72, flash_kib: 128, ram_kib: 32}",
        "target: {cpu_mhz: 72, flash_kib: 40, ram_kib: 32}").replace(
        "prefix: ship", "prefix: rollmpc")  # the stub includes rollmpc.h
    config = tmp_path / "ship.yaml"
    config.write_text(data)
    tree = tmp_path / "tree"
    assert main(["generate", str(config), "-o", str(tree), "--precision", "float",
                 "--force-size", "--no-float-check"]) == 0

    def make(*extra):
        return subprocess.run(["make", "--no-print-directory", "-f", "firmware_stub/firmware.mk",
                               "firmware", f"FW_GEN={tree}", f"FW_BUILD={tmp_path / 'fw'}",
                               *extra], cwd=ROOT, capture_output=True, text=True)

    proc = make()
    assert proc.returncode != 0
    assert re.search(r"firmware: error: flash \d+ B \(\d+\.\d KiB\) above target.flash_kib "
                     r"= 40.0 of ", proc.stderr), proc.stderr
    assert "static RAM" not in proc.stderr and not (tmp_path / "fw" / "rollctl_m4f.elf").exists()
    proc = make("FW_FORCE_SIZE=1")
    assert proc.returncode == 0 and "firmware: warning: flash" in proc.stderr
    assert (tmp_path / "fw" / "rollctl_m4f.elf").exists()
