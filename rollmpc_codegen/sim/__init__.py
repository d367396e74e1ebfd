"""Closed loops on the host: the scenario and simulated plant, the loop itself, the Fig. 2
metrics and figures, the LQR baseline and the double-precision switched observer."""
