"""Shared fixtures: the paper's controller in both precisions, built once per session."""
from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import pytest

# one BLAS thread (as `make test` sets): the QPs are small and threaded OpenBLAS is ~10x
# slower on the 2-core machines under load; effective when numpy is not imported yet
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
import rollmpc_codegen  # noqa: E402,F401  pins OpenBLAS's kernels before NumPy loads

ROOT = Path(__file__).resolve().parents[1]
UAV = ROOT / "examples" / "uav_roll.yaml"

# a design of our own (not among examples/): the UAV's inner loop alone, roll kept within
# 45 deg; its soft form (ROLL45_SOFT on both bounds) meets the polish's capped guesses
ROLL45 = {
    "prefix": "roll45", "sample_time": 0.01, "horizon": 60, "outputs": ["roll"],
    "actuators": ["ail"],
    "modes": [{"name": "only",
               "plant": {"transfer_function": {"num": [-74.15, 8892],
                                               "den": [1, 59.11, 1599, 7936]},
                         "integrator": True},
               "weights": {"Q": 10, "R": 1, "P": 1000},
               "bounds": {"u_min": -15, "u_max": 15, "y_min": -45, "y_max": 45}}],
    "units": {"outputs": "deg", "actuators": "deg"},
    "simulation": {"reference": {"segment": 6.0, "levels": [0, 60, 0]}},
}
ROLL45_SOFT = {"y_max": {"l1": 1000, "l2": 100}, "y_min": {"l1": 1000, "l2": 100}}


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", help="run the long (slow) tests")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="long run: use make check-long (pytest --runslow -m slow)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def require_tool(name: str, install: str) -> str:
    """Path of a command-line tool, or skip saying how to install it."""
    path = shutil.which(name)
    if path is None:
        pytest.skip(f"{name} not found; install with: {install}")
    return path


@pytest.fixture(scope="session", autouse=True)
def build_root(tmp_path_factory) -> Path:
    """The session's build cache, also the default root of every build the tests make in
    process or through the CLI (its $XDG_CACHE_HOME): the user's own cache is never
    written, and a tree built twice is compiled once (the cache is keyed by content)."""
    from rollmpc_codegen.host.build_cache import private_root

    os.environ["XDG_CACHE_HOME"] = str(tmp_path_factory.mktemp("cache"))
    return private_root(None)


class Built:
    """Model, context and compiled C of one configuration (``extra``: more C flags)."""

    def __init__(self, config: Path, precision: str, build_root: Path,
                 extra: tuple[str, ...] = ()):
        from rollmpc_codegen.pipeline import load_model

        self.model, self.ctx = load_model(config, precision)
        self.build_root, self.extra = build_root, extra
        self._library = (None, None)  # (the ctx it was built from, the library)
        self.c = self.fresh_c()

    def fresh_c(self):
        """A second, independent controller instance (its own P_ctrl) from the same library,
        rendered and compiled once for the current ctx, as build_host_controller would."""
        from rollmpc_codegen.codegen.render import render_sources
        from rollmpc_codegen.host.build import HostController, compile_shared
        from rollmpc_codegen.host.build_cache import private_root, source_dir

        built_for, lib = self._library
        if built_for is not self.ctx:
            root = private_root(self.build_root)
            files = render_sources(self.ctx)
            digest = hashlib.sha256("".join(files[k] for k in sorted(files)).encode())
            src = source_dir(root, f"src-{self.ctx['prefix']}-{digest.hexdigest()[:16]}", files)
            lib = compile_shared(self.ctx, src, root, extra=self.extra)
            self._library = (self.ctx, lib)
        return HostController.load(self.ctx, lib)

    def reference(self):
        from rollmpc_codegen.reference.controller import ControllerRef

        return ControllerRef(self.ctx, [m.data for m in self.model.modes])


@pytest.fixture(scope="session", params=["double", "float"])
def uav(request, build_root) -> Built:
    return Built(UAV, request.param, build_root)


@pytest.fixture(scope="session")
def uav_double(build_root) -> Built:
    return Built(UAV, "double", build_root)


@pytest.fixture(scope="session")
def partial_run(build_root, tmp_path_factory):
    """Design name (partial_runs.DESIGNS) -> (mismatches, statuses, calls) of its float
    lockstep closed loop, run once a session."""
    from partial_runs import DESIGNS, counted_lockstep

    runs = {}

    def run(name: str):
        if name not in runs:
            write, steps = DESIGNS[name]
            built = Built(write(tmp_path_factory.mktemp(name)), "float", build_root)
            runs[name] = counted_lockstep(built, steps)
        return runs[name]
    return run


def edited_config(tmp_path: Path, base: Path, name: str, edit) -> Path:
    """The config ``base`` with ``edit(data)`` applied, written to tmp_path/<name>.yaml."""
    import yaml

    data = yaml.safe_load(Path(base).read_text())
    edit(data)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def edit_bounds(**bounds):
    """An ``edited_config`` edit: update every mode's ``bounds`` with ``bounds``."""
    def edit(data):
        for m in data["modes"]:
            m["bounds"].update(bounds)
    return edit


def config_error(path_or_data, loader=None):
    """The ConfigError that ``loader`` (default: config.load) raises on ``path_or_data``;
    the test fails if none is raised."""
    from rollmpc_codegen.config import ConfigError, load

    with pytest.raises(ConfigError) as exc:
        (loader or load)(path_or_data)
    return exc.value


def variant_config(tmp_path: Path, name: str = "variant", **solver) -> Path:
    """examples/uav_roll.yaml with solver settings overridden, written to tmp_path. Without
    the polish the example's work_budget (sized from the polish's cycles per unit) is
    dropped unless given: the paper's sweeps have no budget, max_iterations caps them."""
    def edit(data):
        base = dict(data.get("solver", {}))
        if solver.get("polish") is False and "work_budget" not in solver:
            base.pop("work_budget", None)
        data["solver"] = {**base, **solver}
    return edited_config(tmp_path, UAV, name, edit)


def short_uav_config(tmp_path: Path, horizon: int = 20, name: str = "uav_short", **solver) -> Path:
    """The UAV config with a shorter horizon: same plants and templates, small data (fast builds)."""
    import yaml

    path = variant_config(tmp_path, name, **solver)
    data = yaml.safe_load(path.read_text())
    data["horizon"] = horizon
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def reference_closed_loop(built: Built, ref, steps: int) -> list:
    """The scenario's closed loop driven by the reference controller ``ref`` (a
    ``built.reference()``, possibly with recording wrappers): (status, work) of every step."""
    from rollmpc_codegen.sim.simulate import run_closed_loop

    seen = []

    class Reference:
        def step(self, y, s, r):
            out = ref.step(y, s, r)
            seen.append((int(out[0]), ref.last["work"]))
            return out

    run_closed_loop(built.model.config, Reference(), steps=steps)
    return seen


def lockstep_closed_loop(built: Built, steps: int, ref=None, **loop_options) -> tuple[list, list]:
    """The scenario's closed loop (or a flight's: ``loop_options``, as
    FlightPlan.loop_options() gives them) driven by a fresh host C controller, the reference
    (``ref``, possibly with recording wrappers, or a new one) stepped beside it on the same
    inputs: (mismatches as (step, C's, reference's), and (status, work) of every step). A
    step matches when its status, command bytes, sweeps, polish corrections, active rows
    and work are the same."""
    from rollmpc_codegen.sim.simulate import run_closed_loop

    c, ref = built.fresh_c(), ref or built.reference()
    keys = ("iterations", "polish_iterations", "active", "work")
    seen, bad = [], []

    class Lockstep:
        def step(self, y, s, r):
            st_c, u_c = c.step(y, s, r)
            st_r, u_r = ref.step(y, s, r)
            info = c.info()
            mine = (st_c, u_c.tobytes(), *(info[k] for k in keys))
            theirs = (st_r, u_r.tobytes(), *(ref.last[k] for k in keys))
            if mine != theirs:
                bad.append((len(seen), mine, theirs))
            seen.append((st_c, info["work"]))
            return st_c, u_c

    run_closed_loop(built.model.config, Lockstep(), steps=steps, **loop_options)
    return bad, seen


def sampled_qps_against_independent_solvers(built: Built, states: list, reference, bound: float,
                                            perturb: float, seed: int, count: int = 12):
    """One-mode check on ``count`` states of a lockstep run (``Lockstep.states``), each with
    the scenario's preview and a randomly perturbed one: ``P_solve_qp`` bit for bit against
    the reference solver, both optimal; returns (QPs with an input at +-``bound``, worst
    max |U - U_daqp|, worst max |U - U_exact|), the independent solutions from
    ``exact_qp.qp_data`` (CondensedQP.gradient) by DAQP and ``exact_qp.solve_exact``."""
    import numpy as np

    daqp = pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    from rollmpc_codegen.qp.exact import qp_data, solve_exact
    from rollmpc_codegen.sim.scenario import preview
    from rollmpc_codegen.reference.solver import SolverRef
    from rollmpc_codegen.status import OPTIMAL

    qp, ny = built.model.modes[0].qp, built.ctx["n_outputs"]
    rng = np.random.default_rng(seed)
    c = built.fresh_c()
    solver = SolverRef(built.model.modes[0].data, built.ctx["solver"])
    saturated, worst_daqp, worst_exact = 0, 0.0, 0.0
    for k in sorted(rng.choice(len(states), count, replace=False)):
        _, x, kk = states[k]
        r0 = preview(reference, kk, qp.N, ny)
        for r in (r0, r0 + rng.uniform(-perturb, perturb, r0.size)):
            st_c, U_c, _ = c.solve_qp(0, x, r)
            st_r, U_r, _, _, _ = solver.solve_mode(x, r)
            assert st_c == st_r == OPTIMAL and U_c.tobytes() == U_r.tobytes()
            saturated += bool(np.any(np.abs(U_c) == bound))
            data = qp_data(qp, x, r)
            m = data.b.size  # with soft rows: the QP with explicit slacks, U first
            U_d, _, flag, _ = daqp.solve(data.E, data.f.astype(float), data.L,
                                         data.b.astype(float), np.full(m, -1e30),
                                         np.zeros(m, dtype=np.intc))
            U_d = U_d[:qp.n]
            exact = solve_exact(data)
            assert flag == 1 and exact.status == "optimal"
            worst_daqp = max(worst_daqp, float(np.abs(U_c - U_d).max()))
            worst_exact = max(worst_exact, float(np.abs(U_c - exact.U).max()))
    return saturated, worst_daqp, worst_exact


def cli(args: list[str]) -> tuple[int, str, str]:
    """``rollmpc <args>`` in-process: (exit status, stdout, stderr)."""
    import contextlib
    import io

    from rollmpc_codegen.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(args)
    return rc, out.getvalue(), err.getvalue()


def simulate_and_bench(config: Path, tmp_path: Path, *simulate_args: str):
    """``rollmpc simulate`` (JSON summary) then ``rollmpc bench --max-qps 40 --variants
    default,daqp``; returns (summary, simulate's stdout, bench rows by key)."""
    import json

    rc, out, err = cli(["simulate", str(config), "--quiet", *simulate_args, "--json",
                        str(tmp_path / "s.json")])
    assert rc == 0, err
    summary = json.loads((tmp_path / "s.json").read_text())
    pytest.importorskip("quadprog", reason="install with: pip install 'rollmpc-codegen[peers]'")
    pytest.importorskip("daqp", reason="install with: pip install 'rollmpc-codegen[peers]'")
    rc, _, err = cli(["bench", str(config), "--quiet", "--max-qps", "40", "--variants",
                      "default,daqp", "--json", str(tmp_path / "b.json")])
    assert rc == 0, err
    rows = {r["key"]: r for r in json.loads((tmp_path / "b.json").read_text())["rows"]}
    return summary, out, rows
