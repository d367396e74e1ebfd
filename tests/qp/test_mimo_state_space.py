"""A plain linear MPC (one mode, no scheduler) of a MIMO state-space
plant, end to end, on examples/chain_of_masses.yaml (12 states, 4 inputs, 6 outputs,
N = 10: 40 variables, 200 rows).

Generation and strict compilation in both precisions; P_step bit for bit against the
NumPy reference over the whole closed-loop scenario (200 samples, input and output bounds
active); P_solve_qp bit for bit over 48 warm-started solves (most of them saturated);
the double solutions within 1e-8 of DAQP and of the extended-precision solution
(exact_qp.solve_exact); `rollmpc simulate`, `rollmpc bench` and `rollmpc testvectors` on
the chain config; the per-output reference of `simulation.reference`.
"""
from __future__ import annotations

import contextlib
import io
import json
import subprocess

import numpy as np
import pytest
import yaml

from compile_flags import STRICT, compile_objects
from conftest import ROOT, Built, config_error
from lockstep import Lockstep
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.config import load
from rollmpc_codegen.qp.exact import qp_data, solve_exact
from rollmpc_codegen.pipeline import generate
from rollmpc_codegen.sim.scenario import preview, scenario_reference
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.status import OPTIMAL

CHAIN = ROOT / "examples" / "chain_of_masses.yaml"


@pytest.fixture(scope="module", params=["double", "float"])
def chain(request, build_root) -> Built:
    return Built(CHAIN, request.param, build_root)


@pytest.fixture(scope="module")
def chain_run(chain):
    lock = Lockstep(chain)
    log = run_closed_loop(chain.model.config, lock, info=lock.info)
    return chain, lock, log


def _saturated(U: np.ndarray, md) -> bool:
    lo, hi = np.tile(md.u_min, md.N), np.tile(md.u_max, md.N)
    return bool(np.any((U == lo) | (U == hi)))


def test_config_is_one_mode_mimo_state_space():
    cfg = load(CHAIN)
    assert cfg.scheduler is None and cfg.n_schedule == 0 and len(cfg.modes) == 1
    mode = cfg.modes[0]
    assert mode.plant.kind == "state_space" and not mode.plant.discrete
    assert (mode.plant.A.shape, mode.plant.B.shape, mode.plant.C.shape) == ((12, 12), (12, 4),
                                                                              (6, 12))
    ref = scenario_reference(cfg)
    assert ref.shape == (200, 6)
    assert np.array_equal(ref[120], [0.4, 0.2, 0.0, 0.0, -0.2, -0.4])  # a per-output level
    assert np.all(ref[40] == 0.5)  # a scalar level applies to every output


@pytest.mark.parametrize("precision", ["double", "float"])
def test_generates_and_compiles_strict(tmp_path, precision):
    _, ctx = generate(CHAIN, tmp_path / "chain", precision)
    assert ctx["n_schedule"] == 0 and ctx["n_outputs"] == 6 and ctx["n_actuators"] == 4
    proc = compile_objects("gcc", tmp_path / "chain", ["-O2", "-ffp-contract=off", *STRICT],
                           tmp_path / "obj")
    assert proc.returncode == 0 and not proc.stderr.strip(), proc.stderr


def test_step_bit_exact_over_closed_loop(chain_run):
    chain, lock, log = chain_run
    assert len(log.t) == 200
    assert lock.mismatches == [], f"{len(lock.mismatches)} mismatching steps, first: " \
                                  f"{lock.mismatches[0]}"
    assert np.all(log.status == OPTIMAL)
    mode = chain.model.config.modes[0]
    # the scenario drives inputs and outputs onto their bounds, never beyond
    assert np.any(np.abs(log.u) == 0.5) and np.all(np.abs(log.u) <= 0.5)
    # the plant meets the output bounds up to the solver's feasibility tolerance
    tol = 1e-9 if chain.ctx["precision"] == "double" else 1e-4
    assert np.abs(log.y).max() > 0.59
    assert np.all(log.y <= mode.y_max + tol) and np.all(log.y >= mode.y_min - tol)
    # tracking: settles near each level before the preview sees the next step (an offset
    # from the input weight remains: no integral action)
    for k in (75, 105, 155):
        assert np.abs(log.y[k - 5:k] - log.r[k - 5:k]).max() < 0.1, k


@pytest.fixture(scope="module")
def qp_cases(chain_run):
    chain, lock, log = chain_run
    rng = np.random.default_rng(5)
    N, ny = chain.ctx["horizon"], chain.ctx["n_outputs"]
    ref = scenario_reference(chain.model.config)
    ks = rng.choice(len(lock.states), 24, replace=False)
    cases = []
    for k in sorted(ks):
        _, x, kk = lock.states[k]
        r = preview(ref, kk, N, ny)
        cases.append((x, r))
        cases.append((x, r + rng.uniform(-0.8, 0.8, r.shape)))  # saturating references
    c = chain.fresh_c()
    solver = SolverRef(chain.model.modes[0].data, chain.ctx["solver"])
    results = []
    for x, r in cases:  # one warm start carried over in both, in the same order
        r = r.astype(x.dtype)
        st_c, U_c, its_c = c.solve_qp(0, x, r)
        st_r, U_r, its_r, _, _ = solver.solve_mode(x, r)
        results.append((x, r, st_c, U_c, its_c, st_r, U_r, its_r))
    return chain, results


def test_solve_qp_bit_exact_including_saturated(qp_cases):
    chain, results = qp_cases
    md = chain.model.modes[0].data
    assert len(results) == 48
    assert sum(_saturated(res[3], md) for res in results) >= 24
    bad = [(i, res[2], res[5], res[4], res[7]) for i, res in enumerate(results)
           if res[2] != res[5] or res[3].tobytes() != res[6].tobytes() or res[4] != res[7]]
    assert bad == []


def test_double_matches_independent_solvers(qp_cases):
    chain, results = qp_cases
    if chain.ctx["precision"] != "double":
        pytest.skip("the independent check is a double-precision property")
    daqp = pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    qp = chain.model.modes[0].qp
    worst_daqp = worst_exact = 0.0
    for x, r, st_c, U_c, *_ in results:
        assert st_c == OPTIMAL
        f = qp.F @ (qp.Phi @ x - r)
        b = qp.c + qp.W @ x
        U_d, _, flag, _ = daqp.solve(qp.E, f, qp.L, b, np.full_like(b, -1e30),
                                     np.zeros(b.size, dtype=np.intc))
        assert flag == 1
        exact = solve_exact(qp_data(qp, x, r))
        worst_daqp = max(worst_daqp, np.abs(U_c - U_d).max())
        worst_exact = max(worst_exact, np.abs(U_c - np.asarray(exact.U, float)).max())
    assert worst_daqp <= 1e-8, worst_daqp
    assert worst_exact <= 1e-8, worst_exact


def _cli(args: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(args)
    return rc, out.getvalue(), err.getvalue()


def test_simulate_cli_on_chain(tmp_path):
    rc, out, err = _cli(["simulate", str(CHAIN), "--quiet", "--json", str(tmp_path / "s.json"),
                         "--csv", str(tmp_path / "s.csv")])
    assert rc == 0, err
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["samples"] == 200 and summary["switches"] == 0
    assert len(summary["segments"]) == 5
    assert summary["constraint_violations"]["total"] == 0 and summary["non_optimal"] == 0
    header = (tmp_path / "s.csv").read_text().splitlines()[0].split(",")
    assert "rho" not in header and "r_p6" in header and "y_p1" in header and "u_f6" in header


def test_bench_cli_on_chain(tmp_path):
    pytest.importorskip("quadprog", reason="install with: pip install 'rollmpc-codegen[peers]'")
    pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    rc, out, err = _cli(["bench", str(CHAIN), "--quiet", "--max-qps", "40",
                         "--variants", "default,daqp", "--json", str(tmp_path / "b.json")])
    assert rc == 0, err
    result = json.loads((tmp_path / "b.json").read_text())
    assert result["qps"] == 40 and result["qps_by_mode"] == {"chain": 40}
    rows = {r["key"]: r for r in result["rows"]}
    assert set(rows) == {"default", "quadprog", "daqp"}
    assert rows["default"]["optimal"] == 40
    assert rows["default"]["max_abs_err"] <= 1e-8  # first move vs quadprog
    assert result["replay_max_abs_diff_vs_closed_loop"] <= 1e-12


def test_test_vectors_default_to_the_whole_scenario(tmp_path):
    """Without --steps the program records the config's scenario, not a fixed 6000 (which
    held a 1000-sample scenario's last reference for 5000 more); --steps 0 is refused."""
    from rollmpc_codegen.config import load
    from rollmpc_codegen.sim.scenario import scenario_reference

    out = tmp_path / "tv"
    assert main(["testvectors", str(CHAIN), "--precision", "float", "-o", str(out)]) == 0
    source = next(out.glob("*_test_vectors.c")).read_text()
    assert f"#define STEPS {len(scenario_reference(load(CHAIN)))}\n" in source
    assert main(["testvectors", str(CHAIN), "-o", str(tmp_path / "none"), "--steps", "0"]) == 2
    assert not (tmp_path / "none").exists()


def test_host_c_test_program_passes_on_chain(tmp_path):
    out = tmp_path / "tv"
    assert main(["testvectors", str(CHAIN), "--precision", "float", "-o", str(out),
                 "--steps", "80"]) == 0
    exe = out / "test_vectors"
    proc = subprocess.run(["gcc", "-O2", "-ffp-contract=off", *STRICT, f"-I{out}",
                           *map(str, sorted(out.glob("*.c"))), "-lm", "-o", str(exe)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True)
    assert run.returncode == 0 and " 0 failed" in run.stdout, run.stdout


@pytest.mark.parametrize("levels, key", [
    ([0.0, [0.1, 0.2]], "simulation.reference.levels[1]"),
    ([], "simulation.reference.levels"),
])
def test_reference_errors_name_the_key(tmp_path, levels, key):
    data = yaml.safe_load(CHAIN.read_text())
    data["simulation"]["reference"]["levels"] = levels
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    err = config_error(path)
    assert err.key == key
