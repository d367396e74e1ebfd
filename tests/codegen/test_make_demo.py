"""``make demo`` generates and simulates the paper's controller only (it regenerated all
24 example trees: 2 m 44 s on a fresh clone); ``make generate`` stays the full
regeneration.  Read from ``make -n`` (nothing runs)."""
from __future__ import annotations

import re
import subprocess

from conftest import ROOT, require_tool


def dry_run(target: str) -> list[str]:
    require_tool("make", "apt-get install -y make")
    proc = subprocess.run(["make", "-n", "--no-print-directory", target, "VENV=.venv"],
                          cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.splitlines()


def test_demo_generates_the_paper_controller_in_both_precisions_only():
    generated = [ln for ln in dry_run("demo") if " generate " in ln]
    assert [re.search(r"-o (\S+)", ln).group(1) for ln in generated] == [
        "generated/uav_roll", "generated/uav_roll_f32"]
    assert any(" simulate examples/uav_roll.yaml " in ln for ln in dry_run("demo"))


def test_generate_still_regenerates_every_example():
    text = "\n".join(dry_run("generate"))
    assert "for ex in" in text and "quad_attitude" in text
