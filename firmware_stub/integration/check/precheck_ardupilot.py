#!/usr/bin/env python3
"""Compile the rollmpc ArduPilot glue against a real ArduPilot tree, with waf's own flags.

    python3 firmware_stub/integration/check/precheck_ardupilot.py --ardupilot /path/to/ardupilot \
        [--modules DIR] [--gen generated/uav_roll_f32] [--build build/check/ardupilot] \
        [--python PY] [--boards sitl,MatekF405]

Without --ardupilot (or $ARDUPILOT_TREE) it prints a hint and exits 0 (skipped). The tree
is only read: the build directory gets a shadow of it (symlinks) in which ArduPlane/,
ArduCopter/ and libraries/AC_CustomControl/ are copies with arduplane.patch and
custom_control.patch applied, the Copter backend copied in, and libraries/AP_RollMPC/ laid
out as firmware_stub/README.md says (the adapter, the glue core, the generated controller).

ArduPilot's own waf (modules/waf) configures the shadow for each board with
`--Werror --enable-custom-controller`: sitl (the host's gcc) and MatekF405 (an STM32F405
flight controller: Cortex-M4F, ChibiOS, arm-none-eabi-gcc, -Wframe-larger-than=1300). Every
flag, define and include path is read back from waf's c4che, and each unit is compiled
with waf's command line for its object, from waf's build directory: the vehicle sources
with the vehicle's defines (get_legacy_defines, ArduCopter's FRAME_CONFIG), the library
objects without, C++ with CXXFLAGS (which carry -include ap_config.h), C with CFLAGS.
What waf generates before compiling is generated the way waf does: hwdef.h and
ap_config.h (configure), the MAVLink headers (pymavlink's mavgen from modules/mavlink, the
options of Tools/ardupilotwaf/mavgen.py), the DroneCAN headers (dronecan_dsdlc, as
dronecangen.py runs it), ap_version.h (the tree's commit) and on ChibiOS the include_dirs
of ChibiOS's make (`make pass`, chibios.py). Nothing is stubbed; the DroneCAN include
paths are given to both boards (waf gives them to CAN boards only).

Submodules come from the tree's modules/ or from --modules (same layout): waf, mavlink
(with pymavlink), DroneCAN/{DSDL,dronecan_dsdlc,libcanard,pydronecan}; ChibiOS and lwip
as well for the ChibiOS board. --python names an interpreter with empy 3, lxml and future
(the generators). Exit status 0 = every unit compiled without a diagnostic.
"""
from __future__ import annotations

import argparse
import ast
import os
import re
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from common import Report, compile_unit, copy_tree, repo_root, run, tree_commit  # noqa: E402

INTEGRATION = repo_root() / "firmware_stub/integration"
AP_GLUE = INTEGRATION / "ardupilot"
PATCHES = [AP_GLUE / "plane/arduplane.patch", AP_GLUE / "copter/custom_control.patch"]
SUBMODULES = ["waf", "mavlink", "DroneCAN/DSDL", "DroneCAN/dronecan_dsdlc",
              "DroneCAN/libcanard", "DroneCAN/pydronecan"]
BOARD_SUBMODULES = {"sitl": [], "MatekF405": ["ChibiOS", "lwip"]}
COPIED = ["ArduPlane", "ArduCopter"]            # whole directories the patches touch
COPIED_LIBRARIES = ["AC_CustomControl"]
# (unit, vehicle whose program compiles it; None = a library object)
UNITS = [("ArduPlane/Attitude.cpp", "ArduPlane"), ("ArduPlane/servos.cpp", "ArduPlane"),
         ("ArduPlane/Plane.cpp", "ArduPlane"), ("ArduPlane/Parameters.cpp", "ArduPlane"),
         ("ArduCopter/Parameters.cpp", "ArduCopter"),
         ("libraries/AC_CustomControl/AC_CustomControl.cpp", None),
         ("libraries/AC_CustomControl/AC_CustomControl_RollMPC.cpp", None),
         ("libraries/AP_RollMPC/AP_RollMPC.cpp", None),
         ("libraries/AP_RollMPC/rollglue_ap.c", None), ("libraries/AP_RollMPC/rollglue.c", None)]
VEHICLE_DEFINES = {"ArduPlane": [], "ArduCopter": ["FRAME_CONFIG=MULTICOPTER_FRAME"]}


def submodule_sources(tree: Path, modules: Path | None, boards: list[str]) -> dict[str, Path]:
    """Where each needed submodule is: the tree's own checkout, else --modules."""
    found, missing = {}, []
    for name in SUBMODULES + [m for b in boards for m in BOARD_SUBMODULES[b]]:
        for base in (tree / "modules", modules):
            if base is not None and (base / name).is_dir() and any((base / name).iterdir()):
                found[name] = base / name
                break
        else:
            missing.append(name)
    if missing:
        sys.exit(f"precheck_ardupilot: submodules missing: {', '.join(missing)} (run "
                 "`git submodule update --init --recursive` in the tree, or give --modules DIR)")
    return found


def shadow(tree: Path, build: Path, submodules: dict[str, Path], gen: Path) -> Path:
    """The tree as symlinks, with real copies where the patches and our files go."""
    root = build / "ardupilot"
    root.mkdir(parents=True)
    skip = {"libraries", "modules", "build", ".git", *COPIED}
    for entry in tree.iterdir():
        if entry.name not in skip:
            (root / entry.name).symlink_to(entry)
    for name in COPIED:
        shutil.copytree(tree / name, root / name, symlinks=True)
    (root / "libraries").mkdir()
    for entry in (tree / "libraries").iterdir():
        if entry.name not in COPIED_LIBRARIES:
            (root / "libraries" / entry.name).symlink_to(entry)
    for name in COPIED_LIBRARIES:
        shutil.copytree(tree / "libraries" / name, root / "libraries" / name, symlinks=True)
    for name, src in submodules.items():
        (root / "modules" / name).parent.mkdir(parents=True, exist_ok=True)
        (root / "modules" / name).symlink_to(src)
    for patch in PATCHES:
        run(["patch", "-p1", "-d", str(root), "-i", str(patch)])
    for backend in (AP_GLUE / "copter").glob("AC_CustomControl_RollMPC.*"):
        shutil.copy(backend, root / "libraries/AC_CustomControl")
    lib = root / "libraries/AP_RollMPC"  # firmware_stub/README.md: one flat library
    for src in (AP_GLUE / "AP_RollMPC", INTEGRATION / "common", gen):
        copy_tree(src, lib)
    return root


def read_env(path: Path) -> dict:
    """waf's ConfigSet file (KEY = python literal per line)."""
    env = {}
    for line in path.read_text().splitlines():
        key, sep, value = line.partition(" = ")
        if sep and not line.startswith("#"):
            env[key] = ast.literal_eval(value)
    return env


def configure(root: Path, board: str, python: str) -> dict:
    run([python, "modules/waf/waf-light", "configure", "--board", board, "--Werror",
         "--enable-custom-controller"], cwd=root)
    return read_env(root / "build/c4che" / f"{board}_cache.py")


def generate_mavlink(root: Path, out: Path, python: str) -> Path:
    """Tools/ardupilotwaf/mavgen.py's task: all.xml, C, wire protocol 2.0, no validation."""
    dest = out / "libraries/GCS_MAVLink/include/mavlink/v2.0"
    code = ("import sys; sys.path.insert(0, sys.argv[1])\n"
            "from pymavlink.generator import mavgen\n"
            "class O: language = 'C'; wire_protocol = '2.0'; validate = False; output = sys.argv[2]\n"
            "sys.exit(0 if mavgen.mavgen(O(), [sys.argv[3]]) else 1)\n")
    mavlink = root / "modules/mavlink"
    run([python, "-c", code, str(mavlink), str(dest),
         str(mavlink / "message_definitions/v1.0/all.xml")])
    return dest


def generate_dronecan(root: Path, out: Path, python: str) -> Path:
    """Tools/ardupilotwaf/dronecangen.py's command over wscript's DSDL directories."""
    dest = out / "modules/DroneCAN/libcanard/dsdlc_generated"
    dirs = sorted(d for pattern in ("modules/DroneCAN/DSDL/[a-z]*", "libraries/AP_DroneCAN/dsdl/[a-z]*")
                  for d in root.glob(pattern) if d.is_dir())
    run([python, str(root / "modules/DroneCAN/dronecan_dsdlc/dronecan_dsdlc.py"), f"-O{dest}",
         *map(str, dirs)])
    return dest


def write_version(out: Path, root: Path, commit: str) -> None:
    """ap_version.h as wscript's write_version_header writes it (Board.build's items)."""
    short = commit[:8] if re.fullmatch(r"[0-9a-f]{40}", commit) else "0" * 8
    items = [("GIT_VERSION", f'"{short}"'), ("GIT_VERSION_EXTENDED", f'"{commit[:16]}"'),
             ("GIT_VERSION_INT", str(int(short, 16))), ("AP_BUILD_ROOT", f'"{root}"')]
    body = "".join(f"#define {k} {v}\n" for k, v in items)
    (out / "ap_version.h").write_text(
        "// auto-generated header, do not edit\n\n#pragma once\n\n#ifndef FORCE_VERSION_H_INCLUDE\n"
        "#error ap_version.h should never be included directly. You probably want to include "
        "AP_Common/AP_FWVersion.h\n#endif\n\n" + body)


def chibios_include_dirs(env: dict, out: Path) -> list[str]:
    """chibios.py's include_dirs rule (ChibiOS's make, target pass) and its parsing."""
    make_env = {**os.environ, "BUILDDIR": env["BUILDDIR_REL"], "BUILDROOT": env["BUILDROOT"],
                "CRASHCATCHER": env["CC_ROOT_REL"], "CHIBIOS": env["CH_ROOT_REL"],
                "AP_HAL": env["AP_HAL_REL"]}
    flags = env["CHIBIOS_BUILD_FLAGS"].split() + [env["CHIBIOS_BOARD_NAME"]]
    (out / "Makefile").touch()
    run([*env["MAKE"], "pass", "-f", env["BOARD_MK"], *flags], cwd=out, env=make_env)
    text = (out / "modules/ChibiOS/include_dirs").read_text().replace(";\n", "").replace("-I", "")
    dirs = []
    for d in re.split("; ", text):
        d = os.path.normpath(os.path.join(env["BUILDROOT"], d) if d.startswith("../") else d)
        if d not in dirs:
            dirs.append(d)
    return dirs


def board_flags(root: Path, board: str, commit: str, python: str) -> tuple[dict, list[str], Path]:
    """Configure one board, generate what its build generates; (env, include flags, build dir)."""
    env = configure(root, board, python)
    out = root / "build" / board
    generate_mavlink(root, out, python)
    dronecan = generate_dronecan(root, out, python)
    write_version(out, root, commit)
    exported = [out / "libraries", out / "libraries/GCS_MAVLink", dronecan / "include",
                root / "modules/DroneCAN/libcanard", root / "libraries/AP_DroneCAN/canard"]
    includes = [*map(str, exported), str(out), *env["INCLUDES"]]
    if env.get("BOARD_CLASS") == "ChibiOS":
        includes += chibios_include_dirs(env, out)
    return env, [f"-I{d}" for d in includes], out


def compile_board(root: Path, board: str, commit: str, python: str, report: Report,
                  build: Path) -> None:
    env, includes, out = board_flags(root, board, commit, python)
    units = UNITS + [(f"libraries/AP_RollMPC/{c.name}", None)
                     for c in sorted((root / "libraries/AP_RollMPC").glob("rollmpc_*.c"))]
    for unit, vehicle in units:
        defines = env["DEFINES"] + ([f"APM_BUILD_DIRECTORY=APM_BUILD_{vehicle}",
                                     f'AP_BUILD_TARGET_NAME="{vehicle}"'] + VEHICLE_DEFINES[vehicle]
                                    if vehicle else [])
        is_c = unit.endswith(".c")
        compiler = env["CC"][0] if is_c else env["CXX"][0]
        flags = (env["CFLAGS"] if is_c else env["CXXFLAGS"]) + includes + [f"-D{d}" for d in defines]
        report.add(compile_unit(compiler, flags, root / unit, build / board, unit, cwd=out))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ardupilot", type=Path, default=os.environ.get("ARDUPILOT_TREE"))
    ap.add_argument("--modules", type=Path, help="submodules missing in the tree's modules/")
    ap.add_argument("--gen", type=Path, default=repo_root() / "generated/uav_roll_f32")
    ap.add_argument("--build", type=Path, default=repo_root() / "build/check/ardupilot")
    ap.add_argument("--python", default=sys.executable, help="python with empy 3, lxml, future")
    ap.add_argument("--boards", default="sitl,MatekF405")
    args = ap.parse_args()
    if args.ardupilot is None:
        print("precheck_ardupilot: skipped (give --ardupilot PATH or set ARDUPILOT_TREE to an "
              "ArduPilot tree with its submodules, or --modules DIR for them)")
        return 0
    tree, build = args.ardupilot.resolve(), args.build.resolve()
    boards = args.boards.split(",")
    unknown = [b for b in boards if b not in BOARD_SUBMODULES]
    if unknown:
        sys.exit(f"precheck_ardupilot: unknown board(s) {unknown}; known: {list(BOARD_SUBMODULES)}")
    submodules = submodule_sources(tree, args.modules and args.modules.resolve(), boards)
    shutil.rmtree(build, ignore_errors=True)
    root = shadow(tree, build, submodules, args.gen.resolve())
    commit = tree_commit(tree)
    status = 0
    for board in boards:
        report = Report(f"ardupilot {board}", tree)
        compile_board(root, board, commit, args.python, report, build)
        status |= report.finish()
    for name, src in sorted(submodules.items()):
        print(f"  modules/{name}: {src} at {tree_commit(src)}")
    return status


if __name__ == "__main__":
    sys.exit(main())
