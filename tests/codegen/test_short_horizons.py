"""Horizons of 1 and 2: the generated C of the paper's controller and of a MIMO one with
output and Δu rows (fw_lateral) compiles warning-free under the strict and autopilot flags
with gcc and clang at -O2 and -O3 (array-bounds warnings depend on the optimisation), and
runs bit for bit with the reference with every array index checked (-fsanitize=bounds).

A horizon of 1 failed -Werror=array-bounds (gcc cannot see that the working set stays
within its capacity of 1), and the dual active set ranked up to ADD_BATCH violated rows
into a list of the capacity's length: at horizons of 1 and 2 that overflowed at run time
(qp/sizes.py, working_set_lengths())."""
from __future__ import annotations

import numpy as np
import pytest

from compile_flags import AUTOPILOT, CLANG_HINT, STRICT, compile_objects
from conftest import ROOT, UAV, Built, edited_config, require_tool
from lockstep import Lockstep
from rollmpc_codegen.pipeline import generate
from rollmpc_codegen.reference.solver import SolverRef
from rollmpc_codegen.sim.simulate import run_closed_loop
from rollmpc_codegen.status import OPTIMAL

FW_LATERAL = ROOT / "examples" / "fw_lateral.yaml"
# (config, horizon, precision): each horizon of each config in one precision, the other
# precision for the other horizon
CASES = [(UAV, 1, "double"), (UAV, 2, "float"), (FW_LATERAL, 1, "float"),
         (FW_LATERAL, 2, "double")]
BOUNDS_CHECKED = ("-fsanitize=bounds",)  # a report goes to stderr and the run goes on
STEPS = 1000  # closed-loop samples run in lockstep with the reference


def _params(slow_from: int | None = None) -> list:
    """CASES as parameters; horizons from ``slow_from`` on in the long run only."""
    return [pytest.param(case, id=f"{case[0].stem}-N{case[1]}-{case[2]}",
                         marks=pytest.mark.slow if slow_from and case[1] >= slow_from else ())
            for case in CASES]


@pytest.fixture(scope="module")
def short(request, tmp_path_factory):
    """(config with the horizon edited, precision, its generated sources)."""
    base, horizon, precision = request.param
    tmp = tmp_path_factory.mktemp(f"{base.stem}_N{horizon}")
    config = edited_config(tmp, base, f"{base.stem}_N{horizon}",
                           lambda data: data.update(horizon=horizon))
    generate(config, tmp / "src", precision)
    return config, precision, tmp / "src"


# horizon 1 by default (the analysis failed only there: a 1-element working set); about
# a second per compile of a tree
@pytest.mark.parametrize("short", _params(slow_from=2), indirect=True)
@pytest.mark.parametrize("cc, opt", [pytest.param("gcc", "-O2", marks=pytest.mark.slow),
                                     ("gcc", "-O3"),
                                     pytest.param("clang", "-O2", marks=pytest.mark.slow),
                                     ("clang", "-O3")])
def test_strict_compile_no_warnings(short, tmp_path, cc, opt):
    _, _, src = short
    if cc == "clang":
        cc = require_tool("clang", CLANG_HINT)
    proc = compile_objects(cc, src, [opt, *STRICT, *AUTOPILOT], tmp_path)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


@pytest.mark.parametrize("short", _params(), indirect=True)
def test_bit_exact_with_bounds_checked(short, build_root, capfd):
    """A closed loop in lockstep, then cold QPs from states and references far outside
    the bounds (many rows violated at once: the batch the dual active set ranks)."""
    config, precision, _ = short
    built = Built(config, precision, build_root, extra=BOUNDS_CHECKED)
    lock = Lockstep(built)
    log = run_closed_loop(built.model.config, lock, info=lock.info, steps=STEPS)
    assert lock.mismatches == [], lock.mismatches[:1]
    assert np.any(log.status == OPTIMAL)
    rng = np.random.default_rng(0)
    c, N, ny = built.fresh_c(), built.ctx["horizon"], built.ctx["n_outputs"]
    statuses = set()
    for j, mode in enumerate(built.model.modes):
        ref = SolverRef(mode.data, built.ctx["solver"])
        for scale in (1.0, 10.0, 100.0):
            for _ in range(5):
                x, r = rng.normal(size=mode.data.nx) * scale, rng.normal(size=N * ny) * scale
                st_c, U_c, _ = c.solve_qp(j, x, r)
                st_r, U_r, *_ = ref.solve_mode(x, r)
                assert st_c == st_r and U_c.tobytes() == U_r.tobytes(), (j, scale)
                statuses.add(st_c)
    assert OPTIMAL in statuses
    err = capfd.readouterr().err
    assert "runtime error" not in err, err[-3000:]
