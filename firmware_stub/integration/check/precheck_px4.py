#!/usr/bin/env python3
"""Compile the rollmpc PX4 module against a real PX4-Autopilot tree (SITL/posix flags).

    python3 firmware_stub/integration/check/precheck_px4.py --px4 /path/to/PX4-Autopilot \
        [--gen generated/uav_roll_f32] [--build build/check/px4]

Without --px4 (or $PX4_TREE) it prints a hint and exits 0 (skipped). The tree is only
read. In --build it lays out what PX4's build would: the module as src/modules/rollmpc
(with the glue core and the generated controller), RollmpcServos.msg beside msg/; the
uORB headers from every msg/ file by PX4's own generator (Tools/msg), the parameter
header from module.yaml by PX4's own scripts (Tools/module_config, src/lib/parameters);
the control allocator with control_allocator.patch applied. Then every translation unit
(RollMpc.cpp, rollglue.c, the generated C, the patched ControlAllocator.cpp) is compiled
with PX4's common flags (cmake/px4_add_common_flags.cmake) for the posix platform, and
the ModuleBase switch is set exactly as the module's CMakeLists.txt sets it.

px4_boardconfig.h comes from the px4_sitl board's Kconfig by kconfiglib's genconfig, with
CONFIG_MODULES_ROLLMPC appended (the module is not inside the tree's Kconfig). Nothing is
stubbed. Needs python packages empy 3.x, pyros-genmsg, jinja2, pyyaml and kconfiglib (PX4's
generators; --python names an interpreter that has them); the compiler is g++/gcc (PX4
SITL, the posix platform). Exit status 0 = every unit compiled without a diagnostic.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from common import Report, compile_unit, copy_tree, repo_root, run  # noqa: E402

PX4_FLAGS = [  # cmake/px4_add_common_flags.cmake (GNU branch), both lines
    "-g", "-fdata-sections", "-ffunction-sections", "-fomit-frame-pointer", "-fmerge-all-constants",
    "-fno-signed-zeros", "-fno-trapping-math", "-freciprocal-math", "-fno-math-errno",
    "-fno-strict-aliasing", "-fvisibility=hidden", "-include", "visibility.h", "-Wall", "-Wextra",
    "-Werror", "-Warray-bounds", "-Wcast-align", "-Wdisabled-optimization", "-Wdouble-promotion",
    "-Wfatal-errors", "-Wfloat-equal", "-Wformat-security", "-Winit-self", "-Wlogical-op",
    "-Wpointer-arith", "-Wshadow", "-Wuninitialized", "-Wunknown-pragmas", "-Wunused-variable",
    "-Wno-missing-field-initializers", "-Wno-missing-include-dirs", "-Wno-unused-parameter",
    "-fno-builtin-printf", "-fno-strength-reduce", "-Wformat=1", "-Wunused-but-set-variable",
    "-Wno-format-truncation", "-Wno-stringop-truncation", "-O2",
    "-DCONFIG_ARCH_BOARD_PX4_SITL", "-D__CUSTOM_FILE_IO__", "-D__STDC_FORMAT_MACROS",
    # platforms/posix/cmake/px4_impl_os.cmake
    "-D__PX4_POSIX", "-D__PX4_LINUX", "-Dnoreturn_function=__attribute__((noreturn))",
]
C_FLAGS = ["-std=gnu11", "-fno-common", "-Wnested-externs", "-Wstrict-prototypes"]
CXX_FLAGS = ["-std=gnu++17", "-Wreorder", "-Wno-overloaded-virtual", "-fcheck-new",
             "-fno-exceptions", "-fno-threadsafe-statics"]
GENERATED = ["rollmpc_controller.c", "rollmpc_data.c", "rollmpc_linalg.c", "rollmpc_solver.c"]


def module_flags(px4: Path, module: Path) -> list[str]:
    """The COMPILE_FLAGS of integration/px4/rollmpc/CMakeLists.txt, descriptor switch included."""
    module_h = px4 / "platforms/common/include/px4_platform_common/module.h"
    descriptor = int("struct Descriptor" in module_h.read_text())
    return [f"-DRMPC_MODULE_DESCRIPTOR={descriptor}", "-Wframe-larger-than=1024", "-ffp-contract=off",
            "-fno-reciprocal-math",
            "-include", str(module / "common/rollglue_cycles.h"),
            "-DROLLMPC_TIMESTAMP()=ROLLGLUE_CYCLES()", f"-I{module / 'common'}",
            f"-I{module / 'generated'}", "-DMODULE_NAME=\"rollmpc\"", "-DPX4_MAIN=rollmpc_app_main"]


def layout(px4: Path, build: Path, gen: Path) -> Path:
    """src/modules/rollmpc as the README lays it out, inside the build directory."""
    root = repo_root()
    module = build / "src/modules/rollmpc"
    copy_tree(root / "firmware_stub/integration/px4/rollmpc", module)
    copy_tree(root / "firmware_stub/integration/common", module / "common")
    copy_tree(gen, module / "generated")
    return module


def generate_uorb(px4: Path, build: Path, python: str) -> Path:
    msg_dirs = [px4 / "msg"] + ([px4 / "msg/versioned"] if (px4 / "msg/versioned").is_dir() else [])
    msgs = sorted(p for d in msg_dirs for p in d.glob("*.msg"))
    ours = repo_root() / "firmware_stub/integration/px4/rollmpc/RollmpcServos.msg"
    extra = build / "msg_extra"
    extra.mkdir(parents=True, exist_ok=True)
    shutil.copy(ours, extra / ours.name)
    out = build / "uORB/topics"
    out.mkdir(parents=True, exist_ok=True)
    run([python, str(px4 / "Tools/msg/px_generate_uorb_topic_files.py"), "--headers",
         "-f", *map(str, msgs), str(extra / ours.name), "-i", *map(str, msg_dirs), str(extra),
         "-o", str(out), "-e", str(px4 / "Tools/msg/templates/uorb")])
    return out


def generate_params(px4: Path, build: Path, python: str, module_yaml: Path) -> None:
    """parameters/px4_parameters.hpp of every parameter of the tree and of the module
    (module.yaml files -> .c by Tools/module_config, then src/lib/parameters)."""
    gen_dir = build / "generated_params"
    gen_dir.mkdir(parents=True, exist_ok=True)
    yamls = sorted(y for d in ("src/modules", "src/lib") for y in (px4 / d).rglob("*.yaml")
                   if y.name == "module.yaml" or "params" in y.name)  # MODULE_CONFIG files
    yamls.append(module_yaml)  # drivers are left out: their outputs need a board timer config
    run([python, str(px4 / "Tools/module_config/generate_params.py"), "--params-file",
         str(gen_dir / "module_params.c"), "--config-files", *map(str, yamls),
         "--board", "px4_sitl"])
    xml = build / "parameters.xml"
    injected = px4 / "src/lib/parameters/parameters_injected.xml"  # v1.15 needs it named
    c_dirs = sorted({c.parent for c in (px4 / "src").rglob("*params*.c")})  # v1.15: not recursive
    run([python, str(px4 / "src/lib/parameters/px_process_params.py"), "--src-path",
         str(gen_dir), *map(str, c_dirs), "--xml", str(xml), "--board", "px4_sitl",
         *(["--inject-xml", str(injected)] if injected.exists() else [])])
    dest = build / "src/lib/parameters"  # <parameters/px4_parameters.hpp>
    dest.mkdir(parents=True, exist_ok=True)
    run([python, str(px4 / "src/lib/parameters/px_generate_params.py"), "--xml", str(xml),
         "--dest", str(dest)])


def boardconfig(px4: Path, build: Path, python: str) -> None:
    """px4_boardconfig.h of px4_sitl by PX4's Kconfig (kconfiglib's genconfig, the
    environment of cmake/kconfig.cmake), plus CONFIG_MODULES_ROLLMPC: the module's
    Kconfig sits outside the tree here, so Kconfig cannot see it."""
    config = build / "sitl.px4board"
    shutil.copy(px4 / "boards/px4/sitl/default.px4board", config)
    env = {**os.environ, "KCONFIG_CONFIG": str(config), "BASE_DEFCONFIG": str(config),
           "PLATFORM": "posix", "VENDOR": "px4", "MODEL": "sitl", "LABEL": "default",
           "TOOLCHAIN": "", "ARCHITECTURE": "x86_64", "ROMFSROOT": "px4fmu_common",
           "ZENOH_KCONFIG_TOPICS": os.devnull, "PYTHON_EXECUTABLE": python}
    header = build / "px4_boardconfig.h"
    proc = subprocess.run([python, "-m", "genconfig", "--header-path", str(header), "Kconfig"],
                          cwd=px4, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"genconfig failed (pip install kconfiglib):\n{proc.stderr[-2000:]}")
    with header.open("a") as fh:
        fh.write("#define CONFIG_MODULES_ROLLMPC 1\n")


def includes(px4: Path, build: Path) -> list[str]:
    dirs = [build, build / "src/lib", px4 / "platforms/posix/src/px4/generic/generic/include",
            px4 / "platforms/posix/src/px4/common/include",
            px4 / "platforms/common", px4 / "platforms/common/include", px4 / "src",
            px4 / "src/include", px4 / "src/lib", px4 / "src/lib/matrix", px4 / "src/modules",
            px4 / "platforms/posix/include", px4 / "boards/px4/sitl/src",
            build / "src", build / "src/modules"]
    return [f"-I{d}" for d in dirs]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--px4", type=Path, default=os.environ.get("PX4_TREE"))
    ap.add_argument("--gen", type=Path, default=repo_root() / "generated/uav_roll_f32")
    ap.add_argument("--build", type=Path, default=repo_root() / "build/check/px4")
    ap.add_argument("--python", default=sys.executable, help="python with empy 3, jinja2, pyyaml")
    args = ap.parse_args()
    if args.px4 is None:
        print("precheck_px4: skipped (give --px4 PATH or set PX4_TREE to a PX4-Autopilot tree)")
        return 0
    px4, build = args.px4.resolve(), args.build.resolve()
    shutil.rmtree(build, ignore_errors=True)
    report = Report("px4", px4)
    module = layout(px4, build, args.gen.resolve())
    generate_uorb(px4, build, args.python)
    generate_params(px4, build, args.python, module / "module.yaml")
    boardconfig(px4, build, args.python)
    alloc = build / "src/modules/control_allocator"
    copy_tree(px4 / "src/modules/control_allocator", alloc)
    run(["patch", "-p1", "-d", str(build), "-i",
         str(repo_root() / "firmware_stub/integration/px4/control_allocator.patch")])
    inc = includes(px4, build)
    base = PX4_FLAGS + module_flags(px4, module) + inc
    for name in GENERATED:
        report.add(compile_unit("gcc", base + C_FLAGS, module / "generated" / name, build))
    report.add(compile_unit("gcc", base + C_FLAGS, module / "common/rollglue.c", build))
    report.add(compile_unit("g++", base + CXX_FLAGS, module / "RollMpc.cpp", build))
    alloc_dirs = [alloc, alloc / "VehicleActuatorEffectiveness",  # main, then v1.15 layout
                  px4 / "src/lib/control_allocation/actuator_effectiveness",
                  px4 / "src/lib/control_allocation/control_allocation",
                  alloc / "ActuatorEffectiveness", alloc / "ControlAllocation"]
    alloc_flags = PX4_FLAGS + inc + [f"-I{d}" for d in alloc_dirs if d.is_dir()] + [
                                     "-DMODULE_NAME=\"control_allocator\""] + CXX_FLAGS
    report.add(compile_unit("g++", alloc_flags, alloc / "ControlAllocator.cpp", build))
    return report.finish()


if __name__ == "__main__":
    sys.exit(main())
