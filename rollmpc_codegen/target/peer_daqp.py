"""``rollmpc report --peer daqp``: DAQP's own C, in single precision, on the same emulated
Cortex-M4F, replaying the same QP sequence as the generated controller.

* **Source**: the C of DAQP's PyPI sdist (``pip download --no-binary daqp daqp==V``, V =
  the installed Python daqp, which is also the host reference below), downloaded once and
  unpacked into the build cache; nothing of DAQP is vendored.
* **Build**: DAQP's sources with ``-DDAQP_SINGLE_PRECISION`` and the controller's target
  flags (``CORTEX_M4F`` + ``TARGET_CFLAGS``), linked with the target linker script and the
  harness ``templates/target/daqp_harness.c.j2``. The harness is held to our strict
  warnings; DAQP's own files get the same warnings without ``-Werror`` (relaxed: it is not
  our code), and the warnings they raise are counted by flag in the result.
* **Set-up at its best, not counted**: one workspace per mode; the Hessian is given as its
  Cholesky factor computed offline in double and rounded once to float (DAQP's factored
  Hessian, ``problem_type`` 2, so the float build never factors E itself). The other
  ``SETUPS`` entry lets DAQP factor E in float on the target: it then regularises the
  outer mode (cond(E) 2.5e6) and its proximal iterations hit the iteration limit on the
  first saturated QP (5.3 G cycles, |u| error 11 deg, measured). The QP is
  shifted by the unconstrained optimum theta0 (precomputed gains, as our solver has), so
  DAQP sees no linear term, only bounds: inputs as simple bounds, outputs as two-sided
  general rows (``qp.peers.TwoSidedForm``).
* **Counted per sample**: forming the shifted bounds from (x, r), ``daqp_update_ldp`` of
  the bounds with DAQP's unconstrained check, ``daqp_solve`` warm-started from the mode's
  previous working set (per mode, as ``qp.peers.DaqpPeer``), and U = theta0 + z.
* **Checked**: against the host DAQP in double (``DaqpPeer``, the same working-set policy)
  and against our controller's host build (``P_solve_qp``, warm-started, re-initialised on
  a mode switch as ``P_step`` does); input bounds |u| beyond the limits are reported.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..codegen.context import build_context
from ..codegen.render import render_template
from ..host.build import STRICT_WARNINGS, build_host_controller
from ..host.build_cache import private_root, publish, staging, verified
from ..host.daqp_harness import (DAQP_WARNINGS, SETTINGS, SETUPS, build_key, compile_daqp,
                                 compile_harness, daqp_sources, daqp_version, exit_flags,
                                 harness_context, mode_arrays, warning_counts)
from ..model.controller import ControllerModel
from ..qp.peers import DaqpPeer, c_stdout_silenced, peer_problems
from .build import (EMU_FLASH_KIB, EMU_RAM_KIB, EMU_STACK_BYTES, TARGET_CFLAGS,
                    TARGET_LDFLAGS, _run, core_of, image_sizes, require_cross_compiler)
from .emulate import CortexM

SINGLE_PRECISION = "-DDAQP_SINGLE_PRECISION"
# |u| beyond a limit by more than this fraction of the limit counts as a violation
BOUND_TOL = 1e-5


# ----------------------------------------------------------------------------- build
def build_daqp_target(ctx: dict, csrc: Path, build_root: Path) -> tuple[Path, dict]:
    """Cross-compile DAQP and the harness, link the image; cached by content hash.

    Returns (elf, {warning flag: count}) for the warnings DAQP's own files raised.
    """
    cc = require_cross_compiler()
    p = ctx["prefix"]
    harness = render_template(ctx, "target/daqp_harness.c.j2")
    ld = render_template(ctx, "target/link.ld.j2", flash_kib=EMU_FLASH_KIB,
                         ram_kib=EMU_RAM_KIB, stack_bytes=EMU_STACK_BYTES)
    mcu = core_of(ctx).cflags
    base = [*mcu, *TARGET_CFLAGS, SINGLE_PRECISION]
    key = build_key([cc, *base, *DAQP_WARNINGS, *STRICT_WARNINGS, harness, ld], csrc)
    root = private_root(build_root)
    out, elf_name = root / f"target-{p}-{key[:16]}", f"{p}_target.elf"
    elf = verified(out, elf_name, key)
    if elf is not None:
        return elf, warning_counts((out / "daqp_warnings.txt").read_text())
    with staging(root, out.name) as tmp:
        (tmp / f"{p}_target_harness.c").write_text(harness)
        (tmp / f"{p}_target.ld").write_text(ld)
        objs, warnings = compile_daqp([cc, *base], csrc, tmp)
        objs.append(compile_harness([cc, *base], csrc, tmp / f"{p}_target_harness.c"))
        _run([cc, *mcu, *TARGET_LDFLAGS, "-T", str(tmp / f"{p}_target.ld"),
              f"-Wl,-Map={tmp / (p + '_target.map')}", "-o", str(tmp / elf_name),
              *map(str, objs), "-lm", "-lgcc"])
        (tmp / "daqp_warnings.txt").write_text(warnings)
        elf = publish(tmp, out, elf_name, key)
    return elf, warning_counts(warnings)


# ----------------------------------------------------------------------------- target
class DaqpOnTarget:
    """The DAQP image on the emulated core with every mode's workspace set up (not counted)."""

    def __init__(self, elf: Path, ctx: dict, arrays: list[dict]):
        self.p, self.modes = ctx["prefix"], ctx["modes"]
        self.em = CortexM(elf, core_of(ctx))
        for j, data in enumerate(arrays):
            for name, values in data.items():
                self.em.write(f"{self.p}_{name}_{j}", np.ascontiguousarray(values, np.float32))
        self.em.call(f"{self.p}_target_init")
        flags = self._info()[3:]
        if min(flags) < 0:
            raise RuntimeError(f"setup_daqp failed on the target: exit flags {flags.tolist()}")
        self.heap_after_setup = self.heap_state()

    def _info(self) -> np.ndarray:
        return np.frombuffer(self.em.read(f"{self.p}_target_info"), np.int32)

    def heap_state(self) -> tuple[int, int]:
        """(bytes of DAQP's arena in use, allocations so far)."""
        used, count = np.frombuffer(self.em.read(f"{self.p}_heap_state"), np.uint32)
        return int(used), int(count)

    def step(self, mode: int, x: np.ndarray, r: np.ndarray):
        """One counted sample: (exit flag, iterations, working-set size, U, Counts)."""
        self.em.write(f"{self.p}_target_x", np.ascontiguousarray(x, np.float32))
        self.em.write(f"{self.p}_target_r", np.ascontiguousarray(r, np.float32))
        _, counts = self.em.call(f"{self.p}_target_step", (mode,), count=True)
        flag, iterations, active = (int(v) for v in self._info()[:3])
        n = self.modes[mode]["n"]
        U = np.frombuffer(self.em.read(f"{self.p}_target_U", 4 * n), np.float32)
        return flag, iterations, active, U.astype(np.float64), counts


def daqp_cycles(model: ControllerModel, qp_sequence, progress=None,
                build_root: Path | None = None, limit: int | None = None,
                sdist_cache: Path | None = None, setup: str = "offline") -> dict:
    """Replay ``qp_sequence`` (``host.bench_record.record_qp_sequence``; its first ``limit`` QPs)
    through DAQP on the emulated core of the design's target; per mode: median and worst cycles, the QP where
    they peak, statuses, errors against the host DAQP in double and against our
    controller's host build, and inputs beyond their limits (see the module docstring)."""
    if setup not in SETUPS:
        raise ValueError(f"setup must be one of {', '.join(SETUPS)}, got {setup!r}")
    version = daqp_version()
    csrc = daqp_sources(version, sdist_cache)
    flag_names = exit_flags(csrc)
    ctx = harness_context(model, version, setup)
    root = private_root(build_root)
    elf, warnings = build_daqp_target(ctx, csrc, root)
    qps = [mm.qp for mm in model.modes]
    problems, n_u = peer_problems(qps)
    target = DaqpOnTarget(elf, ctx, [mode_arrays(qp, ctx["factored"]) for qp in problems])
    host = DaqpPeer(qps)
    ours = build_host_controller(build_context(model), root)
    seq = qp_sequence
    count = len(seq.mode) if limit is None else min(limit, len(seq.mode))
    rows = np.zeros((count, 7))  # cycles, instructions, bounds cycles, iterations, 3 errors
    flags, worst_functions, previous = [], {}, None
    bounds_fn = f"{ctx['prefix']}_shifted_bounds"
    with c_stdout_silenced():
        for q in range(count):
            mode, x, r = int(seq.mode[q]), seq.x[q], seq.r[q]
            flag, iterations, _, U, counts = target.step(mode, x, r)
            if mode != previous:  # as P_step on a switch: our incoming mode starts cold
                ours.init()
                previous = mode
            U_ours = ours.solve_qp(mode, x, r)[1].astype(np.float64)
            U_ref = host.solve(mode, x, r).U
            nu, cfg = n_u[mode], model.config.modes[mode]
            U, moves = U[:nu], nu // len(cfg.u_max)
            beyond = max(0.0, float((U - np.tile(cfg.u_max, moves)).max()),
                         float((np.tile(cfg.u_min, moves) - U).max()))
            rows[q] = (counts.cycles, counts.instructions,
                       counts.by_function.get(bounds_fn, (0, 0))[1], iterations,
                       np.abs(U - U_ref).max(), np.abs(U - U_ours[:nu]).max(), beyond)
            flags.append(flag_names.get(flag, str(flag)))
            if counts.cycles > worst_functions.get(mode, (-1, None))[0]:
                worst_functions[mode] = (counts.cycles, counts)
            if progress is not None:
                progress(q)
    k = np.asarray(seq.k[:count])
    modes = np.asarray(seq.mode[:count])
    by_mode = {}
    for j, cfg in enumerate(model.config.modes):
        sel = np.flatnonzero(modes == j)
        if sel.size:
            scale = max(np.abs(cfg.u_min).max(), np.abs(cfg.u_max).max(), 1.0)
            by_mode[cfg.name] = _mode_summary(sel, rows, flags, k, BOUND_TOL * scale,
                                              worst_functions[j][1])
    return {
        "peer": f"DAQP {version} (PyPI sdist, single precision)",
        "daqp_version": version,
        "cflags": " ".join([*core_of(ctx).cflags, *TARGET_CFLAGS, SINGLE_PRECISION]),
        "relaxed_for_daqp": "-Werror",
        "daqp_warnings": warnings,
        "settings": dict(SETTINGS),
        "setup": f"{setup}: {SETUPS[setup]}; not counted; one workspace per mode; the QP "
                 "shifted by theta0 (no linear term)",
        "counted": "shifted bounds from (x, r) + daqp_update_ldp(bounds, unconstrained "
                   "check) + daqp_solve warm-started + U = theta0 + z",
        "qps": count,
        "text_bytes": image_sizes(elf)["text_bytes"],
        "heap_bytes": target.heap_after_setup[0],
        "allocations_after_setup": target.heap_state()[1] - target.heap_after_setup[1],
        "by_mode": by_mode,
        "k": k.tolist(),
        "mode": modes.tolist(),
        "cycles": rows[:, 0].astype(np.int64).tolist(),
        "status": flags,
        "abs_err_vs_host_double": rows[:, 4].tolist(),
        "u_beyond_limits": rows[:, 6].tolist(),
    }


def _peak(values: np.ndarray, sel: np.ndarray) -> tuple[int, int, int]:
    """(median, worst, index of the first worst) of ``values`` over ``sel``."""
    worst = sel[int(np.argmax(values[sel]))]
    return int(np.median(values[sel])), int(values[worst]), int(worst)


def _mode_summary(sel: np.ndarray, rows: np.ndarray, flags: list, k: np.ndarray,
                  bound_tol: float, worst_counts) -> dict:
    median, worst, at = _peak(rows[:, 0], sel)
    solver = _peak(rows[:, 0] - rows[:, 2], sel)
    names, counts = np.unique(np.array([flags[q] for q in sel], dtype=object).astype(str),
                              return_counts=True)
    top = sorted(worst_counts.by_function.items(), key=lambda kv: -kv[1][1])[:6]
    return {
        "qps": int(sel.size),
        "median_cycles": median,
        "worst_cycles": worst,
        "worst_qp": int(k[at]),
        "worst_qp_iterations": int(rows[at, 3]),
        "worst_instructions": int(rows[at, 1]),
        "median_instructions": int(np.median(rows[sel, 1])),
        # the same without forming the shifted bounds: DAQP's update, solve and U
        "median_daqp_cycles": solver[0],
        "worst_daqp_cycles": solver[1],
        "worst_daqp_qp": int(k[solver[2]]),
        "median_bounds_cycles": int(np.median(rows[sel, 2])),
        "max_iterations": int(rows[sel, 3].max()),
        "statuses": {str(n): int(c) for n, c in zip(names, counts)},
        "max_abs_err_vs_host_double": float(rows[sel, 4].max()),
        "max_abs_diff_vs_ours": float(rows[sel, 5].max()),
        "max_u_beyond_limits": float(rows[sel, 6].max()),
        "qps_beyond_limits": int((rows[sel, 6] > bound_tol).sum()),
        "worst_qp_top_functions": {name: int(cyc) for name, (_, cyc) in top},
    }


def daqp_markdown(result: dict) -> str:
    """Per mode: median and worst cycles with the QP where they peak, statuses, errors."""
    lines = ["| mode | QPs | median cycles | worst cycles | worst at QP | statuses | "
             "max abs err vs host double | max abs diff vs ours | max u beyond limit "
             "(QPs) |", "|---|---:|---:|---:|---:|---|---:|---:|---:|"]
    for name, s in result["by_mode"].items():
        statuses = ", ".join(f"{n} {c}" for n, c in s["statuses"].items())
        lines.append(f"| {name} | {s['qps']} | {s['median_cycles']:,} | "
                     f"{s['worst_cycles']:,} | {s['worst_qp']} | {statuses} | "
                     f"{s['max_abs_err_vs_host_double']:.2g} | "
                     f"{s['max_abs_diff_vs_ours']:.2g} | {s['max_u_beyond_limits']:.3g} "
                     f"({s['qps_beyond_limits']}) |")
    return "\n".join(lines)
