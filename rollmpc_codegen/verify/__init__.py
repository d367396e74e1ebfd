"""The reliability tooling of docs/reliability.md: random configs and QP campaigns against an
extended-precision reference, the float stored-data floor, MISRA deviations; run it as
``python -m rollmpc_codegen.verify`` (measurement only: nothing here is on the pipeline's
import path; the float check that ``rollmpc generate`` runs after writing a float
controller, host/float_check.py, borrows float_floor.widened)."""
