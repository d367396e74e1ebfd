"""The NumPy mirror of the generated C, function by function under the C names, bit for bit:
the solver (one module per template partial under templates/solver/), the packed linear algebra,
the band scheduler and the controller step (docs/architecture.md has the mirror table)."""
