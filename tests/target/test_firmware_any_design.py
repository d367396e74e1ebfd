"""`make firmware FW_GEN=<any tree>` builds: the generic main of firmware_stub/generic/ (one
step per sample period through a small HAL) for designs that are not the rollmpc roll
loop, host and Cortex-M4F, double and float, from examples/ and from designs that are not
there; the host build runs the design's own command; a directory that is no tree gets
one line. Every example is in the slow matrix (make check-long)."""
from __future__ import annotations

import json
import math
import re
import subprocess

import pytest

from conftest import ROOT, require_tool
from rollmpc_codegen.pipeline import generate

ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"
NEW_DESIGNS = [ROOT / "tests/data/constraints/motor_current.yaml",
               ROOT / "tests/data/newuser/buck.yaml"]
EXAMPLES = sorted((ROOT / "examples").glob("*.yaml"))


def make_firmware(tree, out, *targets):
    # FW_FORCE_SIZE: an image beyond its design's target: section links with a warning
    # (uav_roll's double tree: 471 KiB for 256; that refusal is tests/target's firmware limits)
    return subprocess.run(["make", "--no-print-directory", "-f", "firmware_stub/firmware.mk",
                           *targets, f"FW_GEN={tree}", f"FW_BUILD={out}", "FW_FORCE_SIZE=1"],
                          cwd=ROOT, capture_output=True, text=True)


def build_both(config, precision, tmp_path):
    """Generate, then the M4F image and the host program; (context, build dir)."""
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    tree, out = tmp_path / "gen", tmp_path / "fw"
    generate(config, tree, precision)
    proc = make_firmware(tree, out, "firmware", "host")
    compiler_warnings = re.findall(r":\d+:\d+: warning", proc.stderr)
    assert proc.returncode == 0 and not compiler_warnings, proc.stdout + proc.stderr
    ctx = json.loads(next(tree.glob("*_context.json")).read_text())
    return ctx, out


@pytest.mark.parametrize("precision", [pytest.param("double", marks=pytest.mark.slow), "float"])
@pytest.mark.parametrize("config", NEW_DESIGNS, ids=lambda p: p.stem)
def test_a_design_not_in_examples_builds_and_runs(config, precision, tmp_path):
    ctx, out = build_both(config, precision, tmp_path)
    prefix = ctx["prefix"]
    assert (out / f"{prefix}_fw_m4f.elf").exists()
    ny, ns, nu = (ctx[k] for k in ("n_outputs", "n_schedule", "n_actuators"))
    line = " ".join(["0"] * (ny + ns) + ["1"] * ny) + "\n"
    run = subprocess.run([str(out / f"{prefix}_fw_host")], input=line * 3, capture_output=True,
                         text=True, timeout=60)
    rows = [r.split() for r in run.stdout.splitlines()]
    assert run.returncode == 0 and len(rows) == 3 and all(len(r) == 1 + nu for r in rows)
    assert all(math.isfinite(float(v)) for r in rows for v in r[1:])
    # a status P_step returns (buck's cold double solves may hit its work budget)
    assert {int(r[0]) for r in rows} <= {s["code"] for s in ctx["statuses"] if s["step"]}


def test_a_directory_that_is_no_tree_gets_one_line(tmp_path):
    proc = make_firmware(tmp_path, tmp_path / "fw", "firmware")
    assert proc.returncode != 0 and "not a generated tree" in proc.stderr
    assert len([line for line in proc.stderr.splitlines() if "not a generated tree" in line]) == 1


@pytest.mark.slow
@pytest.mark.parametrize("precision", ["double", "float"])
@pytest.mark.parametrize("config", EXAMPLES, ids=lambda p: p.stem)
def test_every_example_builds(config, precision, tmp_path):
    build_both(config, precision, tmp_path)
