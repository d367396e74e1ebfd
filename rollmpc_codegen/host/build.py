"""Stage 8: compile generated C on the host and load it through cffi (ABI mode).

The host build uses ``-ffp-contract=off`` so that no multiply-add is fused: every
operation rounds exactly as in the NumPy reference.  Builds are cached in a private
directory and checked before they are loaded (:mod:`.build_cache`).
"""
from __future__ import annotations

import hashlib
import subprocess
from dataclasses import dataclass
from pathlib import Path

import cffi
import numpy as np

from ..codegen.build_flags import EXACT_MATH, STRICT_WARNINGS  # noqa: F401  (re-exported)
from ..codegen.render import render_template
from .build_cache import private_root, publish, source_dir, staging, verified


class BuildError(RuntimeError):
    """The C compiler failed; the message carries its output."""


def c_sources(src_dir: Path, prefix: str) -> list[Path]:
    return sorted(Path(src_dir).glob(f"{prefix}*.c"))


def compile_shared(ctx: dict, src_dir: Path, build_dir: Path, compiler: str = "gcc",
                   opt: str = "-O2", extra: tuple[str, ...] = (), timer: bool = True) -> Path:
    """Build ``lib<prefix>.so`` from the generated sources in ``src_dir``.

    The library lands in ``build_dir/<hash of sources and flags>/`` so repeated builds of
    the same code are free; a cached library is reused only if its record verifies.
    """
    root = private_root(build_dir)
    prefix = ctx["prefix"]
    sources = c_sources(src_dir, prefix)
    flags = [opt, "-fPIC", "-shared", *STRICT_WARNINGS, *EXACT_MATH, *extra]
    digest = hashlib.sha256()
    for path in sources + sorted(Path(src_dir).glob(f"{prefix}*.h")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    digest.update(" ".join([compiler, *flags, str(timer)]).encode())
    key = digest.hexdigest()
    out, lib_name = root / key[:16], f"lib{prefix}.so"
    cached = verified(out, lib_name, key)
    if cached is not None:
        return cached
    with staging(root, out.name) as tmp:
        extra_src = []
        if timer:
            (tmp / f"{prefix}_host_timer.h").write_text(render_template(ctx, "host/timer.h.j2"))
            timer_c = tmp / f"{prefix}_host_timer.c"
            timer_c.write_text(render_template(ctx, "host/timer.c.j2"))
            extra_src.append(timer_c)
            # the feature macro must precede the force-included header (it pulls in stdint.h)
            flags += ["-D_POSIX_C_SOURCE=199309L",
                      "-include", str(tmp / f"{prefix}_host_timer.h"), f"-I{tmp}"]
        cmd = [compiler, *flags, f"-I{src_dir}", "-o", str(tmp / lib_name),
               *map(str, sources), *map(str, extra_src), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise BuildError(f"{' '.join(cmd)}\n{proc.stderr}")
        return publish(tmp, out, lib_name, key)


def c_values(values, dtype) -> np.ndarray:
    """``values`` as a contiguous array of the C's real type. In float a value beyond its
    range becomes +-inf, which the C reports (NONFINITE_INPUT, docs/reliability.md): the
    cast is the documented path, so numpy's overflow warning would only alarm."""
    with np.errstate(over="ignore"):
        return np.ascontiguousarray(values, dtype)


@dataclass
class HostController:
    """A loaded host build of one generated controller."""

    ffi: cffi.FFI
    lib: object
    ctx: dict

    @classmethod
    def load(cls, ctx: dict, lib_path: Path) -> "HostController":
        ffi = cffi.FFI()
        ffi.cdef(render_template(ctx, "host/cffi_cdef.h.j2"))
        lib = ffi.dlopen(str(lib_path))
        obj = cls(ffi=ffi, lib=lib, ctx=ctx)
        obj.prefix = ctx["prefix"]
        obj.dtype = np.float64 if ctx["real"] == "double" else np.float32
        obj._fn = {name: getattr(lib, f"{obj.prefix}_{name}") for name in
                   ("ctrl_size", "init", "step", "observe", "solve_qp", "last_info",
                    "status_message")
                   + (("set_bounds", "get_bounds") if ctx.get("runtime_bounds") else ())
                   + (("set_signal_bounds", "get_signal_bounds")
                      if ctx.get("runtime_bounds") and ctx.get("has_signal_rows") else ())}
        obj.ctrl = ffi.new("char[]", obj._fn["ctrl_size"]())
        obj.u = np.zeros(ctx["n_actuators"], obj.dtype)
        obj.init()
        return obj

    def _ptr(self, arr: np.ndarray):
        return self.ffi.cast(f"{self.prefix}_real *", self.ffi.from_buffer(arr))

    def _sched_ptr(self, sched):
        """A P_real pointer to the scheduling signal (NULL when there is none), and the
        array behind it (keep it alive across the call)."""
        if sched is None or not len(sched):
            return self.ffi.NULL, None
        arr = c_values(sched, self.dtype)
        return self._ptr(arr), arr

    def init(self) -> None:
        self._fn["init"](self.ctrl)

    def instance(self) -> bytes:
        """The controller instance's bytes (``P_ctrl``: its whole state)."""
        return bytes(self.ffi.buffer(self.ctrl))

    def step(self, y, sched, r) -> tuple[int, np.ndarray]:
        y = c_values(y, self.dtype)
        r = c_values(r, self.dtype)
        sp, _keep = self._sched_ptr(sched)
        u = np.zeros(self.ctx["n_actuators"], self.dtype)
        status = self._fn["step"](self.ctrl, self._ptr(y), sp, self._ptr(r), self._ptr(u))
        return status, u

    def observe(self, y, sched, u_applied) -> int:
        """``P_observe``: track the plant under another controller's command."""
        y = c_values(y, self.dtype)
        u = c_values(u_applied, self.dtype)
        sp, _keep = self._sched_ptr(sched)
        return self._fn["observe"](self.ctrl, self._ptr(y), sp, self._ptr(u))

    def solve_qp(self, mode: int, x, r) -> tuple[int, np.ndarray, int]:
        x = c_values(x, self.dtype)
        r = c_values(r, self.dtype)
        n = self.ctx["modes"][mode]["n"] if 0 <= mode < len(self.ctx["modes"]) else 1
        U = np.zeros(max(n, 1), self.dtype)
        its = self.ffi.new("int *")
        status = self._fn["solve_qp"](self.ctrl, mode, self._ptr(x), self._ptr(r), self._ptr(U), its)
        return status, U, its[0]

    def _bound_ptr(self, values):
        """A P_real pointer to a copy of ``values`` (None -> NULL), and the copy."""
        if values is None:
            return self.ffi.NULL, None
        arr = c_values(np.atleast_1d(values), self.dtype)
        return self._ptr(arr), arr

    def set_bounds(self, mode: int, u_min, u_max, y_min, y_max) -> int:
        """``P_set_bounds`` (configs with ``runtime_bounds: true``); None passes NULL."""
        ptrs = [self._bound_ptr(v) for v in (u_min, u_max, y_min, y_max)]
        return self._fn["set_bounds"](self.ctrl, mode, *(p for p, _ in ptrs))

    def get_bounds(self, mode: int) -> tuple[int, dict]:
        """``P_get_bounds``: (status, {u_min, u_max, y_min, y_max}) of one mode."""
        nu = max(m["nu"] for m in self.ctx["modes"])
        nu = self.ctx["modes"][mode]["nu"] if 0 <= mode < len(self.ctx["modes"]) else nu
        out = {"u_min": np.zeros(nu, self.dtype), "u_max": np.zeros(nu, self.dtype),
               "y_min": np.zeros(self.ctx["n_outputs"], self.dtype),
               "y_max": np.zeros(self.ctx["n_outputs"], self.dtype)}
        status = self._fn["get_bounds"](self.ctrl, mode, *(self._ptr(v) for v in out.values()))
        return status, out

    def set_signal_bounds(self, mode: int, z_min, z_max) -> int:
        """``P_set_signal_bounds`` (run-time bounds with signal rows); None passes NULL."""
        ptrs = [self._bound_ptr(v) for v in (z_min, z_max)]
        return self._fn["set_signal_bounds"](self.ctrl, mode, *(p for p, _ in ptrs))

    def get_signal_bounds(self, mode: int) -> tuple[int, dict]:
        """``P_get_signal_bounds``: (status, {z_min, z_max}) of one mode."""
        live = self.ctx["modes"][mode]["nsig_live"] if 0 <= mode < len(self.ctx["modes"]) else 1
        out = {k: np.zeros(max(live, 1), self.dtype) for k in ("z_min", "z_max")}
        status = self._fn["get_signal_bounds"](self.ctrl, mode,
                                               *(self._ptr(v) for v in out.values()))
        return status, {k: v[:live] for k, v in out.items()}

    def info(self) -> dict:
        """``P_last_info()``: every member of P_info by name (info_struct.py)."""
        p = self._fn["last_info"](self.ctrl)
        return {f["name"]: float(getattr(p, f["name"])) if f["real"] else getattr(p, f["name"])
                for f in self.ctx["info_fields"]}

    def status_message(self, status: int) -> str:
        return self.ffi.string(self._fn["status_message"](status)).decode()


def build_host_controller(ctx: dict, build_root: Path | None = None, compiler: str = "gcc",
                          opt: str = "-O2", extra: tuple[str, ...] = ()) -> HostController:
    """Render ``ctx`` into the build cache (the default root when None), compile it and load it."""
    from ..codegen.render import render_sources

    root = private_root(build_root)
    files = render_sources(ctx)
    digest = hashlib.sha256("".join(files[k] for k in sorted(files)).encode()).hexdigest()[:16]
    src = source_dir(root, f"src-{ctx['prefix']}-{digest}", files)
    lib = compile_shared(ctx, src, root, compiler=compiler, opt=opt, extra=extra)
    return HostController.load(ctx, lib)
