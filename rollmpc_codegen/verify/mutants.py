"""The planted bugs of the mutation run (:mod:`.mutation`; docs/reliability.md, "Mutation
testing").

Each :class:`Mutant` is one plausible bug: an exact text of one file of the repository
(it must occur exactly once) and its replacement, plus the test selection that should
notice it (a few fast test files, and the byte comparison of the generated files that
the changed code renders).  The first six are the bugs of issue 15's table; the others
cover the rest of the pipeline: observer, scheduler, clamp, soft rows, Δu rows, move
blocking, status, NaN checks, run-time bounds, disturbance model, innovation limit; the
last twelve issue 49's audit (per-output limits, held commands, P_observe's applied
command, the output writer, the prefix check).

Every mutant here changes behaviour (commands, statuses or accepted arguments), so the
run requires each to be caught by a test other than ``tests/codegen/test_generated_snapshot.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

FORMULATION = "tests/qp/test_independent_formulation.py"
OBSERVERS = "templates/controller/observers.c.j2"
LIMITS = "tests/reliability/test_innovation_limit_per_output.py"
HELD = "tests/reliability/test_held_command_bounds.py"
APPLIED = "tests/reliability/test_applied_command.py"
ATOMIC = "tests/codegen/test_atomic_output.py"
SPIKES_MIMO = "tests/controller/test_innovation_limit.py::test_step_bit_exact_through_spikes_mimo"
GLUE_HOLD = "tests/glue/test_glue_core.py::test_a_held_command_is_the_active_modes_after_observe_switches"


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
    Mutant("observer gain read as L[a*nx+i] instead of L[i*ny+a]", OBSERVERS,
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
    Mutant("observer innovation sign (C x - y)", OBSERVERS,
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
    Mutant("innovation clipped at -2 limit on the lower side", OBSERVERS,
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
    # issue 49's audit: the three no behavioural test caught
    Mutant("every output clipped at output 0's innovation limit", OBSERVERS,
           "const {{ prefix }}_real limit = md->innovation_limit[a];",
           "const {{ prefix }}_real limit = md->innovation_limit[0];",
           (LIMITS, SPIKES_MIMO, *regenerated("chain_of_masses"))),
    Mutant("a held command above its range clamped to the lower bound",
           "templates/controller.c.j2",
           "held[md->actuator_index[i]] = (v < lo) ? lo : ((v > hi) ? hi : v);",
           "held[md->actuator_index[i]] = (v < lo) ? lo : ((v > hi) ? lo : v);",
           (HELD, "tests/controller/test_runtime_bounds.py", *regenerated("chain_runtime_bounds"))),
    Mutant("reference: every output clipped at output 0's innovation limit",
           "rollmpc_codegen/reference/controller.py",
           "limit = md.innovation_limit[a]", "limit = md.innovation_limit[0]",
           (LIMITS, SPIKES_MIMO)),
    # and nine more of the areas that audit went through: held commands, P_observe, the
    # applied command's plausibility, the writer of output directories, the prefix check
    Mutant("a held command keeps the other mode's actuators (not 0)", "templates/controller.c.j2",
           "held[i] = R_(0.0);", "held[i] = c->u_last[i];",
           (GLUE_HOLD, HELD, *regenerated("uav_roll"))),
    Mutant("the incoming mode keeps stale multipliers (no cold start)", "templates/controller.c.j2",
           "c->lam[j][i] = R_(0.0); /* stale multipliers of the incoming mode: cold start */",
           "c->lam[j][i] *= R_(1.0); /* mutant: the incoming mode starts warm */",
           ("tests/controller/test_scheduler_bands.py", "tests/glue/test_glue_core.py", *regenerated("uav_roll"))),
    Mutant("P_observe does not follow the scheduler", "templates/controller.c.j2",
           "    if (use_y) {\n        follow_schedule(c, sched);\n    }",
           "    if (use_y && 0) {\n        follow_schedule(c, sched);\n    }",
           ("tests/glue/test_glue_core.py", *regenerated("uav_roll"))),
    Mutant("applied command clipped one span above its range", OBSERVERS,
           "if (u[i] > hi[i]) {", "if (u[i] > hi[i] + (hi[i] - lo[i])) {",
           (APPLIED, *regenerated("uav_roll"))),
    Mutant("an applied command's clip reported only beyond two entries",
           "templates/controller.c.j2",
           "if (applied_clipped > 0) {", "if (applied_clipped > 1) {",
           (APPLIED, *regenerated("uav_roll"))),
    Mutant("run-time bounds do not widen the applied command's range", OBSERVERS,
           "hi[a] = (c->bounds[j].u_max[i] > hi[a]) ? c->bounds[j].u_max[i] : hi[a];",
           "hi[a] = (c->bounds[j].u_max[i] > hi[a]) ? hi[a] : hi[a];",
           (APPLIED, *regenerated("chain_runtime_bounds"))),
    Mutant("a failed file move is not undone", "rollmpc_codegen/codegen/output.py",
           "        _undo(out, backup, changed)\n        raise", "        raise",
           (ATOMIC, "tests/codegen/test_output_and_cache_safety.py")),
    Mutant("only the output path itself is checked for a symbolic link",
           "rollmpc_codegen/codegen/output.py",
           "        if path.is_symlink():", "        if path == out and path.is_symlink():",
           (ATOMIC, "tests/codegen/test_output_and_cache_safety.py")),
    Mutant("a prefix with a single library collision passes", "rollmpc_codegen/config/controller.py",
           "    if clash:\n", "    if len(clash) > 1:\n",
           ("tests/reliability/test_prefix_library_names.py", "tests/config/test_hostile_config.py")),
)
