"""rollmpc: YAML -> switched linear MPC -> static C99 with a Hildreth-family QP solver.

Pipeline (one module per stage): config -> plant -> mpc -> observer -> qp -> context ->
render -> build; then simulate / bench / report on the compiled C.
"""
__version__ = "0.1.0"
