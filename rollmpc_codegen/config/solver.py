"""``solver``: the QP solver's variant, SOR factor, stopping rule, polish and active set."""
from __future__ import annotations

from .errors import ConfigError
from .reader import Reader
from .schema import MAX_C_INT, SOLVER_METHODS, WORK_BUDGET_AUTO, SolverConfig


def parse_solver(r: Reader) -> SolverConfig:
    """``solver``: every key optional, the defaults are SolverConfig's."""
    d = SolverConfig()
    method = r.string("method", d.method, choices=SOLVER_METHODS)
    omega = r.number("omega", d.omega)
    if not 0.0 < omega < 2.0:
        raise ConfigError(r.key("omega"), f"SOR needs 0 < omega < 2, got {omega}")
    sigma = r.number("sigma", d.sigma, nonnegative=True)
    delta = r.number("delta", d.delta, positive=True)
    max_iterations = r.integer("max_iterations", d.max_iterations, minimum=1, maximum=MAX_C_INT)
    warm_start = r.boolean("warm_start", d.warm_start)
    polish = r.boolean("polish", d.polish)
    polish_first = r.boolean("polish_first", d.polish_first)
    polish_every = r.integer("polish_every", d.polish_every, minimum=1, maximum=MAX_C_INT)
    polish_max = r.integer("polish_max", d.polish_max, minimum=1, maximum=MAX_C_INT)
    tol = r.number("feasibility_tol", None, positive=True) if r.has("feasibility_tol") else None
    active_set = r.boolean("active_set", d.active_set)
    active_set_max = r.integer("active_set_max", d.active_set_max, minimum=1,
                               maximum=MAX_C_INT)
    dep_tol = (r.number("dependence_tol", None, positive=True)
               if r.has("dependence_tol") else None)
    if dep_tol is not None and not dep_tol < 1.0:
        raise ConfigError(r.key("dependence_tol"), f"must be < 1, got {dep_tol}")
    work_budget = d.work_budget
    if r.has("work_budget") and r.raw("work_budget") != WORK_BUDGET_AUTO:
        try:
            work_budget = r.integer("work_budget", minimum=1, maximum=MAX_C_INT)
        except ConfigError as exc:
            raise ConfigError(exc.key, f"{exc.problem} (work units) or {WORK_BUDGET_AUTO}") from None
    budget_share = r.number("budget_share", d.budget_share, positive=True)
    if not budget_share <= 1.0:
        raise ConfigError(r.key("budget_share"), f"is a fraction of the sample time: 0 < "
                          f"budget_share <= 1, got {budget_share}")
    if active_set and not polish and r.has("active_set"):
        raise ConfigError(r.key("active_set"), "needs polish: true (its working set is "
                          "finished by the polish step)")
    return SolverConfig(method=method, omega=omega, sigma=sigma, delta=delta,
                        max_iterations=max_iterations, warm_start=warm_start, polish=polish,
                        polish_first=polish_first,
                        polish_every=polish_every, polish_max=polish_max,
                        feasibility_tol=tol, active_set=active_set,
                        active_set_max=active_set_max, dependence_tol=dep_tol,
                        work_budget=work_budget, budget_share=budget_share)
