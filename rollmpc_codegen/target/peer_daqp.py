"""``rollmpc report --peer daqp``: DAQP's own C, in single precision, on the same emulated
Cortex-M4F, replaying the same QP sequence as the generated controller.

* **Source**: the C of DAQP's PyPI sdist (``pip download --no-binary :all: daqp==V``, V =
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

import hashlib
import re
import shutil
import subprocess
import sys
import tarfile
from importlib import metadata
from pathlib import Path

import numpy as np

from ..codegen.context import build_context
from ..codegen.render import render_template
from ..host.build import STRICT_WARNINGS, BuildError, build_host_controller
from ..host.build_cache import private_root, publish, staging, verified
from ..model.controller import ControllerModel
from ..qp.condense import solve_refined
from ..qp.peers import DAQP_INF, DaqpPeer, TwoSidedForm, c_stdout_silenced, peer_problems
from .build import (CORTEX_M4F, EMU_FLASH_KIB, EMU_RAM_KIB, EMU_STACK_BYTES, TARGET_CFLAGS,
                    TARGET_LDFLAGS, _run, image_sizes, require_cross_compiler)
from .emulate import CortexM4

SINGLE_PRECISION = "-DDAQP_SINGLE_PRECISION"
# DAQP's own files: our warnings, reported and counted but not errors
DAQP_WARNINGS = tuple(w for w in STRICT_WARNINGS if w != "-Werror")
# Settings changed from DAQP's defaults (name -> value), rendered into the harness.
# zero_tol (1e-11; it bounds blocking along a singular direction of the working set):
# 1e-14 gave the same statuses and errors on the UAV scenario and an inner-mode median of
# 354 k instead of 430 k cycles (worst 18.79 M instead of 18.68 M; outer mode unchanged)
SETTINGS = {"zero_tol": 1e-14}
# how E reaches DAQP (the set-up is not counted either way)
SETUPS = {
    "offline": "Cholesky factor of E in double, rounded once to float (problem_type 2)",
    "target": "E rounded to float, factored by DAQP's own float setup on the target",
}
# |u| beyond a limit by more than this fraction of the limit counts as a violation
BOUND_TOL = 1e-5


class DaqpSourceUnavailable(RuntimeError):
    """DAQP's sdist could not be downloaded (no network, no pip, unknown version)."""


def daqp_version() -> str:
    """The installed Python daqp: the sdist of the same version is compiled for the M4F."""
    try:
        return metadata.version("daqp")
    except metadata.PackageNotFoundError:
        raise DaqpSourceUnavailable("daqp is not installed: pip install "
                                    "'rollmpc-codegen[peers]'") from None


def daqp_sources(version: str, cache_dir: Path | None = None) -> Path:
    """``csrc/`` of DAQP's sdist: downloaded with pip and unpacked once into ``cache_dir``."""
    cache = (Path(cache_dir) if cache_dir is not None else private_root() / "daqp-sdist")
    top = f"daqp-{version}"
    csrc = cache / top / "csrc"
    if (csrc / "include" / "api.h").is_file():
        return csrc
    tarball = cache / f"{top}.tar.gz"
    if not tarball.is_file():
        cache.mkdir(parents=True, exist_ok=True)
        cmd = [sys.executable, "-m", "pip", "download", "--no-binary", ":all:", "--no-deps",
               "--disable-pip-version-check", f"daqp=={version}", "-d", str(cache)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0 or not tarball.is_file():
            raise DaqpSourceUnavailable(f"{' '.join(cmd)} failed:\n{proc.stderr.strip()}")
    tmp = cache / f"{top}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    with tarfile.open(tarball) as tar:
        members = [m for m in tar.getmembers() if m.name.startswith(f"{top}/csrc/")]
        tar.extractall(tmp, members=members, filter="data")
    shutil.rmtree(cache / top, ignore_errors=True)
    (tmp / top).rename(cache / top)
    shutil.rmtree(tmp, ignore_errors=True)
    return csrc


def exit_flags(csrc: Path) -> dict[int, str]:
    """DAQP's exit flags (``DAQP_EXIT_*`` of its constants.h): value -> lower-case name."""
    text = (csrc / "include" / "constants.h").read_text()
    return {int(v): name.lower() for name, v in
            re.findall(r"#define DAQP_EXIT_(\w+) \(?(-?\d+)\)?", text)}


# ----------------------------------------------------------------------------- data
def mode_arrays(qp, factored: bool = True) -> dict[str, np.ndarray]:
    """The harness arrays of one mode, in double (rounded once when written to the target).

    H: the packed upper Cholesky factor of E (by rows) if ``factored``, else E; A: the
    general rows; theta0 = Tx x + Tr r + t0; per DAQP row the bounds cu + Wu x (upper) and
    cl + Wl x (lower), +/- DAQP_INF where a side is absent.
    """
    form = TwoSidedForm(qp)
    R = np.linalg.cholesky(qp.E).T
    up = np.concatenate((form.bound_upper, form.general_upper))
    lo = np.concatenate((form.bound_lower, form.general_lower))
    has_up, has_lo = (up >= 0)[:, None], (lo >= 0)[:, None]
    t0 = (np.zeros(qp.n) if qp.f_const is None
          else solve_refined(qp.E, -qp.f_const[:, None])[:, 0])
    return {
        "H": np.concatenate([R[i, i:] for i in range(qp.n)]) if factored else qp.E,
        "A": form.A,
        "Tx": qp.Kx, "Tr": qp.Kr, "t0": t0,
        "Wu": np.where(has_up, qp.W[np.maximum(up, 0)], 0.0),
        "cu": np.where(up >= 0, qp.c[np.maximum(up, 0)], DAQP_INF),
        "Wl": np.where(has_lo, -qp.W[np.maximum(lo, 0)], 0.0),
        "cl": np.where(lo >= 0, -qp.c[np.maximum(lo, 0)], -DAQP_INF),
    }


def harness_context(model: ControllerModel, version: str, setup: str = "offline") -> dict:
    """What ``daqp_harness.c.j2`` and ``link.ld.j2`` see."""
    problems, _ = peer_problems([mm.qp for mm in model.modes])
    modes = []
    for mm, qp in zip(model.config.modes, problems):
        general = TwoSidedForm(qp).A.shape[0]
        modes.append({"name": mm.name, "n": qp.n, "nx": qp.nx, "nr": qp.Kr.shape[1],
                      "ms": qp.n, "m": qp.n + general})
    # DAQP's setup allocations: about 1.5 n^2 + n m floats a mode; twice that, plus slack
    heap = sum(8 * (2 * (md["n"] + 2) ** 2 + md["n"] * md["m"] + 16 * md["m"]) + 4096
               for md in modes)
    return {"prefix": f"{model.config.prefix}_daqp", "config_prefix": model.config.prefix,
            "precision": "float", "daqp_version": version, "modes": modes,
            "heap_bytes": heap, "settings": SETTINGS, "factored": setup == "offline",
            "setup": SETUPS[setup],
            "n_max": max(md["n"] for md in modes), "nx_max": max(md["nx"] for md in modes),
            "nr_max": max(md["nr"] for md in modes)}


# ----------------------------------------------------------------------------- build
def _compile_relaxed(cmd: list[str]) -> str:
    """Compile one of DAQP's files; its warnings are returned, not errors."""
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise BuildError(f"{' '.join(cmd)}\n{proc.stderr}")
    return proc.stderr


def build_daqp_target(ctx: dict, csrc: Path, build_root: Path) -> tuple[Path, dict]:
    """Cross-compile DAQP and the harness, link the image; cached by content hash.

    Returns (elf, {warning flag: count}) for the warnings DAQP's own files raised.
    """
    cc = require_cross_compiler()
    p = ctx["prefix"]
    harness = render_template(ctx, "target/daqp_harness.c.j2")
    ld = render_template(ctx, "target/link.ld.j2", flash_kib=EMU_FLASH_KIB,
                         ram_kib=EMU_RAM_KIB, stack_bytes=EMU_STACK_BYTES)
    daqp_c = sorted((csrc / "src").glob("*.c"))
    base = [*CORTEX_M4F, *TARGET_CFLAGS, SINGLE_PRECISION]
    digest = hashlib.sha256("\n".join([cc, *base, *DAQP_WARNINGS, *STRICT_WARNINGS,
                                       harness, ld]).encode())
    for path in [*daqp_c, *sorted((csrc / "include").glob("*.h"))]:
        digest.update(path.read_bytes())
    key = digest.hexdigest()
    root = private_root(build_root)
    out, elf_name = root / f"target-{p}-{key[:16]}", f"{p}_target.elf"
    elf = verified(out, elf_name, key)
    if elf is not None:
        return elf, _warning_counts((out / "daqp_warnings.txt").read_text())
    with staging(root, out.name) as tmp:
        (tmp / f"{p}_target_harness.c").write_text(harness)
        (tmp / f"{p}_target.ld").write_text(ld)
        warnings = []
        objs = []
        for src in daqp_c:
            objs.append(tmp / f"daqp_{src.stem}.o")
            warnings.append(_compile_relaxed([cc, *base, *DAQP_WARNINGS,
                                              f"-I{csrc / 'include'}", "-c", str(src),
                                              "-o", str(objs[-1])]))
        objs.append(tmp / f"{p}_target_harness.o")
        # -isystem: DAQP's headers are not held to our warnings, the harness itself is
        _run([cc, *base, *STRICT_WARNINGS, "-isystem", str(csrc / "include"), "-c",
              str(tmp / f"{p}_target_harness.c"), "-o", str(objs[-1])])
        _run([cc, *CORTEX_M4F, *TARGET_LDFLAGS, "-T", str(tmp / f"{p}_target.ld"),
              f"-Wl,-Map={tmp / (p + '_target.map')}", "-o", str(tmp / elf_name),
              *map(str, objs), "-lm", "-lgcc"])
        (tmp / "daqp_warnings.txt").write_text("".join(warnings))
        elf = publish(tmp, out, elf_name, key)
    return elf, _warning_counts("".join(warnings))


def _warning_counts(text: str) -> dict[str, int]:
    counts: dict[str, int] = {}
    for flag in re.findall(r"warning: .*\[(-W[\w-]+)\]", text):
        counts[flag] = counts.get(flag, 0) + 1
    return dict(sorted(counts.items()))


# ----------------------------------------------------------------------------- target
class DaqpOnTarget:
    """The DAQP image on the emulated M4F with every mode's workspace set up (not counted)."""

    def __init__(self, elf: Path, ctx: dict, arrays: list[dict]):
        self.p, self.modes = ctx["prefix"], ctx["modes"]
        self.em = CortexM4(elf)
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
    through DAQP on the emulated M4F; per mode: median and worst cycles, the QP where
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
        "cflags": " ".join([*CORTEX_M4F, *TARGET_CFLAGS, SINGLE_PRECISION]),
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
