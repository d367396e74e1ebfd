"""``rollmpc bench``'s ``daqp_c`` rows: DAQP's own C, compiled on the host, timed like ours.

The ``daqp`` row times the Python daqp by its ``info['solve_time']``, which leaves out
forming the QP's data from (x, r) and DAQP's ``update()`` (its linear term and bounds);
our ``solve_ticks`` includes both (theta0, the rows' constants). On small QPs that is
most of the time. These rows build the harness of ``rollmpc report --peer daqp``
(:mod:`.daqp_harness`) for the host in double, with DAQP's own optimisation flags
(``HOST_FLAGS``), and read the same monotonic clock around:

* ``daqp_c``: the whole sample, as ``solve_ticks`` does for ours -- the shifted bounds
  from (x, r), ``daqp_update_ldp``, ``daqp_solve`` warm-started, U = theta0 + z;
* ``daqp_c_solve``: only ``daqp_update_ldp`` and ``daqp_solve`` (a lower bound on what a
  controller around DAQP spends).

DAQP's set-up is not counted; its Hessian is the Cholesky factor of E computed offline.
"""
from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from .build import STRICT_WARNINGS, BuildError
from .build_cache import private_root, publish, staging, verified
from .daqp_harness import (DAQP_WARNINGS, build_key, compile_daqp, compile_harness,
                           compile_relaxed, daqp_sources, daqp_version, exit_flags,
                           harness_context, mode_arrays)
from ..codegen.render import render_template
from ..model.controller import ControllerModel
from ..qp.peers import PeerResult, peer_problems

# DAQP at its best: the optimisation flags of its own Python build (the sdist's setup.py,
# daqp 0.11.0: -O3 -fassociative-math -fno-signed-zeros -fno-trapping-math; its
# -DPROFILING, a clock inside daqp_solve, left out), for DAQP and the harness alike.
# With our -O2 -ffp-contract=off its worst solves ran up to 2.2x slower than the wheel's.
# Ours keeps its own flags: its sums must round exactly as the NumPy reference's.
HOST_FLAGS = ("-O3", "-fassociative-math", "-fno-signed-zeros", "-fno-trapping-math", "-fPIC")
TIMED = {"step": 0, "solve": 1}  # which of the harness' two tick counts a row reads


def build_daqp_host(ctx: dict, csrc: Path, build_root: Path | None = None,
                    compiler: str = "gcc") -> Path:
    """DAQP's sources and the host harness as one shared library; cached by content hash."""
    p = ctx["prefix"]
    harness = render_template(ctx, "target/daqp_harness.c.j2")
    key = build_key([compiler, *HOST_FLAGS, *DAQP_WARNINGS, *STRICT_WARNINGS, harness], csrc)
    root = private_root(build_root)
    out, lib_name = root / f"daqp-host-{p}-{key[:16]}", f"lib{p}_host.so"
    lib = verified(out, lib_name, key)
    if lib is not None:
        return lib
    with staging(root, out.name) as tmp:
        (tmp / f"{p}_host_harness.c").write_text(harness)
        objs, _ = compile_daqp([compiler, *HOST_FLAGS], csrc, tmp)
        objs.append(compile_harness([compiler, *HOST_FLAGS], csrc, tmp / f"{p}_host_harness.c"))
        compile_relaxed([compiler, "-shared", "-o", str(tmp / lib_name), *map(str, objs), "-lm"])
        return publish(tmp, out, lib_name, key)


class DaqpCPeer:
    """DAQP's C on the host, one warm-started workspace per mode, timed in C (``timed``:
    "step", the whole sample as ours, or "solve", DAQP's update and solve only)."""

    name = "daqp_c"

    def __init__(self, model: ControllerModel, timed: str = "step",
                 build_root: Path | None = None):
        if timed not in TIMED:
            raise ValueError(f"timed must be one of {', '.join(TIMED)}, got {timed!r}")
        version = daqp_version()
        csrc = daqp_sources(version)
        self.flag_names = exit_flags(csrc)
        ctx = harness_context(model, version, host=True)
        self.p, self.modes, self.tick = ctx["prefix"], ctx["modes"], TIMED[timed]
        problems, self.n_u = peer_problems([mm.qp for mm in model.modes])
        self.lib = ctypes.CDLL(str(build_daqp_host(ctx, csrc, build_root)))
        for j, qp in enumerate(problems):
            for name, values in mode_arrays(qp).items():
                self._write(f"{name}_{j}", values)
        getattr(self.lib, f"{self.p}_target_init")()
        flags = self._ints("target_info", 3 + len(self.modes), np.int32)[3:]
        if min(flags) < 0:
            raise BuildError(f"setup_daqp failed on the host: exit flags {flags.tolist()}")
        self._step = getattr(self.lib, f"{self.p}_target_step")
        self._step.argtypes, self._step.restype = [ctypes.c_int], ctypes.c_int

    def _address(self, symbol: str) -> int:
        return ctypes.addressof(ctypes.c_char.in_dll(self.lib, f"{self.p}_{symbol}"))

    def _write(self, symbol: str, values) -> None:
        data = np.ascontiguousarray(values, np.float64)
        ctypes.memmove(self._address(symbol), data.ctypes.data, data.nbytes)

    def _ints(self, symbol: str, count: int, dtype) -> np.ndarray:
        size = count * np.dtype(dtype).itemsize
        return np.frombuffer(ctypes.string_at(self._address(symbol), size), dtype)

    def solve(self, mode: int, x: np.ndarray, r: np.ndarray) -> PeerResult:
        self._write("target_x", x)
        self._write("target_r", r)
        flag = self._step(mode)
        iterations = int(self._ints("target_info", 2, np.int32)[1])
        ticks = int(self._ints("target_ticks", 2, np.uint32)[self.tick])
        n = self.modes[mode]["n"]
        U = np.frombuffer(ctypes.string_at(self._address("target_U"), 8 * n), np.float64)
        status = "optimal" if flag == 1 else self.flag_names.get(flag, f"exitflag {flag}")
        return PeerResult(status, U[:self.n_u[mode]].copy(), ticks * 1e-9, iterations)
