"""The members of ``P_info``, the diagnostics ``P_last_info()`` returns, each declared once.

:mod:`.codegen.context` passes them to the templates, which render the struct of the
public header (``api.h.j2``), the host's cffi declaration (``host/cffi_cdef.h.j2``) and the
emulator harness' copy (``target/harness.c.j2``); the host wrapper reads them by these
names (:meth:`rollmpc_codegen.host.build.HostController.info`).
"""
from __future__ import annotations

from typing import NamedTuple


class InfoField(NamedTuple):
    name: str
    ctype: str  # "int", "uint32_t" or "real" (P_real)
    doc: str  # "{p}" / "{P}" stand for the prefix in lower / upper case
    soft_rows_only: bool = False  # a member only with soft output bounds
    timing: bool = False  # measured, not computed: differs between runs and machines

    @property
    def compared(self) -> bool:
        """An integer every build computes: the emulated target's must equal the host's."""
        return self.ctype != "real" and not self.timing and not self.soft_rows_only


INFO_FIELDS = (
    InfoField("status", "int", "{p}_status of the last call."),
    InfoField("mode", "int", "Mode used by the last call (0-based, config order)."),
    InfoField("iterations", "int", "Dual sweeps of the last QP solve."),
    InfoField("polish_iterations", "int",
              "Active-set corrections of the polish step (0 if unused)."),
    InfoField("active", "int", "Rows in the final active set."),
    InfoField("mode_switches", "int", "Mode changes since init."),
    InfoField("clipped", "int", "Innovations clipped by the last {p}_step(), summed over every "
              "mode's observer and output (observer.innovation_limit)."),
    InfoField("solve_ticks", "uint32_t", "{P}_TIMESTAMP() difference around the solve.",
              timing=True),
    InfoField("work", "uint32_t",
              "Work units of the last QP solve (<= {P}_SOLVER_WORK_BUDGET)."),
    InfoField("slack_max", "real", "Largest soft-bound slack s of the planned outputs (output "
              "units: how far the plan exceeds a soft bound); 0 when none does or the status "
              "is not OPTIMAL.", soft_rows_only=True),
    InfoField("slack_rows", "int",
              "Soft output rows (output, side, stage) with s > 0 in the plan.",
              soft_rows_only=True),
)


def context_info_fields(prefix: str, has_soft_rows: bool) -> list[dict]:
    """The members of one build's P_info, in order, for the templates."""
    return [{"name": f.name, "real": f.ctype == "real", "compared": f.compared,
             "ctype": f"{prefix}_real" if f.ctype == "real" else f.ctype,
             "doc": f.doc.format(p=prefix, P=prefix.upper())}
            for f in INFO_FIELDS if has_soft_rows or not f.soft_rows_only]


# the members the emulator harness copies out after each step (target/harness.c.j2), in order
COMPARED_FIELDS = tuple(f.name for f in INFO_FIELDS if f.compared)
