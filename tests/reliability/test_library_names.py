"""The generated C survives any system header a firmware build makes visible.

A unity build, a forced include, NuttX or PX4 headers declare the C, POSIX and newlib
names; ``static int accept(...)`` of every P_solver.c then stopped the build against
<sys/socket.h>.  Checked: every committed tree compiles (strict flags, -Werror), file by
file and as one unity translation unit, with every header of the list force-included
(host gcc on glibc; arm-none-eabi-gcc with newlib's); no identifier of any tree is a
library name (the data file of rollmpc_codegen/codegen/c_names.py); and the templates'
prefixed identifiers, which the prefix check reads, cover every one a tree defines.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from conftest import ROOT, require_tool
from rollmpc_codegen.codegen.c_names import (_generated_tails, c_identifiers, library_names,
                                             source_collisions)
from rollmpc_codegen.verify.c_library_names import FEATURES, HEADERS, NEWLIB_INCLUDE

GENERATED = ROOT / "generated"
TREES = sorted(p.name for p in GENERATED.iterdir() if (p / ".rollmpc-manifest").is_file())
# the trees whose code differs most: the paper's, soft rows, run-time bounds, Δu rows, a
# band scheduler of three modes; both precisions among them
QUICK = ("uav_roll", "chain_soft_f32", "chain_runtime_bounds", "thermal_zones_rate_f32",
         "three_drives")
STRICT = ["-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow", "-Wdouble-promotion",
          "-Wvla", "-Werror"]
ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"


def _compiles(cc: list[str], headers) -> bool:
    source = "".join(f"#include <{h}>\n" for h in headers)
    return subprocess.run([*cc, *FEATURES, "-x", "c", "-fsyntax-only", "-"], input=source,
                          capture_output=True, text=True).returncode == 0


def _headers(cc: list[str]) -> list[str]:
    """The headers of the list this compiler has and compiles (newlib has a threads.h
    whose machine/_threads.h the Arm port lacks)."""
    probe = "".join(f"#if __has_include(<{h}>)\nhas {h}\n#endif\n" for h in HEADERS)
    out = subprocess.run([*cc, *FEATURES, "-x", "c", "-E", "-P", "-"], input=probe,
                         capture_output=True, text=True, check=True).stdout
    found = [line.split()[1] for line in out.splitlines() if line.startswith("has ")]
    return found if _compiles(cc, found) else [h for h in found if _compiles(cc, [h])]


@pytest.fixture(scope="module")
def host_headers() -> list[str]:
    found = _headers(["gcc"])
    assert {"sys/socket.h", "threads.h", "aio.h", "pthread.h", "unistd.h"} <= set(found)
    return found


@pytest.fixture(scope="module")
def newlib() -> tuple[list[str], list[str]]:
    """(arm-none-eabi-gcc for the M4F, the headers of the list newlib has)."""
    cc = [require_tool("arm-none-eabi-gcc", ARM_HINT), "-mcpu=cortex-m4", "-mthumb",
          "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"]
    headers = _headers(cc)
    assert len(headers) >= 40 and "pthread.h" in headers, headers
    return cc, headers


def _syntax_errors(cc: list[str], tree: Path, headers: list[str], tmp_path: Path) -> list[str]:
    """Compile every source of ``tree``, then all of them as one translation unit, with
    ``headers`` force-included; the diagnostics of those that fail."""
    forced = [arg for h in headers for arg in ("-include", h)]
    unity = tmp_path / f"{tree.name}_unity.c"
    unity.write_text("".join(f'#include "{c.name}"\n' for c in sorted(tree.glob("*.c"))))
    failed = []
    for source in [*sorted(tree.glob("*.c")), unity]:
        proc = subprocess.run([*cc, *FEATURES, *STRICT, *forced, f"-I{tree}", "-fsyntax-only",
                               str(source)], capture_output=True, text=True)
        if proc.returncode != 0 or proc.stderr.strip():
            failed.append(f"{source.name}: {proc.stderr.strip()[:600]}")
    return failed


def _assert_compiles(cc, tree, headers, tmp_path):
    failed = _syntax_errors(cc, tree, headers, tmp_path)
    assert not failed, "\n".join(failed)


@pytest.mark.parametrize("tree", QUICK)
def test_tree_compiles_with_every_system_header(tree, host_headers, tmp_path):
    _assert_compiles(["gcc"], GENERATED / tree, host_headers, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("tree", TREES)
def test_every_tree_compiles_with_every_system_header(tree, host_headers, tmp_path):
    _assert_compiles(["gcc"], GENERATED / tree, host_headers, tmp_path)


def test_tree_compiles_with_every_newlib_header(newlib, tmp_path):
    _assert_compiles(newlib[0], GENERATED / "uav_roll_f32", newlib[1], tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("tree", [t for t in TREES if t.endswith("_f32")])
def test_every_float_tree_compiles_with_every_newlib_header(tree, newlib, tmp_path):
    _assert_compiles(newlib[0], GENERATED / tree, newlib[1], tmp_path)


def test_the_audits_collision_fails_this_check(host_headers, tmp_path):
    """The check sees the audit's finding: accept() under <sys/socket.h>."""
    tree = tmp_path / "t"
    tree.mkdir()
    (tree / "x.c").write_text("static int accept(int a) { return a; }\n"
                              "int use(void);\nint use(void) { return accept(1); }\n")
    failed = _syntax_errors(["gcc"], tree, host_headers, tmp_path)
    assert failed and "accept" in failed[0]
    assert source_collisions((tree / "x.c").read_text()) == ["accept"]


# --------------------------------------------------------------------------- the name list
def test_name_list_holds_the_names_that_broke_builds():
    names = library_names()
    assert len(names) > 8000
    # the audit's: the solver's accept(); the prefixes aio, cnd, mtx, sem, pthread_mutex,
    # pthread_cond, inotify, posix_spawnattr; newlib-only names; math.h's Bessel y0
    assert {"accept", "aio_init", "cnd_init", "mtx_init", "sem_init", "pthread_mutex_init",
            "pthread_cond_init", "inotify_init", "posix_spawnattr_init", "y0", "truncate",
            "round", "SHM_R", "bool", "typeof"} <= names
    assert {"_exit", "__errno_location"}.isdisjoint(names)  # the implementation's own


@pytest.mark.parametrize("tree", TREES)
def test_no_identifier_of_a_tree_is_a_library_name(tree):
    hits = {f.name: source_collisions(f.read_text())
            for f in sorted((GENERATED / tree).glob("*.[ch]"))}
    assert not any(hits.values()), {k: v for k, v in hits.items() if v}


@pytest.mark.parametrize("tree", ["uav_roll", "chain_runtime_bounds", "chain_soft_f32",
                                  "three_drives", "c172_roll"])
def test_prefix_check_sees_every_prefixed_identifier(tree):
    """prefix_collisions() reads the identifiers from the templates; each prefixed one of a
    rendered tree must match what it read, or a colliding prefix could pass."""
    prefix = next((GENERATED / tree).glob("*_config.h")).name[:-len("_config.h")]
    tails = _generated_tails()
    seen = set()
    for f in (GENERATED / tree).glob("*.[ch]"):
        seen |= c_identifiers(f.read_text())
    missed = sorted(
        name for name in seen
        for case, start in (("prefix", prefix + "_"), ("PREFIX", prefix.upper() + "_"))
        if name.startswith(start) and not tails[case].fullmatch(name[len(start):]))
    assert not missed, missed
    assert any(name.startswith(prefix + "_") for name in seen)
