"""What ``simulate`` says about a new user's buck converter (tests/data/newuser/buck.yaml):
its metrics count the weighted outputs only (the inductor current, Q = 0, gave "settled
... max 0.333" while the voltage was within 6.6e-5 V), each output is printed with its
unit, the plot draws the output bounds, and hard bounds that fail under noise are named
with the soft-bound key (sim/run_checks.py, docs/checks.md)."""
from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from conftest import ROOT
from rollmpc_codegen.cli.simulate import print_summary, print_tracking
from rollmpc_codegen.config import parse
from rollmpc_codegen.sim.metrics import summarize, weighted_outputs
from rollmpc_codegen.sim.run_checks import infeasible_check, scenario_checks
from rollmpc_codegen.sim.simulate import ClosedLoopLog
from rollmpc_codegen.status import INFEASIBLE, OPTIMAL, TIME_LIMIT

BUCK = yaml.safe_load((ROOT / "tests" / "data" / "newuser" / "buck.yaml").read_text())
K = 400  # the buck's scenario: 4 levels of 100 samples


def buck_cfg(**mode_weights):
    data = copy.deepcopy(BUCK)
    data["modes"][0]["weights"].update(mode_weights)
    return parse(data)


def tracking_log(cfg, status=None) -> ClosedLoopLog:
    """vout within 1e-4 V of its reference, iL nowhere near the (unweighted) levels."""
    r = np.repeat([0.0, 5.0, 8.0, 3.0], K // 4)
    y = np.stack([r + 1e-4, np.full(K, 0.5)], axis=1)
    return ClosedLoopLog(t=np.arange(K) * cfg.sample_time, r=np.stack([r, r], axis=1), y=y,
                         sched=np.zeros((K, 0)), u=np.full((K, 1), 0.4), mode=np.zeros(K, int),
                         status=np.full(K, OPTIMAL) if status is None else status,
                         iterations=np.zeros(K, int), solve_us=np.zeros(K))


def test_the_settled_error_and_overshoot_count_the_weighted_outputs_only():
    cfg = buck_cfg()
    assert weighted_outputs(cfg).tolist() == [True, False]
    s = summarize(cfg, tracking_log(cfg))
    assert s["weighted_outputs"] == ["vout"]
    assert s["max_settled_error"] == pytest.approx(1e-4)
    assert s["segments"][2]["settled_error_by_output"]["iL"] == pytest.approx(7.5)
    assert max(x["overshoot"] for x in s["segments"]) == pytest.approx(1e-4)
    weighted = summarize(buck_cfg(Q=[1, 1]), tracking_log(cfg))
    assert weighted["max_settled_error"] == pytest.approx(7.5)  # both weighted: both count


def test_the_summary_prints_each_output_with_its_unit(capsys):
    cfg = buck_cfg()
    print_tracking(cfg, summarize(cfg, tracking_log(cfg)))
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("  vout [V]: settled |y - r| per segment 0.0001, 0.0001, ")
    assert lines[1].startswith("  iL [A] (Q = P = 0: not weighted, not in the max): "
                               "settled |y - r| per segment 0.5, 4.5, 7.5, 2.5")
    assert lines[2] == "  max settled |y - r| of the weighted outputs [V]: 0.0001"


def test_a_shared_unit_keeps_one_line(capsys):
    data = copy.deepcopy(BUCK)
    data["modes"][0]["weights"]["Q"] = [1, 1]
    data["units"]["outputs"] = "V"
    cfg = parse(data)
    print_tracking(cfg, summarize(cfg, tracking_log(cfg)))
    assert capsys.readouterr().out.startswith("  settled |y - r| per segment [V]: 0.5, 4.5, 7.5, "
                                              "2.5 (max 7.5)\n")


def test_the_plot_draws_every_output_bound(tmp_path):
    matplotlib = pytest.importorskip("matplotlib", reason="pip install matplotlib")
    from rollmpc_codegen.sim.figures import _pyplot, closed_loop_figure

    cfg = buck_cfg()
    fig = closed_loop_figure(_pyplot(), cfg, tracking_log(cfg))
    flat = [line.get_ydata() for line in fig.axes[0].get_lines()]
    assert any(len(d) == 2 and d[0] == d[1] == 3.0 for d in flat)  # iL <= 3 A
    assert fig.axes[0].get_ylabel() == "output y, reference r (vout V, iL A)"
    matplotlib.pyplot.close(fig)


def test_infeasible_samples_are_named_with_the_soft_bound_key():
    cfg = buck_cfg()
    status = np.full(K, OPTIMAL)
    status[100:135] = INFEASIBLE
    (found,) = infeasible_check(cfg, status, np.zeros(K, int), {"iL": 3.99})
    assert (found.code, found.key) == ("infeasible_samples", "modes[0].bounds.soft")
    assert found.message.startswith("35 of 400 samples (8.8 %) were INFEASIBLE (most in "
                                    "modes[0] ccm)")
    assert "passed them by up to iL 3.99 A" in found.message
    assert found.message.endswith("e.g. modes[0].bounds.soft: {y_max: {l1: 0, l2: 1000}} "
                                  "(docs/features.md, \"Soft output bounds\")")


def test_a_hard_bound_passed_without_infeasible_samples_is_named_too():
    cfg = buck_cfg()
    (found,) = infeasible_check(cfg, np.full(K, OPTIMAL), np.zeros(K, int), {"iL": 0.2})
    assert found.code == "hard_bound_passed" and "by up to iL 0.2 A" in found.message
    assert infeasible_check(cfg, np.full(K, OPTIMAL), np.zeros(K, int), {}) == []
    assert "Tighten the bound by that margin" in found.message


def test_a_bound_passed_where_samples_stopped_sends_to_the_unbudgeted_copy_first():
    """A DC motor's current loop, nominal, passed its 6 A bound by 61.9 A where the budget
    stopped it, and was told to tighten the bound by 61.9 A."""
    cfg = buck_cfg()
    status = np.full(K, OPTIMAL)
    status[100:130] = TIME_LIMIT
    (found,) = infeasible_check(cfg, status, np.zeros(K, int), {"iL": 10.0})
    assert "With 30 samples stopped at the work budget, first see whether the bound holds " \
        "without it" in found.message
    assert "Else tighten the bound by that margin" in found.message


def test_the_cli_prints_the_run_warnings_in_their_order(capsys):
    cfg = buck_cfg()
    status = np.full(K, OPTIMAL)
    status[:10] = INFEASIBLE
    log = tracking_log(cfg, status)
    s = summarize(cfg, log)
    found = scenario_checks(cfg, s, log.status, log.mode, [])
    ctx = {"precision": "double", "solver": {"method": "hildreth_plus_prime", "polish": True}}
    print_summary(cfg, ctx, s, found)
    out = capsys.readouterr().out
    assert [ln for ln in out.splitlines() if "warning" in ln] == [
        f"  warning: {w.message}" for w in found]
    assert [w.code for w in found] == ["infeasible_samples"]
