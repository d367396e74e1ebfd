"""The compiler flag sets the generated C must compile warning-free under, and a compile
of a tree file by file (each object's diagnostics apart)."""
from __future__ import annotations

import subprocess
from pathlib import Path

STRICT = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
          "-Wdouble-promotion", "-Wvla", "-Werror"]
# PX4's C flags and ArduPilot's frame limit (as firmware_stub/firmware.mk builds)
AUTOPILOT = ["-Wfloat-equal", "-Wcast-align", "-Wstrict-prototypes", "-Wbad-function-cast",
             "-Wnested-externs", "-fno-common", "-Wframe-larger-than=1300"]
CLANG_HINT = "apt-get install -y --no-install-recommends clang"
ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"


def compile_objects(cc: str, src: Path, flags: list[str], out: Path) -> subprocess.CompletedProcess:
    """Compile every .c of ``src`` into ``out``; the first failing or warning compile's
    result, else an empty success."""
    out.mkdir(parents=True, exist_ok=True)
    for c in sorted(src.glob("*.c")):
        obj = out / (c.stem + ".o")
        cmd = [cc, *flags, f"-I{src}", "-c", str(c), "-o", str(obj)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0 or proc.stderr.strip():
            return proc
    return subprocess.CompletedProcess(args=[], returncode=0, stdout="", stderr="")
