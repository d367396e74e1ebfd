"""`rollmpc simulate` contract: CSV columns and rows, JSON keys, the PNG, errors.

The run is shortened with --steps (the 60 s scenario's first two reference steps and the
first switches to the outer pair happen before k = 2200); timings are never asserted.
"""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from rollmpc_codegen.cli.main import main
from rollmpc_codegen.sim.metrics import (constraint_violations, reference_segments,
                                                 settled_window)
from rollmpc_codegen.sim.simulate import csv_header

from conftest import UAV

STEPS = 2200
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SUMMARY_KEYS = {"segments", "max_settled_error", "max_overshoot", "switches", "switch_times_s",
                "max_abs_u", "constraint_violations", "non_optimal", "status_counts",
                "max_iterations", "solve_us", "by_mode", "samples", "longest_time_limit_run"}
SEGMENT_KEYS = {"t_start", "t_end", "settled_window_s", "reference", "step", "settled_error",
                "overshoot", "overshoot_pct", "settling_time_s", "index"}


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory):
    pytest.importorskip("matplotlib", reason="install with: pip install 'rollmpc-codegen[plot]'")
    out = tmp_path_factory.mktemp("simulate")
    paths = {k: out / f"uav.{k}" for k in ("csv", "json", "png")}
    import contextlib
    import io

    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        rc = main(["simulate", str(UAV), "--steps", str(STEPS), "--csv", str(paths["csv"]),
                   "--json", str(paths["json"]), "--plot", str(paths["png"]),
                   "--baseline", "lqr"])
    return rc, stdout.getvalue(), stderr.getvalue(), paths


def test_exit_status_and_summary_on_stdout(sim_run):
    rc, out, err, _ = sim_run
    assert rc == 0, err
    assert "settled |y - r| per segment" in out
    assert "switches:" in out and "constraint violations: 0" in out
    assert "LQR baseline" in out
    assert "(2200/2200)" in err  # the progress bar went to stderr, to the end


def test_csv_columns_and_rows(sim_run):
    _, _, _, paths = sim_run
    with open(paths["csv"], newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["k", "t", "r", "y", "rho", "mode", "u_inner", "u_outer", "status",
                       "iterations", "solve_us", "work"]
    body = rows[1:]
    assert len(body) == STEPS
    assert [int(r[0]) for r in body] == list(range(STEPS))
    assert float(body[-1][1]) == pytest.approx((STEPS - 1) * 0.01)
    modes = {int(r[5]) for r in body}
    assert modes == {0, 1}  # the switching is in the log
    assert {int(r[8]) for r in body} == {0}  # every solve optimal
    u = np.array([[float(r[6]), float(r[7])] for r in body])
    assert np.abs(u).max() <= 15.0
    assert np.all((u[:, 0] == 0) | (u[:, 1] == 0))  # never both pairs at once


def test_json_summary_keys_and_values(sim_run):
    _, _, _, paths = sim_run
    s = json.loads(paths["json"].read_text())
    assert SUMMARY_KEYS <= set(s)
    assert s["samples"] == STEPS and s["precision"] == "double"
    assert len(s["segments"]) == 3  # 0, -20, 20 deg within 22 s
    for seg in s["segments"]:
        assert SEGMENT_KEYS <= set(seg)
    assert s["constraint_violations"]["total"] == 0
    assert s["non_optimal"] == 0
    assert s["switches"] >= 1 and len(s["switch_times_s"]) == s["switches"]
    assert set(s["max_abs_u"]) == {"inner", "outer"}
    assert {"median", "max"} == set(s["solve_us"])
    # the LQR baseline carries the same metrics
    assert SUMMARY_KEYS <= set(s["baseline"])
    assert s["baseline"]["kind"] == "lqr_saturated"
    assert s["baseline"]["constraint_violations"]["total"] == 0


def test_plot_is_a_png(sim_run):
    _, _, _, paths = sim_run
    data = paths["png"].read_bytes()
    assert data[:8] == PNG_MAGIC
    assert len(data) > 20_000  # three panels with curves, not an empty canvas


def test_float_precision_runs(tmp_path, capsys):
    out = tmp_path / "f.json"
    rc, stdout, err = run_cli(["simulate", str(UAV), "--precision", "float", "--steps", "150",
                               "--json", str(out), "--quiet"], capsys)
    assert rc == 0, err
    assert err == ""  # --quiet: no progress bar
    s = json.loads(out.read_text())
    assert s["precision"] == "float" and s["samples"] == 150


@pytest.mark.parametrize("extra, word", [
    (["--steps", "0"], "--steps"),
    (["--baseline", "pid"], "--baseline"),
    (["--precision", "half"], "--precision"),
    (["--noise", "-1"], "--noise"),
    (["--steps", "ten"], "--steps"),
])
def test_bad_arguments_one_line_exit_2(extra, word, capsys, monkeypatch):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    rc, out, err = run_cli(["simulate", str(UAV), *extra], capsys)
    assert rc == 2
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("rollmpc: error: ") and word in err, err


def test_missing_config_and_directory_target(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)
    rc, _, err = run_cli(["simulate", str(tmp_path / "nope.yaml")], capsys)
    assert rc == 2 and err.count("\n") == 1 and "cannot read" in err, err
    rc, _, err = run_cli(["simulate", str(UAV), "--csv", str(tmp_path)], capsys)
    assert rc == 2 and err.count("\n") == 1 and "--csv" in err, err


def test_csv_header_multi_output_and_no_scheduler():
    ctx = {"outputs": ["roll", "pitch"], "actuators": ["a", "b", "c"], "n_schedule": 0}
    assert csv_header(ctx) == ["k", "t", "r_roll", "r_pitch", "y_roll", "y_pitch", "mode",
                               "u_a", "u_b", "u_c", "status", "iterations", "solve_us",
                               "work"]


def test_flight_csv_without_the_work_column_still_reads(tmp_path):
    """`report --flight` reads the columns it replays: a CSV written before the ``work``
    column was added (its other columns where they were) still reads; one without a column
    it needs is refused naming it."""
    from rollmpc_codegen.config import ConfigError
    from rollmpc_codegen.target.flight_replay import read_flight_inputs

    ctx = {"outputs": ["roll"], "actuators": ["aileron"], "n_schedule": 1}
    old = [c for c in csv_header(ctx) if c != "work"]
    path = tmp_path / "old.csv"
    path.write_text(",".join(old) + "\n0,0.0,5.0,1.5,80.0,0,-2.5,0,0,1.000\n")
    inputs = read_flight_inputs(path, ctx)
    assert inputs.u[0, 0] == -2.5 and inputs.y[0, 0] == 1.5 and inputs.status[0] == 0
    path.write_text(",".join(c for c in old if c != "u_aileron") + "\n0,0.0,5.0,1.5,80.0,0,0,0,1\n")
    with pytest.raises(ConfigError, match="u_aileron"):
        read_flight_inputs(path, ctx)


def test_work_column_and_summary_agree(sim_run):
    """The CSV's ``work`` (the solver's deterministic count) and the JSON's ``work``
    statistics describe the same samples, within the config's budget; the LQR baseline
    counts none."""
    _, out, _, paths = sim_run
    with open(paths["csv"], newline="") as fh:
        work = np.array([int(r["work"]) for r in csv.DictReader(fh)])
    s = json.loads(paths["json"].read_text())
    w = s["work"]
    assert w["budget"] == s["solver"]["work_budget"] > 0
    assert w["max"] == work.max() <= w["budget"] and w["median"] == np.median(work) > 0
    assert w["median"] <= w["p99"] <= w["max"]
    assert f"solver work per sample (units): median {w['median']:,.0f}" in out
    assert "work" not in s["baseline"]


def test_segments_and_settled_window():
    r = np.repeat([0.0, -20.0, 20.0], 1000)[:, None]
    assert reference_segments(r) == [(0, 1000), (1000, 2000), (2000, 3000)]
    # 7 s .. 9 s of a 10 s segment (the last N = 100 samples anticipate the next step)
    assert settled_window(1000, 2000, last=False, horizon=100) == (1700, 1900)
    assert settled_window(2000, 3000, last=True, horizon=100) == (2700, 3000)
    assert settled_window(0, 150, last=False, horizon=100) == (105, 150)  # short segment


def test_constraint_violations_are_counted():
    from rollmpc_codegen.config import load
    from rollmpc_codegen.sim.simulate import ClosedLoopLog

    cfg = load(UAV)
    K = 4
    log = ClosedLoopLog(t=np.arange(K) * 0.01, r=np.zeros((K, 1)), y=np.zeros((K, 1)),
                        sched=np.zeros((K, 1)), u=np.zeros((K, 2)),
                        mode=np.array([0, 0, 1, 1]))
    log.u[1, 0] = 15.5  # inner beyond its limit
    log.u[2, 0] = 1.0  # the inactive inner pair moves while the outer is active
    log.y[3, 0] = -271.0  # roll angle below y_min
    cv = constraint_violations(cfg, log)
    assert {k: cv[k] for k in ("u", "inactive_actuator_nonzero", "y", "total")} == {
        "u": 1, "inactive_actuator_nonzero": 1, "y": 1, "total": 3}
    assert cv["y_max_beyond"] == {"roll": 1.0}  # 1 deg below -270


def test_overshoot_counts_the_outputs_whose_reference_steps():
    """A servo's speed swings while its position steps: the segment's overshoot is the
    position's, not the speed's excursion in other units (overshoot_by_output has both)."""
    from rollmpc_codegen.sim.metrics import _segment_metrics
    from rollmpc_codegen.sim.simulate import ClosedLoopLog

    K = 400
    r = np.zeros((K, 2))
    r[100:, 0] = 1.0  # theta steps at k = 100; omega's reference stays 0
    y = r.copy()
    y[100:, 0] += 0.05 * np.exp(-np.arange(K - 100) / 20.0)  # 0.05 past the new level
    y[100:150, 1] = 0.9  # the speed of the move
    log = ClosedLoopLog(t=np.arange(K) * 0.01, r=r, y=y, sched=np.zeros((K, 0)),
                        u=np.zeros((K, 1)))
    both = np.ones(2, bool)  # both outputs weighted
    seg = _segment_metrics(log, 100, K, True, 10, 0.01, ("theta", "omega"), both)
    assert seg["overshoot"] == pytest.approx(0.05)
    assert seg["overshoot_by_output"]["omega"] == pytest.approx(0.9)
    still = _segment_metrics(log, 0, 100, False, 10, 0.01, ("theta", "omega"), both)
    assert still["overshoot"] == 0.0  # no step: the largest excursion, none here


def test_a_closed_pipe_ends_quietly(monkeypatch, capsys):
    """`rollmpc simulate ... | head -1`: the reader leaves; the tool stops with 141 (128 +
    SIGPIPE) and no 'error: BrokenPipeError' line."""
    from rollmpc_codegen.cli import main as cli_main

    def closed(_args):
        raise BrokenPipeError(32, "Broken pipe")  # what print() raises once head has left

    args = cli_main.parser().parse_args(["simulate", str(UAV)])
    args.func = closed
    parsed = type("Parsed", (), {"parse_args": lambda self, argv: args})()
    monkeypatch.setattr(cli_main, "parser", lambda: parsed)
    assert cli_main.main(["simulate", str(UAV)]) == 141
    assert capsys.readouterr().err == ""
