"""The controller instance as ``rollmpc report`` compares it: host against target, every
step, member by member.

The commands agree bit for bit when the two builds only share the arithmetic; the
instance's bytes agree only when they also run the same kernels (a dual factor that
breaks down leaves other partial rows in ``work.chol`` with the wide kernels than with
the plain ones: templates/internal.h.j2, ``P_WIDE_KERNELS``). So the target image states
its layout and its kernel choice (``P_target_layout``, ``P_target_members`` of
templates/target/harness.c.j2), the host build of the report is compiled with the same
kernels, and each step's instance is compared as one digest per member
(:meth:`StateLayout.digests`): the first step that differs is named with its members.

The member names are read from the rendered ``P.h`` (its ``P_ctrl`` and ``P_work``
structs), their offsets from the target's ``offsetof``: the struct is declared once,
in templates/api.h.j2.  The diagnostics (``info``, with the host's solve time) are left
out, and a real that is NaN counts as one NaN whatever its sign and payload (x86 makes
-NaN where the M4F makes +NaN; a diverged run can leave NaN in a state it no longer
reads).
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass

import numpy as np

from ..codegen.build_flags import kernel_flags

LAYOUT_WORDS = 5  # P_target_layout: sizeof ctrl, sizeof real, offsetof info, sizeof info, wide
INFO_MEMBER = "info"
WORK_MEMBER = "work"


def _struct_body(header: str, closing: str) -> str:
    end = header.index(closing)
    return header[header.rindex("typedef struct", 0, end):end]


def _member_names(body: str) -> list[str]:
    body = re.sub(r"/\*.*?\*/", "", body, flags=re.S)
    body = body[body.index("{") + 1:]
    body = re.sub(r"union\s*\{[^{}]*\}", "", body)  # a union is one member, by its name
    return re.findall(r"(\w+)\s*(?:\[[^\]]*\]\s*)*;", body)


def ctrl_members(header: str, prefix: str) -> list[str]:
    """The members of ``P_ctrl`` in declaration order, ``work`` expanded into its own
    (``work.chol``, ...): the designators the harness takes ``offsetof`` of."""
    top = _member_names(_struct_body(header, f"}} {prefix}_ctrl;"))
    work = [f"{WORK_MEMBER}.{m}" for m in _member_names(_struct_body(header, f"}} {prefix}_work;"))]
    out = []
    for name in top:
        out += work if name == WORK_MEMBER else [name]
    return out


@dataclass(frozen=True)
class StateLayout:
    """The instance of one target image: its size, real type, diagnostics' place, the
    kernels its compiler chose, and each member's byte range."""

    ctrl_size: int
    real: np.dtype
    info_at: int
    info_size: int
    wide_kernels: bool
    members: tuple[tuple[str, int, int], ...]  # (name, offset, end), in offset order

    @classmethod
    def from_words(cls, layout: np.ndarray, names: list[str], offsets: np.ndarray,
                   real: np.dtype) -> "StateLayout":
        ctrl_size, real_size, info_at, info_size, wide = (int(v) for v in layout)
        if real_size != real.itemsize:
            raise RuntimeError(f"the target's real has {real_size} B, the tree's {real.itemsize}")
        order = sorted(zip((int(o) for o in offsets), names))
        ends = [o for o, _ in order[1:]] + [ctrl_size]
        members = tuple((name, at, end) for (at, name), end in zip(order, ends)
                        if name != INFO_MEMBER)
        return cls(ctrl_size, real, info_at, info_size, bool(wide), members)

    @property
    def kernels(self) -> str:
        return "wide" if self.wide_kernels else "plain"

    def host_flags(self, ctx: dict) -> tuple[str, ...]:
        """The host build's flags that run the target's kernels."""
        return kernel_flags(ctx["prefix"], self.wide_kernels)

    def canonical(self, state: bytes) -> np.ndarray:
        """The instance's bytes, diagnostics zeroed, every NaN real one canonical NaN."""
        if len(state) != self.ctrl_size:
            raise RuntimeError(f"an instance of {len(state)} B, the target's has "
                               f"{self.ctrl_size} B")
        raw = np.frombuffer(state, np.uint8).copy()
        raw[self.info_at:self.info_at + self.info_size] = 0
        whole = len(raw) - len(raw) % self.real.itemsize
        words = raw[:whole].view(self.real)
        words[np.isnan(words)] = np.nan
        return raw

    def digests(self, state: bytes) -> tuple[bytes, ...]:
        """One short digest per member of the canonical instance."""
        raw = self.canonical(state)
        return tuple(hashlib.blake2b(raw[at:end].tobytes(), digest_size=8).digest()
                     for _name, at, end in self.members)

    def differing(self, host: tuple[bytes, ...], target: tuple[bytes, ...]) -> list[str]:
        """The members whose digests differ."""
        return [m[0] for m, a, b in zip(self.members, host, target) if a != b]

