"""The status codes of the generated C, each declared once.

Each :class:`Status` carries its code, the ``P_status_message()`` text, what it means,
what the command holds after it and whether that command is the optimal plan's.  From
these, :mod:`.codegen.context` passes the list on to the templates, which render the C enum
and the ``P_STATUS_PLAN_USABLE()`` test (``api.h.j2``) and the message table
(``controller.c.j2``).  The NumPy reference returns the same codes.  The README's status
table repeats the texts, and tests/controller/test_status_codes.py keeps it in step.
"""
from __future__ import annotations

from enum import IntEnum

UNKNOWN_MESSAGE = "unknown status"  # P_status_message() of any other code


class Status(IntEnum):
    """Return codes of P_step(), P_solve_qp() and P_set_bounds(); 0 is optimal."""

    def __new__(cls, code: int, message: str, meaning: str, command: str,
                runtime_bounds_only: bool = False, plan_usable: bool = False):
        status = int.__new__(cls, code)
        status._value_ = code
        status.message, status.meaning, status.command = message, meaning, command
        status.runtime_bounds_only = runtime_bounds_only  # P_set_bounds() only
        # the command is the optimal plan's first move: a glue flies it, not its fallback
        status.plan_usable = plan_usable
        return status

    OPTIMAL = (0, "optimal", "KKT conditions hold within the feasibility tolerance",
               "the solution", False, True)
    MAX_ITER = (1, "iteration cap reached", "the sweep cap was hit",
                "best estimate, clamped to the limits")
    INACCURATE = (2, "converged by delta but constraints violated",
                  "stopped by the δ test with rows still violated", "best estimate, clamped")
    # the dual active set proves it (add_to_set(): a dependent row and none can leave, Farkas);
    # the sweeps only see their multipliers pass P_LAMBDA_LIMIT
    INFEASIBLE = (3, "infeasible: constraints cannot all hold (proven, or multipliers diverged)",
                  "the dual active set proved that the constraints cannot all hold (a violated "
                  "row that depends on the working set, which no row can leave), or the sweeps' "
                  "multipliers diverged", "the unconstrained optimum (active set) or the best "
                  "estimate (sweeps), clamped")
    NONFINITE_INPUT = (4, "non-finite input; last command held",
                       "NaN/Inf in `y`, `sched`, `r` (or `x`)",
                       "last command held, made the active mode's: its actuators clamped "
                       "into its input bounds, the others 0 (`P_observe` may have switched the "
                       "mode since) (`P_solve_qp`: 0)")
    NUMERICAL = (5, "non-finite intermediate result; safe fallback", "a non-finite intermediate",
                 "clamped unconstrained solution, else 0")
    BAD_ARGUMENT = (6, "bad argument", "NULL pointer or bad mode index",
                    "last command held, as for status 4")
    BAD_BOUNDS = (7, "bad bounds; nothing changed", "`P_set_bounds` only: NaN, a non-finite "
                  "configured bound, lower >= upper, or input bounds without 0", "nothing changed",
                  True)
    BOUND_NOT_CONFIGURED = (8, "bound not in the config (no constraint rows); nothing changed",
                            "`P_set_bounds` only: a finite value for an output bound the config "
                            "left infinite (no rows)", "nothing changed", True)
    # appended (the codes above keep their values); docs/solver.md, "Work budget"
    TIME_LIMIT = (9, "work budget reached; best command so far",
                  "the solve reached `solver.work_budget` (`P_last_info()->work`) before the "
                  "KKT conditions held; the next sample continues from the working set it "
                  "reached", "the last point of the dual active set (or of the sweeps); "
                  "before it has one, the point of the last primal polish in a mode whose rows "
                  "are all input bounds, else the mode's last plan shifted one stage (while "
                  "younger than the horizon), else the unconstrained optimum; clamped")
    # the observer's plausibility check (docs/features.md, "Measurement plausibility")
    # reports only when the solve was OPTIMAL: any solver status above wins
    MEASUREMENT_CLIPPED = (10, "optimal; an implausible measurement was clipped",
                           "the solve was optimal, and an innovation y − C x̂ of this sample was "
                           "beyond ±`observer.innovation_limit` and was clipped to it "
                           "(`P_last_info()->clipped` counts the clips whatever the status)",
                           "the solution (this sample's y enters only the next one)", False, True)
    # P_observe's plausibility check of the applied command (docs/reliability.md, "Run time:
    # one hostile sample of every input"): beyond its actuator's range it was not applied
    APPLIED_CLIPPED = (11, "an applied command beyond its actuator's range was clipped",
                       "`P_observe` only: an entry of `u_applied` was beyond the range of "
                       "its actuator (the lowest `u_min` to the highest `u_max` of the modes "
                       "that drive it) and was clipped to that range before the observers "
                       "used it; it wins over `MEASUREMENT_CLIPPED`",
                       "none (`P_observe` solves nothing)")


# the codes as module names, for the reference's and the tests' comparisons
(OPTIMAL, MAX_ITER, INACCURATE, INFEASIBLE, NONFINITE_INPUT, NUMERICAL, BAD_ARGUMENT, BAD_BOUNDS,
 BOUND_NOT_CONFIGURED, TIME_LIMIT, MEASUREMENT_CLIPPED, APPLIED_CLIPPED) = Status

# every build's codes (the runtime_bounds ones exist only in a runtime build) -> short name;
# P_step() returns these
STATUS_NAMES = {s: s.name.lower() for s in Status if not s.runtime_bounds_only}


def context_statuses(prefix: str, runtime_bounds: bool) -> list[dict]:
    """The codes of one build for the templates (``P_`` becomes the prefix)."""
    return [{"name": s.name, "code": int(s), "message": s.message, "plan_usable": s.plan_usable,
             "step": not s.runtime_bounds_only,
             "meaning": s.meaning.replace("P_", f"{prefix}_"),
             "command": s.command.replace("P_", f"{prefix}_"),
             "doc": f"{s.meaning[0].upper()}{s.meaning[1:]}. Command: {s.command}."
             .replace("P_", f"{prefix}_")}
            for s in Status if runtime_bounds or not s.runtime_bounds_only]
