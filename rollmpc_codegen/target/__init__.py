"""The generated C on a Cortex-M4F: cross-compile and size it (``build``), run it on an emulated
core (``emulate``), and ``rollmpc report``: replay a closed loop on the target bit for bit and
count cycles (``replay``, ``measure``, ``horizons``), worst stack path (``stack_usage``)."""
