"""The planted bugs of the mutation run (:mod:`.mutation`; docs/reliability.md, "Mutation
testing").

Each :class:`Mutant` is one plausible bug: an exact text of one file of the repository
(it must occur exactly once) and its replacement, plus the test selection that should
notice it (a few fast test files, and the byte comparison of the generated files that
the changed code renders).  The first six are the bugs of issue 15's table; the others
cover the rest of the pipeline: observer, scheduler, clamp, soft rows, Δu rows, move
blocking, status, NaN checks, run-time bounds, disturbance model, innovation limit.

Every mutant here changes behaviour (commands, statuses or accepted arguments), so the
run requires each to be caught by a test other than ``tests/codegen/test_generated_snapshot.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

FORMULATION = "tests/qp/test_independent_formulation.py"


def regenerated(*examples: str) -> tuple[str, ...]:
    """The test_generated_snapshot.py cases that regenerate ``examples`` in double."""
    return tuple(f"tests/codegen/test_generated_snapshot.py::test_regeneration_is_byte_identical[{e}-double-{e}]"
                 for e in examples)


@dataclass(frozen=True)
class Mutant:
    name: str  # the bug, as the table shows it
    file: str  # path from the repository root
    old: str  # exact text, present exactly once in the file
    new: str
    tests: tuple[str, ...]  # pytest arguments: files or node ids


MUTANTS = (
    # issue 15's table
    Mutant("P_set_bounds refuses u_min = 0 (accepts u_min < 0 only)",
           "templates/controller/runtime_bounds.c.j2",
           "&& u_min[i] <= R_(0.0) && u_max[i] >= R_(0.0)))",
           "&& u_min[i] < R_(0.0) && u_max[i] >= R_(0.0)))",
           (FORMULATION, "tests/controller/test_runtime_bounds.py", *regenerated("chain_runtime_bounds"))),
    Mutant("multipliers not cleared after a failed solve", "templates/solver/qp_solve.c.j2",
           "lam[i] = R_(0.0); /* no sticky warm start after a failed sample */",
           "lam[i] = lam[i] * R_(1.0); /* mutant: the warm start survives a failure */",
           (FORMULATION, "tests/solver/test_active_set.py", *regenerated("uav_roll"))),
    Mutant("observer gain read as L[a*nx+i] instead of L[i*ny+a]", "templates/controller.c.j2",
           "acc += md->L[i * md->ny + a] * ws->innov[a];",
           "acc += md->L[a * md->nx + i] * ws->innov[a];",
           (FORMULATION, "tests/controller/test_c_api_contract.py", *regenerated("uav_roll", "chain_of_masses"))),
    Mutant("reference preview shifted by one sample (r_k..r_{k+N-1})", "rollmpc_codegen/sim/scenario.py",
           "idx = np.minimum(np.arange(k + 1, k + N + 1), len(ref) - 1)",
           "idx = np.minimum(np.arange(k, k + N), len(ref) - 1)",
           (FORMULATION, "tests/controller/test_c_api_contract.py", "tests/qp/test_mimo_state_space.py")),
    Mutant("terminal weight P replaced by Q", "rollmpc_codegen/qp/condense.py",
           "Omega = _block_diag(mode.Q, N, last=mode.P)",
           "Omega = _block_diag(mode.Q, N, last=mode.Q)",
           (FORMULATION, "tests/model/test_offline_maths.py", *regenerated("uav_roll"))),
    Mutant("gradient sign flipped (F = -2 Gamma' Omega)", "rollmpc_codegen/qp/condense.py",
           "F = 2.0 * Gamma.T @ Omega", "F = -2.0 * Gamma.T @ Omega",
           (FORMULATION, "tests/controller/test_c_api_contract.py", "tests/model/test_offline_maths.py", *regenerated("uav_roll"))),
    # the rest of the pipeline
    Mutant("observer innovation sign (C x - y)", "templates/controller.c.j2",
           "ws->innov[a] = y[a] - acc;", "ws->innov[a] = acc - y[a];",
           (FORMULATION, "tests/controller/test_c_api_contract.py", *regenerated("uav_roll"))),
    Mutant("observer gain halved by the generator", "rollmpc_codegen/model/observer.py",
           "L = np.asarray(K).T", "L = 0.5 * np.asarray(K).T",
           (FORMULATION, "tests/model/test_offline_maths.py", *regenerated("uav_roll"))),
    Mutant("scheduler hysteresis lost going up (s > t - eps)", "templates/controller.c.j2",
           "&& (s > sched_above[band])) {", "&& (s > sched_below[band])) {",
           (FORMULATION, "tests/controller/test_scheduler_bands.py", *regenerated("uav_roll", "three_drives"))),
    Mutant("upper clamp dropped in finish()", "templates/solver/qp_solve.c.j2",
           "U[i] = (v < lo) ? lo : ((v > hi) ? hi : v);",
           "U[i] = (v < lo) ? lo : ((v > hi) ? v : v);",
           (FORMULATION, "tests/controller/test_c_api_contract.py", "tests/reliability/test_iteration_caps.py",
            *regenerated("uav_roll"))),
    Mutant("infeasible reported as MAX_ITER", "templates/solver/qp_solve.c.j2",
           "(i == 0) ? {{ PREFIX }}_OPTIMAL : {{ PREFIX }}_INFEASIBLE, U);",
           "(i == 0) ? {{ PREFIX }}_OPTIMAL : {{ PREFIX }}_MAX_ITER, U);",
           (FORMULATION, "tests/solver/test_active_set.py", *regenerated("uav_roll"))),
    Mutant("NaN check of the preview covers r_1 only", "templates/controller.c.j2",
           "|| !{{ prefix }}_all_finite(sched, {{ PREFIX }}_N_SCHEDULE)\n"
           "        || !{{ prefix }}_all_finite(r, {{ PREFIX }}_HORIZON * {{ PREFIX }}_N_OUTPUTS)) {",
           "|| !{{ prefix }}_all_finite(sched, {{ PREFIX }}_N_SCHEDULE)\n"
           "        || !{{ prefix }}_all_finite(r, {{ PREFIX }}_N_OUTPUTS)) {",
           ("tests/controller/test_c_api_contract.py", "tests/reliability/test_nonfinite_inputs.py", *regenerated("uav_roll"))),
    Mutant("soft slack sign in the polish ((l1 - z) w)", "templates/solver/soft_rows.c.j2",
           "return ws->slack_on[r] ? (z - l1) * w : R_(0.0);",
           "return ws->slack_on[r] ? (l1 - z) * w : R_(0.0);",
           (FORMULATION, "tests/qp/test_soft_output_bounds.py", *regenerated("chain_soft"))),
    Mutant("Δu row: u_prev enters with the wrong sign", "templates/solver/rows.c.j2",
           "g = (md->row_sign[r] > 0) ? g + up : g - up;",
           "g = (md->row_sign[r] > 0) ? g - up : g + up;",
           (FORMULATION, "tests/qp/test_input_rate_bounds.py", *regenerated("thermal_zones_rate"))),
    Mutant("Δu weight: gradient term -2 R_delta u_prev with the wrong sign",
           "rollmpc_codegen/features/input_rate.py",
           "G[:nu, nx - nu:] = -2.0 * R_delta", "G[:nu, nx - nu:] = 2.0 * R_delta",
           (FORMULATION, "tests/qp/test_input_rate_weighting.py", *regenerated("thermal_zones"))),
    Mutant("move blocking: stage -> block map of the reversed blocks",
           "rollmpc_codegen/features/move_blocking.py",
           "return np.repeat(np.arange(len(blocks)), blocks).astype(np.int32)",
           "return np.repeat(np.arange(len(blocks)), blocks[::-1]).astype(np.int32)",
           (FORMULATION, "tests/qp/test_move_blocking.py", *regenerated("uav_roll_blocked"))),
    Mutant("disturbance input target with the wrong sign",
           "rollmpc_codegen/features/disturbance_model.py",
           "Mu = sol[nx:]  # (nu, nd)", "Mu = -sol[nx:]  # (nu, nd)",
           (FORMULATION, "tests/model/test_tf_matrix_kalman_disturbance.py", *regenerated("quadruple_tank"))),
    Mutant("P_set_bounds accepts u_min = u_max", "templates/controller/runtime_bounds.c.j2",
           "&& u_min[i] < u_max[i]\n", "&& u_min[i] <= u_max[i]\n",
           (FORMULATION, "tests/controller/test_runtime_bounds.py", *regenerated("chain_runtime_bounds"))),
    Mutant("run-time lower input bound row: +u_min instead of -u_min", "templates/solver/bounds.c.j2",
           ": -b->u_min[q % md->nu];", ": b->u_min[q % md->nu];",
           (FORMULATION, "tests/controller/test_runtime_bounds.py", *regenerated("chain_runtime_bounds"))),
    # the observers' innovation limit (issue 15's huge but finite measurement)
    Mutant("innovation clipped at -2 limit on the lower side", "templates/controller.c.j2",
           "if (ws->innov[a] < -limit) {", "if (ws->innov[a] < -limit - limit) {",
           ("tests/controller/test_innovation_limit.py", *regenerated("uav_roll"))),
    Mutant("a clip reported only beyond two clipped innovations", "templates/controller.c.j2",
           "if (status == {{ PREFIX }}_OPTIMAL && clipped > 0) {",
           "if (status == {{ PREFIX }}_OPTIMAL && clipped > 2) {",
           ("tests/controller/test_innovation_limit.py", *regenerated("uav_roll"))),
    Mutant("default innovation limit from the largest value, not the span",
           "rollmpc_codegen/config/schema.py",
           "out[a] = INNOVATION_LIMIT_SPANS * (max(values) - min(values))",
           "out[a] = INNOVATION_LIMIT_SPANS * max(values)",
           ("tests/controller/test_innovation_limit.py", *regenerated("uav_roll"))),
)
