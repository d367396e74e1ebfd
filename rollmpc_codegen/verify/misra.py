"""cppcheck with its MISRA C 2012 addon over generated C, checked against deviations.

``cppcheck --addon=misra`` reports rule numbers (the rule texts are licensed, so the
messages are generic).  Every finding must be covered by a recorded deviation
(:data:`rollmpc_codegen.codegen.misra_deviations.DEVIATIONS`, which the generated README
lists): the rule, the generated files it applies to (a glob on the file name without the
prefix, e.g. ``_solver.c``, or ``*``), a classification and the reason.  cppcheck's own warnings (``--enable=warning,portability``) have no deviations:
any of them fails the check.  A finding nobody has justified is "unjustified": the
check fails on it, so a template change that introduces a new kind of finding must
either fix it or add a reasoned deviation.
"""
from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

from ..codegen.misra_deviations import DEVIATIONS

TEMPLATE = "{file}\t{line}\t{severity}\t{id}\t{message}"


@dataclass(frozen=True)
class Finding:
    file: str  # generated file name
    line: int
    rule: str  # "12.1" for MISRA, else cppcheck's id ("nullPointer", ...)
    severity: str
    message: str

    @property
    def misra(self) -> bool:
        return re.fullmatch(r"\d+\.\d+", self.rule) is not None


def run_cppcheck(src_dir: Path, cppcheck: str = "cppcheck", jobs: int = 1) -> list[Finding]:
    """Findings of cppcheck + the MISRA addon on every generated source of ``src_dir``."""
    src_dir = Path(src_dir)
    cmd = [cppcheck, "--addon=misra", "--std=c99", "--language=c", "-q",
           "--enable=warning,portability", "--suppress=missingIncludeSystem",
           f"-j{jobs}", f"--template={TEMPLATE}", f"-I{src_dir}",
           *map(str, sorted(src_dir.glob("*.c")))]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    findings = []
    for line in proc.stderr.splitlines():
        parts = line.split("\t")
        if len(parts) != 5:
            if line.strip():
                raise RuntimeError(f"unexpected cppcheck output: {line}")
            continue
        file, lineno, severity, ident, message = parts
        rule = ident.removeprefix("misra-c2012-")
        findings.append(Finding(Path(file).name, int(lineno or 0), rule, severity, message))
    return findings


def unjustified(findings: list[Finding], prefix: str,
                deviations=DEVIATIONS) -> list[Finding]:
    """The findings no deviation covers."""
    return [f for f in findings
            if not any(d.covers(f.rule, f.file, prefix) for d in deviations)]


def by_rule(findings: list[Finding]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for f in findings:
        counts[f.rule] = counts.get(f.rule, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: [int(p) if p.isdigit() else p
                                                       for p in re.split(r"\.", kv[0])]))
