"""rollmpc report compares the whole controller instance with the host's after every step,
and builds the host with the target's kernels (P_WIDE_KERNELS: wide on the M4F's FPU).

tests/data/kernels/repeated_rows.yaml breaks its dual factor down at step 149 of its
scenario with noise: the wide kernels leave other partial rows in work.chol than the
plain ones, so a host build with the plain kernels (the host compiler's own choice)
agrees on every command but not on the instance."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from conftest import require_tool

ROWS = Path(__file__).resolve().parents[1] / "data" / "kernels" / "repeated_rows.yaml"
ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"
STEPS, NOISE = 150, 0.01  # step 149: the breakdown


@pytest.fixture
def target_tools():
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")


def test_report_instance_is_bit_exact_with_the_targets_kernels(target_tools, build_root):
    """Fails when the report's host build runs the plain kernels: the last step's
    instance differs in work.chol (the commands still agree)."""
    from rollmpc_codegen.cli.report import bit_exact_text
    from rollmpc_codegen.target.report import run_report

    rep = run_report(ROWS, precision="float", noise_std=NOISE, steps=STEPS, hardest=2,
                     sample_every=50, host_repeats=1, build_dir=build_root)
    assert rep["kernels"] == "wide" and rep["mismatches"] == 0
    assert rep["state_bit_exact"] is True and rep["state_mismatch"] is None
    assert rep["bit_exact_vs_host"] is True
    assert bit_exact_text(rep).startswith("yes (commands and instance, every step; wide")


def test_every_steps_instance_is_compared_member_by_member(target_tools, build_root):
    """With the plain kernels on the host the instance differs from step 149 in work.chol
    only, and a planted difference in an earlier step's record is found at its step."""
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.target.build import build_target
    from rollmpc_codegen.target.replay import record_host_run, replay_on_target
    from rollmpc_codegen.target.build import target_layout

    model, ctx = load_model(ROWS, "float")
    build = build_target(ctx, build_root)
    layout = target_layout(build, ctx)
    assert layout.wide_kernels and "work.chol" in [m[0] for m in layout.members]
    plain = dataclasses.replace(layout, wide_kernels=False)
    options = {"noise_std": NOISE, "seed": 0}
    record = record_host_run(model, ctx, build_root, STEPS, loop_options=options,
                             layout=plain)
    run = replay_on_target(build, ctx, record, set())
    assert run.mismatches == []  # the commands, statuses and diagnostics agree
    assert run.state_steps and run.state_steps[0] == 149 and run.state_members == ["work.chol"]
    assert run.state_mismatch() == {"step": 149, "members": ["work.chol"], "steps": 1}

    record = record_host_run(model, ctx, build_root, STEPS, loop_options=options,
                             layout=layout)
    assert replay_on_target(build, ctx, record, set()).state_steps == []
    k, xhat = 40, [i for i, m in enumerate(layout.members) if m[0] == "xhat"][0]
    record.states[k] = tuple(b"planted!" if i == xhat else d
                             for i, d in enumerate(record.states[k]))
    run = replay_on_target(build, ctx, record, set())
    assert run.state_steps == [k] and run.state_members == ["xhat"] and not run.state_equal
