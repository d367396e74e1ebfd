"""The mirror rule's exceptions, declared once (docs/architecture.md, "The C and its mirror").

The rule: every C function of the generated sources has a Python function of the same
name (``P_name``: ``name``) in the reference module of its template partial:
``templates/solver/X.c.j2`` and ``templates/X.c.j2`` -> ``reference/X.py``, or the modules
:data:`PARTIAL_MODULES` names.  The C functions without one are :data:`UNMIRRORED`, each
with the Python function whose arithmetic covers it and why it has none of its own.
``tests/codegen/test_mirror.py`` checks the rendered C, the reference and the table of the
architecture page against this module.
"""
from __future__ import annotations

from typing import NamedTuple

# template (under templates/) -> the modules (under rollmpc_codegen/) of its mirror, where
# they are not reference/<its name>.py
PARTIAL_MODULES = {
    "controller.c.j2": ("reference/controller.py", "reference/scheduler.py",
                        "reference/solver.py"),
    "controller/runtime_bounds.c.j2": ("reference/controller.py", "features/runtime_bounds.py"),
    "controller/observers.c.j2": ("reference/controller.py",),
    "linalg/cholesky_blocks.c.j2": ("reference/linalg.py",),
    "solver/bounds.c.j2": ("features/runtime_bounds.py",),
    "solver/gather.c.j2": ("reference/dot.py",),
    "solver/qp_solve.c.j2": ("reference/solver.py",),
    "solver/soft_rows.c.j2": ("reference/soft_rows.py", "features/soft_constraints.py"),
    "solver/violated_rows.c.j2": ("reference/rows.py",),
    "solver/work.c.j2": ("qp/work.py", "reference/solver.py"),
}


class Unmirrored(NamedTuple):
    covered_by: str  # the mirror of its arithmetic: module (under rollmpc_codegen/).function
    why: str


# A kernel forms, blocked, unrolled or a column at a time, sums its mirror forms in the same
# order (the bit-exactness tests compare every result); bookkeeping moves indices, flags or
# copies, with no arithmetic a mirror could get wrong.
_KERNEL = "a kernel of it: the same sequential sums, "
_BOOKKEEPING = "bookkeeping without arithmetic: "
_HQ = "reference/hq.py.hessian_reads"
_DOT = "reference/dot.py.s_row_dot"
_CHOLESKY = "reference/linalg.py.cholesky_from"
_ORDER = "reference/primal_rows.py.primal_order"
_ROLES = "reference/polish_primal.py.primal_solve"

UNMIRRORED = {
    "P_ctrl_size": Unmirrored("reference/controller.py.init", _BOOKKEEPING + "sizeof(P_ctrl)"),
    # hq.c.j2: the reference tabulates every element of H the C reads, formed by the same
    # operations (Δu differences: _rate_extended)
    **{name: Unmirrored(_HQ, _KERNEL + "tabulated once per mode") for name in (
        "by_sign", "by_signs", "einv", "hq_output", "hq_base", "hq_side", "hq", "h_rows",
        "einv_column", "hq_input_column", "h_from_column", "h_column",
        "hq_quantities", "hq_signal")},
    **{name: Unmirrored(_HQ, _BOOKKEEPING + "which way h_column() reads (same values)")
       for name in ("einv_reads", "column_pays")},
    **{name: Unmirrored(_DOT, _KERNEL + "over the support of x, unrolled or a column at a "
                              "time") for name in (
        "packed_range_dot", "packed_range_dot2", "packed_range_dot4", "packed_gather",
        "packed_gather_listed",
        "s_row_dot2", "s_row_dot4", "packed_columns_axpy", "sparse_rows_dot", "sym_product",
        "gather_dot4", "gather_product")},
    "gather_bound": Unmirrored(_ROLES, _BOOKKEEPING + "the bound inputs and their values "
                               "gathered in ascending order"),
    **{name: Unmirrored(_CHOLESKY, _KERNEL + "by blocks of rows") for name in (
        "cholesky_row", "cholesky_block", "finish_four", "cholesky_block44", "cholesky_block4",
        "cholesky_column", "pair_columns", "pair_diagonal")},
    "matvec_rows": Unmirrored("reference/linalg.py.seqsum_rows", _KERNEL + "four rows a trip"),
    "stage_sum": Unmirrored("reference/unconstrained.py.other_runs",
                            _KERNEL + "four stages a trip"),
    "add_sinv_pair": Unmirrored("reference/sweeps.py.correct",
                                _KERNEL + "two neighbouring columns in one pass"),
    "violated_kind": Unmirrored("reference/rows.py.violated_outside",
                                _BOOKKEEPING + "the rows of one kind, through scan_rows"),
    "unpredicted_value": Unmirrored("reference/rows.py.row_value",
                                    _KERNEL + "row_value() of an input or Δu row, inline"),
    "soft_of": Unmirrored("reference/solver.py.__init__",
                          _BOOKKEEPING + "a row's (l1, w): the table soft_l1, soft_w"),
    "forget_row": Unmirrored("reference/polish_dual.py.remove_row",
                             _BOOKKEEPING + "a row's flags cleared"),
    "clear_flags": Unmirrored("reference/seeds.py.carry_factor",
                              _BOOKKEEPING + "the guess's membership flags cleared"),
    **{name: Unmirrored(_ORDER, _BOOKKEEPING + "the order of the primal factor's rows")
       for name in ("in_form", "role_gen", "primal_diff")},
    "input_run": Unmirrored("reference/polish_primal.py.primal_factor",
                            _BOOKKEEPING + "the runs the factor's rows are gathered by"),
    **{name: Unmirrored(_ROLES, _BOOKKEEPING + "the inputs' roles in ws->input_role")
       for name in ("role_word", "set_role_word", "mark_bound_inputs")},
}
