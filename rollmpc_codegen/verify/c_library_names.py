"""The names of the C, POSIX and newlib libraries, written into the package's data file.

    python -m rollmpc_codegen.verify.c_library_names      # rewrites codegen/c_library_names.txt

A firmware build may see any system header: a unity build, a forced include, NuttX or PX4
headers.  A generated identifier equal to a library's then breaks the build (``static int
accept(...)`` against <sys/socket.h>) or, with external linkage, silently replaces the
library's function at link time.  The generator refuses such prefixes and the tests
refuse such internal names (:mod:`rollmpc_codegen.codegen.c_names`), against this list:

* every name :data:`HEADERS` declare on this host's glibc with ``_GNU_SOURCE`` (clang's
  AST: functions, objects, typedefs, struct/union/enum tags, enumerators) and every macro
  they define;
* the same for the headers of the list that newlib (arm-none-eabi) has;
* the symbols glibc's libc/libm and newlib's libc.a/libm.a export;
* the keywords C23 adds (a local named ``bool`` or ``typeof`` breaks a C23 build).

Names that begin with an underscore are left out: they are the implementation's, and no
generated identifier begins with one.
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from ..codegen.c_names import C23_KEYWORDS, LIBRARY_NAMES_FILE

# Headers a firmware build may see: the C standard's (C99 to C17; threads.h and uchar.h
# of C11), POSIX.1-2017's (those glibc ships: not ndbm.h, stropts.h, trace.h) and common
# glibc/Linux ones.
C_HEADERS = (
    "assert.h", "complex.h", "ctype.h", "errno.h", "fenv.h", "float.h", "inttypes.h",
    "iso646.h", "limits.h", "locale.h", "math.h", "setjmp.h", "signal.h", "stdalign.h",
    "stdarg.h", "stdatomic.h", "stdbool.h", "stddef.h", "stdint.h", "stdio.h", "stdlib.h",
    "stdnoreturn.h", "string.h", "tgmath.h", "threads.h", "time.h", "uchar.h", "wchar.h",
    "wctype.h")
POSIX_HEADERS = (
    "aio.h", "arpa/inet.h", "cpio.h", "dirent.h", "dlfcn.h", "fcntl.h", "fmtmsg.h",
    "fnmatch.h", "ftw.h", "glob.h", "grp.h", "iconv.h", "langinfo.h", "libgen.h",
    "monetary.h", "mqueue.h", "net/if.h", "netdb.h", "netinet/in.h", "netinet/tcp.h",
    "nl_types.h", "poll.h", "pthread.h", "pwd.h", "regex.h", "sched.h", "search.h",
    "semaphore.h", "spawn.h", "strings.h", "sys/ipc.h", "sys/mman.h", "sys/msg.h",
    "sys/resource.h", "sys/select.h", "sys/sem.h", "sys/shm.h", "sys/socket.h", "sys/stat.h",
    "sys/statvfs.h", "sys/time.h", "sys/times.h", "sys/types.h", "sys/uio.h", "sys/un.h",
    "sys/utsname.h", "sys/wait.h", "syslog.h", "tar.h", "termios.h", "ulimit.h", "unistd.h",
    "utime.h", "utmpx.h", "wordexp.h")
SYSTEM_HEADERS = (
    "alloca.h", "argp.h", "byteswap.h", "elf.h", "endian.h", "err.h", "error.h",
    "execinfo.h", "features.h", "getopt.h", "link.h", "malloc.h", "sys/epoll.h",
    "sys/eventfd.h", "sys/file.h", "sys/inotify.h", "sys/ioctl.h", "sys/param.h",
    "sys/prctl.h", "sys/random.h", "sys/signalfd.h", "sys/sysinfo.h", "sys/timerfd.h")
HEADERS = C_HEADERS + POSIX_HEADERS + SYSTEM_HEADERS
FEATURES = ("-std=c99", "-D_GNU_SOURCE")  # every declaration glibc and newlib can show
NEWLIB_INCLUDE = Path("/usr/lib/arm-none-eabi/include")
NEWLIB_LIBS = ("/usr/lib/arm-none-eabi/lib/libc.a", "/usr/lib/arm-none-eabi/lib/libm.a")
GLIBC_LIBS = ("libc.so.6", "libm.so.6")
DECLARATIONS = ("FunctionDecl", "VarDecl", "TypedefDecl", "RecordDecl", "EnumDecl")


def _run(cmd: list[str], **kw) -> str:
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout


def _existing(headers, flags: list[str]) -> list[str]:
    """The headers of the list that this compiler (with ``flags``) has."""
    return [h for h in headers
            if subprocess.run(["clang", *flags, "-x", "c", "-fsyntax-only", "-"],
                              input=f"#include <{h}>\n", capture_output=True,
                              text=True).returncode == 0]


def _declared(source: Path, flags: list[str]) -> set[str]:
    """File-scope names (and enumerators) of ``source`` and every macro it defines."""
    tree = json.loads(_run(["clang", *flags, "-fsyntax-only", "-Xclang", "-ast-dump=json",
                            str(source)]))
    names = set()
    for node in tree.get("inner", []):
        if node.get("kind") == "EnumDecl":
            names.update(c["name"] for c in node.get("inner", [])
                         if c.get("kind") == "EnumConstantDecl")
        if node.get("kind") in DECLARATIONS and node.get("name"):
            names.add(node["name"])
    macros = _run(["clang", *flags, "-dM", "-E", str(source)])
    names.update(re.findall(r"^#define (\w+)", macros, re.M))
    return names


def _exported(nm: str, libraries) -> set[str]:
    """The global symbols the libraries define (glibc's version suffixes dropped)."""
    out = _run([nm, "--defined-only", "-D" if nm == "nm" else "-g", *libraries])
    return {parts[2].split("@")[0] for parts in map(str.split, out.splitlines())
            if len(parts) == 3 and parts[1] in "TDBRWVGSi"}


def _glibc_paths() -> list[str]:
    paths = _run(["gcc", "-print-file-name=libc.so.6"]), _run(["gcc", "-print-file-name=libm.so.6"])
    found = [p.strip() for p in paths if Path(p.strip()).is_file()]
    if len(found) < 2:  # the loader's copies
        found = [str(p) for p in Path("/lib").glob("*-linux-gnu/lib[cm].so.6")]
    return found


def collect() -> tuple[set[str], list[str]]:
    """(every library name, the provenance lines for the file's header)."""
    names, notes = set(C23_KEYWORDS), []
    with tempfile.TemporaryDirectory() as tmp:
        resource = _run(["clang", "-print-resource-dir"]).strip()
        builds = {"glibc": [*FEATURES],
                  "newlib": ["--target=arm-none-eabi", "-nostdinc", "-isystem",
                             str(NEWLIB_INCLUDE), "-isystem", f"{resource}/include", *FEATURES]}
        for label, flags in builds.items():
            headers = _existing(HEADERS, flags)
            source = Path(tmp) / f"{label}.c"
            source.write_text("".join(f"#include <{h}>\n" for h in headers))
            names |= _declared(source, flags)
            notes.append(f"{label}: {len(headers)} of the {len(HEADERS)} headers")
    names |= _exported("nm", _glibc_paths())
    names |= _exported("arm-none-eabi-nm", NEWLIB_LIBS)
    versions = [_run(["ldd", "--version"]).splitlines()[0],
                _run(["clang", "--version"]).splitlines()[0],
                _run(["arm-none-eabi-gcc", "--version"]).splitlines()[0]]
    return {n for n in names if not n.startswith("_")}, notes + versions


def main() -> int:
    missing = [t for t in ("clang", "nm", "arm-none-eabi-gcc", "arm-none-eabi-nm", "ldd")
               if shutil.which(t) is None]
    if missing:
        print(f"needs {', '.join(missing)} (apt-get install clang binutils gcc-arm-none-eabi)",
              file=sys.stderr)
        return 2
    names, notes = collect()
    header = ["# C, POSIX and newlib identifiers (rollmpc_codegen/verify/c_library_names.py):",
              *(f"# {n}" for n in notes), f"# {len(names)} names, one a line, sorted"]
    LIBRARY_NAMES_FILE.write_text("\n".join(header + sorted(names)) + "\n")
    print(f"{LIBRARY_NAMES_FILE}: {len(names)} names")
    return 0


if __name__ == "__main__":
    sys.exit(main())
