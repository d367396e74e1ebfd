"""What the M7's caches would add to one step, which its cycle model leaves out
(zero wait states: target/cycle_models.py): the misses of that step in a cold 16 KiB
4-way instruction cache and a 16 KiB 4-way data cache with 32-byte lines (the STM32F7's
and H7's L1), every other firmware task having evicted the controller since its last
step.  A miss costs a line fill from flash or AXI SRAM: the cycles it adds are the misses
times the penalty of docs/target.md "Parts" (an assumption per part, not measured).

    python -m rollmpc_codegen.target.cache_lines examples/uav_roll.yaml --part stm32h743 \\
        --precision double --step 3071

The run is replayed on the emulator up to the step (not counted), then the step's code
fetches (per executed block) and data reads and writes (a memory hook) go through the two
simulated caches.  Data in the controller instance is cached like the constants: on the
H743 it lives in AXI SRAM (parts.py); in DTCM, as on the F765's first 128 KiB, it would
not miss at all.
"""
from __future__ import annotations

import argparse
from collections import OrderedDict
from pathlib import Path

import numpy as np

LINE = 32


class Cache:
    """A set-associative LRU cache that only counts: ``access`` returns whether it missed."""

    def __init__(self, kib: int = 16, ways: int = 4, line: int = LINE):
        self.line, self.ways = line, ways
        self.sets = kib * 1024 // (line * ways)
        self.lines = [OrderedDict() for _ in range(self.sets)]
        self.accesses = self.misses = 0

    def access(self, address: int, size: int = 1) -> None:
        for tag in range(address // self.line, (address + max(size, 1) - 1) // self.line + 1):
            self.accesses += 1
            ways = self.lines[tag % self.sets]
            if tag in ways:
                ways.move_to_end(tag)
                continue
            self.misses += 1
            ways[tag] = True
            if len(ways) > self.ways:
                ways.popitem(last=False)


def step_misses(model, ctx: dict, build_root: Path, step: int) -> dict:
    """The cold-cache misses of ``step`` of the config's scenario on its target image."""
    from unicorn import UC_HOOK_BLOCK, UC_HOOK_MEM_READ, UC_HOOK_MEM_WRITE

    from .build import build_target
    from .emulate import CortexM
    from .replay import record_host_run

    build = build_target(ctx, build_root)
    record = record_host_run(model, ctx, build_root, steps=step + 1, progress=False)
    em, p = CortexM(build.elf, build.core), ctx["prefix"]
    em.call(f"{p}_target_init")

    def feed(k: int) -> None:
        em.write(f"{p}_target_y", record.y[k])
        if ctx["n_schedule"]:
            em.write(f"{p}_target_sched", record.sched[k])
        em.write(f"{p}_target_r", record.r[k])

    for k in range(step):
        feed(k)
        em.call(f"{p}_target_step")
    feed(step)
    code, data = Cache(), Cache()
    hooks = [em.uc.hook_add(UC_HOOK_BLOCK, lambda uc, a, s, _u: code.access(a, s)),
             em.uc.hook_add(UC_HOOK_MEM_READ | UC_HOOK_MEM_WRITE,
                            lambda uc, _acc, a, s, _v, _u: data.access(a, s))]
    em.uc.ctl_flush_tb()
    try:
        em.call(f"{p}_target_step")
    finally:
        for h in hooks:
            em.uc.hook_del(h)
    out = np.frombuffer(em.read(f"{p}_target_u"), np.float64 if ctx["real"] == "double"
                        else np.float32)
    if out.tobytes() != record.u[step].tobytes():
        raise RuntimeError(f"step {step}: the emulated command differs from the host's")
    return {"step": step, "code_lines": code.accesses, "code_misses": code.misses,
            "data_accesses": data.accesses, "data_misses": data.misses}


def main(argv=None) -> int:
    from ..pipeline import load_model
    from ..host.build_cache import private_root

    ap = argparse.ArgumentParser(prog="python -m rollmpc_codegen.target.cache_lines")
    ap.add_argument("config")
    ap.add_argument("--part", default="stm32h743")
    ap.add_argument("--precision", default=None)
    ap.add_argument("--step", type=int, required=True)
    args = ap.parse_args(argv)
    model, ctx = load_model(args.config, args.precision, args.part)
    r = step_misses(model, ctx, private_root(None), args.step)
    print(f"step {r['step']}: code {r['code_misses']} misses of {r['code_lines']} line "
          f"fetches, data {r['data_misses']} misses of {r['data_accesses']} line accesses "
          "(cold 16 KiB 4-way caches, 32-byte lines)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
