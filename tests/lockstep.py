"""The C and the NumPy reference driven side by side on the same inputs (a closed loop's
controller), every difference recorded: the bit-exactness check of most feature tests."""
from __future__ import annotations


class Lockstep:
    """Drives the C and the reference with the same inputs; records every difference."""

    def __init__(self, built):
        self.c = built.fresh_c()
        self.ref = built.reference()
        self.mismatches = []
        self.states = []  # (mode, xhat before the solve, k)
        self.iterations = {j: [] for j in range(len(built.model.modes))}
        self.k = 0

    def step(self, y, s, r):
        st_c, u_c = self.c.step(y, s, r)
        info = self.c.info()
        mode_before = self.ref.mode
        x_before = [x.copy() for x in self.ref.xhat]
        st_r, u_r = self.ref.step(y, s, r)
        self.states.append((self.ref.mode, x_before[self.ref.mode], self.k))
        same = (st_c == st_r and u_c.tobytes() == u_r.tobytes()
                and info["iterations"] == self.ref.last["iterations"]
                and info["mode"] == self.ref.mode)
        if not same:
            self.mismatches.append((self.k, st_c, st_r, u_c, u_r, info, self.ref.last,
                                    mode_before))
        self.iterations[self.ref.mode].append(info["iterations"])
        self.k += 1
        return st_c, u_c

    def info(self):
        return self.c.info()
