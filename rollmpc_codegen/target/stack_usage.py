"""Worst-case stack depth of the generated C, from GCC's own per-function figures.

Each generated source is compiled with ``-fstack-usage -fcallgraph-info=su``: GCC writes
the frame size of every function it emitted (``.su``) and the call graph after inlining
(``.ci``, VCG).  The worst path from each public entry point is the maximum over call
chains of the sum of the frames; a cycle (recursion) or an unbounded dynamic frame (VLA,
alloca) is an error, since the design forbids both.  Calls to library functions (sqrt,
memset) have no figure and count as 0 bytes; they are listed separately.
"""
from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from ..host.build import STRICT_WARNINGS

_NODE = re.compile(r'node: \{ title: "([^"]+)" label: "([^"]*)"')
_EDGE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')
_SIZE = re.compile(r"\\n(\d+) bytes \(([^)]*)\)")


@dataclass
class StackReport:
    frames: dict  # function ("file.c:name" when static) -> bytes
    qualifiers: dict  # function -> "static" | "dynamic,bounded" | "dynamic"
    calls: dict  # function -> set of callees
    external: set = field(default_factory=set)  # callees without a figure (library)

    def worst_path(self, entry: str) -> tuple[int, list[str]]:
        """(bytes, chain) of the deepest call chain from ``entry``."""
        memo: dict = {}

        def visit(f: str, stack: tuple) -> tuple[int, list[str]]:
            if f in stack:
                raise ValueError(f"recursion: {' -> '.join(stack + (f,))}")
            if f in memo:
                return memo[f]
            best = (0, [])
            for g in sorted(self.calls.get(f, ())):
                depth = visit(g, stack + (f,))
                if depth[0] > best[0]:
                    best = depth
            memo[f] = (self.frames.get(f, 0) + best[0], [f] + best[1])
            return memo[f]

        return visit(entry, ())

    @property
    def unbounded(self) -> list[str]:
        return sorted(f for f, q in self.qualifiers.items()
                      if "dynamic" in q and "bounded" not in q)


def analyse(src_dir: Path, work_dir: Path, cc: str = "gcc",
            flags: tuple[str, ...] = ("-O2",)) -> StackReport:
    """Compile every generated ``*.c`` of ``src_dir`` and merge the figures."""
    work_dir = Path(work_dir)
    work_dir.mkdir(parents=True, exist_ok=True)
    for c in sorted(Path(src_dir).glob("*.c")):
        if c.name.endswith("_data.c"):
            continue  # constant tables only: no function, nothing on the stack
        cmd = [cc, *flags, *STRICT_WARNINGS, "-ffp-contract=off", "-fstack-usage",
               "-fcallgraph-info=su", f"-I{src_dir}", "-c", str(c),
               "-o", str(work_dir / (c.stem + ".o"))]
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=work_dir)
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)}\n{proc.stderr}")
    frames, quals, calls = {}, {}, {}
    for ci in sorted(work_dir.glob("*.ci")):
        text = ci.read_text()
        for title, label in _NODE.findall(text):
            m = _SIZE.search(label)
            if m:
                frames[_short(title)] = int(m.group(1))
                quals[_short(title)] = m.group(2)
        for src, dst in _EDGE.findall(text):
            calls.setdefault(_short(src), set()).add(_short(dst))
    callees = set().union(*calls.values()) if calls else set()
    return StackReport(frames=frames, qualifiers=quals, calls=calls,
                       external=callees - set(frames))


def _short(title: str) -> str:
    """``/dir/file.c:func`` (a static function) -> ``file.c:func``; globals unchanged."""
    if ":" not in title:
        return title
    path, func = title.rsplit(":", 1)
    return f"{Path(path).name}:{func}"
