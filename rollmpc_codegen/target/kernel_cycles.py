"""Cycles of the linear-algebra kernels (linalg.c) alone on the emulated Cortex-M4F, per
operation of their work formulas: the measurement behind CHOL_UNITS_PER_OP and
TRI_UNITS_PER_OP (:mod:`rollmpc_codegen.qp.work`).

    python -m rollmpc_codegen.target.kernel_cycles examples/uav_roll.yaml

Each kernel runs once per order on a random SPD matrix (packed lower triangle) written
into the controller instance's RAM; the build is the firmware's (float, -O2).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from ..config.errors import ConfigError
from ..pipeline import load_model
from ..qp.work import chol_ops, tri_ops
from .build import build_target
from .emulate import CortexM

ORDERS = (5, 10, 20, 40, 60, 80)


def kernel_cycles(config: str | Path, orders=ORDERS) -> list[dict]:
    """Per order: the cycles of cholesky_from, chol_lsolve_from and chol_ltsolve, and
    their cycles per chol_ops() / tri_ops() operation."""
    _model, ctx = load_model(config, "float")
    with tempfile.TemporaryDirectory(prefix="rollmpc-kernels-") as tmp:  # loaded: not kept
        build = build_target(ctx, Path(tmp))
        cpu = CortexM(build.elf, build.core)
    p, rng, rows = ctx["prefix"], np.random.default_rng(0), []
    base, room = cpu.objects[f"{p}_target_ctrl"]
    for k in orders:
        a = rng.standard_normal((k, k))
        packed = np.concatenate([row[:i + 1] for i, row in enumerate(a @ a.T + k * np.eye(k))])
        packed = packed.astype(np.float32)
        if packed.nbytes + 64 + 4 * k > room:
            break  # the instance's RAM holds no larger factor
        rhs = base + packed.nbytes + 64
        cpu.write(f"{p}_target_ctrl", packed)
        cpu.uc.mem_write(rhs, np.ones(k, np.float32).tobytes())
        chol = cpu.call(f"{p}_cholesky_from", (base, 0, k), count=True)[1].cycles
        fwd = cpu.call(f"{p}_chol_lsolve_from", (base, 0, k, rhs), count=True)[1].cycles
        back = cpu.call(f"{p}_chol_ltsolve", (base, k, rhs), count=True)[1].cycles
        rows.append({"order": k, "cholesky": chol, "per_chol_op": chol / chol_ops(k),
                     "forward": fwd, "back": back, "per_tri_op": max(fwd, back) / tri_ops(k)})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rollmpc_codegen.target.kernel_cycles",
                                 description="Cycles per operation of the factor and "
                                 "triangular-solve kernels on the emulated Cortex-M4F.")
    ap.add_argument("config", nargs="?", default="examples/uav_roll.yaml",
                    help="a design to build the kernels from (default: %(default)s)")
    args = ap.parse_args(argv)
    try:
        rows = kernel_cycles(args.config)
    except ConfigError as exc:
        print(f"kernel_cycles: error: {exc}", file=sys.stderr)
        return 2
    print("order  cholesky  cycles/op   forward     back  cycles/op (slower solve)")
    for r in rows:
        print(f"{r['order']:5d} {r['cholesky']:9d} {r['per_chol_op']:10.2f} {r['forward']:9d}"
              f" {r['back']:8d} {r['per_tri_op']:10.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
