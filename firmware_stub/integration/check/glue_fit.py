#!/usr/bin/env python3
"""Can the autopilot glue fly this generated tree?  One line before any build.

    python3 firmware_stub/integration/check/glue_fit.py TREE [--design-header DIR]

The glue (integration/common/rollglue.c and the PX4/ArduPilot adapters) flies roll
loops: one output (the roll angle), one or two aileron pairs, a schedule on the roll rate,
on the airspeed or none. Read from the tree's <prefix>_config.h, the file the C reads;
exit 0 if it fits, else one line naming what does not and exit 2 (`make firmware
FW_GEN=TREE` serves any design with the generic main instead). --design-header writes
rollglue_design.h (the prefix macros) into DIR for a build that cannot pass -D flags
(ArduPilot's flat library).
"""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

SIGNALS = ("ROLL_RATE", "AIRSPEED")   # what rollglue.c can feed (schedule_value)
MAX_PAIRS = 2                         # the adapters' RMPC_IN_* and RMPC_OUT_* pairs


def config_header(tree: Path) -> Path:
    found = sorted(tree.glob("*_config.h"))
    if len(found) != 1:
        raise ValueError(f"{tree}: no single <prefix>_config.h, not a generated tree "
                         "(rollmpc generate CONFIG -o DIR)")
    return found[0]


def design(tree: Path) -> tuple[str, dict[str, str]]:
    """(prefix, {macro without the prefix: value}) of the tree's config header."""
    header = config_header(tree)
    prefix = header.name[: -len("_config.h")]
    upper = prefix.upper()
    macros = dict(re.findall(rf"^#define {upper}(_\w+) +(\S+)", header.read_text(), re.M))
    return prefix, macros


def unfit(tree: Path) -> str | None:
    """Why the glue cannot fly the tree (None: it can)."""
    try:
        prefix, m = design(tree)
    except ValueError as exc:
        return str(exc)
    why = []
    if m.get("_N_OUTPUTS") != "1":
        why.append(f"{m.get('_N_OUTPUTS')} outputs (the glue feeds one, the roll angle)")
    if not 1 <= int(m.get("_N_ACTUATORS", "0")) <= MAX_PAIRS:
        why.append(f"{m.get('_N_ACTUATORS')} actuators (the adapters map one or two aileron pairs)")
    signal = [s for s in re.findall(r"^_SCHEDULE_SIGNAL_(\w+)$", "\n".join(m), re.M)]
    if m.get("_N_SCHEDULE", "0") != "0" and not set(signal) & set(SIGNALS):
        why.append(f"scheduled on {', '.join(signal).lower() or '?'} (the glue feeds roll_rate "
                   "or airspeed)")
    if not why:
        return None
    return (f"{tree}: the autopilot glue cannot fly {prefix}: {'; '.join(why)}. "
            f"`make firmware FW_GEN={tree}` builds the generic firmware main for it")


def design_header(tree: Path) -> str:
    prefix, _ = design(tree)
    return (f"/* rollglue_design.h: the generated controller the glue runs (glue_fit.py) */\n"
            f"#define ROLLGLUE_PREFIX {prefix}\n#define ROLLGLUE_PREFIX_UPPER {prefix.upper()}\n"
            f"#define ROLLGLUE_HEADER \"{prefix}.h\"\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tree", type=Path)
    ap.add_argument("--design-header", type=Path, metavar="DIR")
    args = ap.parse_args()
    reason = unfit(args.tree)
    if reason:
        print(f"glue_fit: {reason}", file=sys.stderr)
        return 2
    if args.design_header:
        (args.design_header / "rollglue_design.h").write_text(design_header(args.tree))
    return 0


if __name__ == "__main__":
    sys.exit(main())
