"""Stand-alone host C programs around a generated controller, for dynamic analysis.

Two programs, both rendered from templates and built with the C compiler alone:

* the test-vector program of ``rollmpc testvectors`` (bit-exact replay of the NumPy
  reference, :mod:`rollmpc_codegen.host.testvectors`);
* the soak program (``templates/host/soak.c.j2``): a long random closed loop with
  injected NaN/Inf inputs that checks the API contract at every sample.

Each can be built plain (for valgrind) or with AddressSanitizer + UndefinedBehavior-
Sanitizer, and run; :class:`RunResult` counts the sanitizer and valgrind reports.
"""
from __future__ import annotations

import math
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

from .build import EXACT_MATH, STRICT_WARNINGS
from ..pipeline import load_model
from ..codegen.output import write_output
from ..codegen.render import render_sources, render_template
from ..status import STATUS_NAMES

SANITIZE = ("-O1", "-g", "-fno-omit-frame-pointer",
            "-fsanitize=address,undefined,float-cast-overflow", "-fno-sanitize-recover=all")
VALGRIND_BUILD = ("-O2", "-g")
SANITIZER_PATTERNS = (r"runtime error:", r"ERROR: AddressSanitizer", r"ERROR: LeakSanitizer",
                      r"SUMMARY: UndefinedBehaviorSanitizer")


def soak_parameters(cfg) -> dict:
    """Reference span and noise of the soak loop, from the output bounds of the config."""
    finite = [abs(float(v)) for m in cfg.modes for v in (*m.y_min, *m.y_max) if math.isfinite(v)]
    span = 0.8 * min(finite) if finite else 10.0
    return {"ref_span": min(span, 60.0), "noise": 1e-3 * min(span, 60.0), "fault_period": 500}


def write_soak_program(config: str | Path, out_dir: Path, precision: str | None = None) -> Path:
    """Generated sources + ``<prefix>_soak.c`` in ``out_dir`` (codegen/output.py)."""
    model, ctx = load_model(config, precision)
    program = render_template(ctx, "host/soak.c.j2", **soak_parameters(model.config))
    return write_output({f"{ctx['prefix']}_soak.c": program, **render_sources(ctx)}, out_dir)


def compile_program(src_dir: Path, exe: Path, flags: tuple[str, ...], cc: str = "gcc") -> Path:
    """Compile every ``*.c`` of ``src_dir`` into ``exe`` with the strict warning set."""
    cmd = [cc, *flags, *STRICT_WARNINGS, *EXACT_MATH, f"-I{src_dir}",
           *map(str, sorted(Path(src_dir).glob("*.c"))), "-lm", "-o", str(exe)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or proc.stderr.strip():
        raise RuntimeError(f"{' '.join(cmd)}\n{proc.stderr}")
    return Path(exe)


@dataclass
class RunResult:
    returncode: int
    stdout: str
    stderr: str

    @property
    def sanitizer_reports(self) -> int:
        return sum(len(re.findall(p, self.stderr)) for p in SANITIZER_PATTERNS)

    @property
    def valgrind_errors(self) -> int | None:
        m = re.search(r"ERROR SUMMARY: (\d+) errors", self.stderr)
        return int(m.group(1)) if m else None

    def counts(self, pattern: str) -> tuple[int, ...]:
        m = re.search(pattern, self.stdout, re.M)
        return tuple(int(g) for g in m.groups()) if m else ()


def run_program(exe: Path, args: tuple[str, ...] = (), valgrind: str | None = None,
                timeout: float = 3600) -> RunResult:
    """Run ``exe`` (under valgrind's memcheck when ``valgrind`` is its path)."""
    cmd = [str(exe), *args]
    if valgrind:
        cmd = [valgrind, "--tool=memcheck", "--leak-check=full", "--error-exitcode=3",
               "--track-origins=yes", *cmd]
    env = {"ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0",
           "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1", "PATH": "/usr/bin:/bin"}
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    return RunResult(proc.returncode, proc.stdout, proc.stderr)


# the soak's last line: steps, faults, the count of each status P_step returns (in
# STATUS_NAMES' order, by name), violations
SOAK_SUMMARY = (r"^soak: (\d+) steps, (\d+) faults injected, statuses"
                + "".join(rf" {name}=(\d+)" for name in STATUS_NAMES.values())
                + r", (\d+) violations$")
VECTORS_SUMMARY = r"^(\d+) passed, (\d+) failed$"
