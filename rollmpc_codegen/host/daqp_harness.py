"""DAQP's own C on our QPs: its PyPI sdist and the data of ``templates/target/daqp_harness.c.j2``.

One harness serves two builds of DAQP at its best (set-up not counted, warm-started, the
QP shifted by theta0 so that it has only bounds):

* the emulated Cortex-M4F in single precision (``rollmpc report --peer daqp``,
  :mod:`rollmpc_codegen.target.peer_daqp`), counted in cycles;
* the host in double (``rollmpc bench``'s ``daqp_c`` rows, :mod:`.peer_daqp_c`), timed by
  the same clock and around the same work as our ``solve_ticks``.

Nothing of DAQP is vendored: its C comes from the sdist of the installed Python daqp.
"""
from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
import sys
import tarfile
from importlib import metadata
from pathlib import Path

import numpy as np

from .build import STRICT_WARNINGS, BuildError
from .build_cache import private_root
from ..model.controller import ControllerModel
from ..qp.condense import solve_refined
from ..qp.peers import DAQP_INF, TwoSidedForm, peer_problems

# DAQP's own files: our warnings, reported and counted but not errors
DAQP_WARNINGS = tuple(w for w in STRICT_WARNINGS if w != "-Werror")
# Settings changed from DAQP's defaults (name -> value), rendered into the harness.
# zero_tol (1e-11; it bounds blocking along a singular direction of the working set):
# 1e-14 gave the same statuses and errors on the UAV scenario and an inner-mode median of
# 354 k instead of 430 k cycles (worst 18.79 M instead of 18.68 M; outer mode unchanged)
SETTINGS = {"zero_tol": 1e-14}
# how E reaches DAQP (the set-up is not counted either way)
SETUPS = {
    "offline": "Cholesky factor of E in double, rounded once to float (problem_type 2)",
    "target": "E rounded to float, factored by DAQP's own float setup on the target",
}


class DaqpSourceUnavailable(RuntimeError):
    """DAQP's sdist could not be downloaded (no network, no pip, unknown version)."""


def daqp_version() -> str:
    """The installed Python daqp: the sdist of the same version is the C we compile."""
    try:
        return metadata.version("daqp")
    except metadata.PackageNotFoundError:
        raise DaqpSourceUnavailable("daqp is not installed: pip install "
                                    "'rollmpc-codegen[peers]'") from None


def daqp_sources(version: str, cache_dir: Path | None = None) -> Path:
    """``csrc/`` of DAQP's sdist: downloaded with pip and unpacked once into ``cache_dir``."""
    cache = (Path(cache_dir) if cache_dir is not None else private_root() / "daqp-sdist")
    top = f"daqp-{version}"
    csrc = cache / top / "csrc"
    if (csrc / "include" / "api.h").is_file():
        return csrc
    tarball = cache / f"{top}.tar.gz"
    if not tarball.is_file():
        cache.mkdir(parents=True, exist_ok=True)
        # --no-binary daqp, not :all:: pip prepares the sdist's metadata, and with :all: it
        # would build every build dependency from source too (minutes, not seconds)
        cmd = [sys.executable, "-m", "pip", "download", "--no-binary", "daqp", "--no-deps",
               "--disable-pip-version-check", f"daqp=={version}", "-d", str(cache)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0 or not tarball.is_file():
            why = (proc.stderr.strip().splitlines() or ["no sdist downloaded"])[-1]
            raise DaqpSourceUnavailable(
                f"DAQP's C comes from its sdist, downloaded once into {cache} (needs pip "
                f"and network to PyPI): {why}\n{' '.join(cmd)}\n{proc.stderr.strip()}")
    tmp = cache / f"{top}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    with tarfile.open(tarball) as tar:
        members = [m for m in tar.getmembers() if m.name.startswith(f"{top}/csrc/")]
        tar.extractall(tmp, members=members, filter="data")
    shutil.rmtree(cache / top, ignore_errors=True)
    (tmp / top).rename(cache / top)
    shutil.rmtree(tmp, ignore_errors=True)
    return csrc


def exit_flags(csrc: Path) -> dict[int, str]:
    """DAQP's exit flags (``DAQP_EXIT_*`` of its constants.h): value -> lower-case name."""
    text = (csrc / "include" / "constants.h").read_text()
    return {int(v): name.lower() for name, v in
            re.findall(r"#define DAQP_EXIT_(\w+) \(?(-?\d+)\)?", text)}


def mode_arrays(qp, factored: bool = True) -> dict[str, np.ndarray]:
    """The harness arrays of one mode, in double (rounded once when written to the target).

    H: the packed upper Cholesky factor of E (by rows) if ``factored``, else E; A: the
    general rows; theta0 = Tx x + Tr r + t0; per DAQP row the bounds cu + W x (upper) and
    cl + W x (lower), +/- DAQP_INF where a side is absent. The two sides of a row bound
    the same quantity, so their W x is one (ValueError if a QP's pair ever differs).
    """
    form = TwoSidedForm(qp)
    R = np.linalg.cholesky(qp.E).T
    up = np.concatenate((form.bound_upper, form.general_upper))
    lo = np.concatenate((form.bound_lower, form.general_lower))
    Wu, Wl = qp.W[np.maximum(up, 0)], -qp.W[np.maximum(lo, 0)]
    both = (up >= 0) & (lo >= 0)
    if not np.array_equal(Wu[both], Wl[both]):
        raise ValueError("a two-sided row's bounds move differently with x")
    t0 = (np.zeros(qp.n) if qp.f_const is None
          else solve_refined(qp.E, -qp.f_const[:, None])[:, 0])
    return {
        "H": np.concatenate([R[i, i:] for i in range(qp.n)]) if factored else qp.E,
        "A": form.A,
        "Tx": qp.Kx, "Tr": qp.Kr, "t0": t0,
        "W": np.where((up >= 0)[:, None], Wu, Wl),
        "cu": np.where(up >= 0, qp.c[np.maximum(up, 0)], DAQP_INF),
        "cl": np.where(lo >= 0, -qp.c[np.maximum(lo, 0)], -DAQP_INF),
    }


def harness_context(model: ControllerModel, version: str, setup: str = "offline",
                    host: bool = False) -> dict:
    """What ``daqp_harness.c.j2`` (and, on the target, ``link.ld.j2``) see: single
    precision on the target, double on the ``host``."""
    problems, _ = peer_problems([mm.qp for mm in model.modes])
    modes = []
    for mm, qp in zip(model.config.modes, problems):
        general = TwoSidedForm(qp).A.shape[0]
        modes.append({"name": mm.name, "n": qp.n, "nx": qp.nx, "nr": qp.Kr.shape[1],
                      "ms": qp.n, "m": qp.n + general})
    # DAQP's setup allocations: about 1.5 n^2 + n m floats a mode; twice that, plus slack
    heap = sum(8 * (2 * (md["n"] + 2) ** 2 + md["n"] * md["m"] + 16 * md["m"]) + 4096
               for md in modes)
    return {"prefix": f"{model.config.prefix}_daqp", "config_prefix": model.config.prefix,
            "precision": "double" if host else "float", "host": host,
            "daqp_version": version, "modes": modes,
            "heap_bytes": heap, "settings": SETTINGS, "factored": setup == "offline",
            "setup": SETUPS[setup],
            "n_max": max(md["n"] for md in modes), "nx_max": max(md["nx"] for md in modes),
            "nr_max": max(md["nr"] for md in modes),
            "target": {"core": model.config.target.core}}  # the core it is built for


def compile_relaxed(cmd: list[str]) -> str:
    """Compile one of DAQP's files; its warnings are returned, not errors."""
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise BuildError(f"{' '.join(cmd)}\n{proc.stderr}")
    return proc.stderr


def warning_counts(text: str) -> dict[str, int]:
    """{warning flag: count} over a compiler's output."""
    counts: dict[str, int] = {}
    for flag in re.findall(r"warning: .*\[(-W[\w-]+)\]", text):
        counts[flag] = counts.get(flag, 0) + 1
    return dict(sorted(counts.items()))


def build_key(texts: list[str], csrc: Path) -> str:
    """The cache key of a DAQP build: its compiler, flags and rendered files, and DAQP's
    sources and headers."""
    digest = hashlib.sha256("\n".join(texts).encode())
    for path in [*sorted((csrc / "src").glob("*.c")), *sorted((csrc / "include").glob("*.h"))]:
        digest.update(path.read_bytes())
    return digest.hexdigest()


def compile_daqp(compile_cmd: list[str], csrc: Path, out_dir: Path) -> tuple[list[Path], str]:
    """DAQP's own files, each compiled by ``compile_cmd`` (compiler and flags) with our
    warnings relaxed: (object files, the warnings they raised)."""
    objs, warnings = [], []
    for src in sorted((csrc / "src").glob("*.c")):
        objs.append(out_dir / f"daqp_{src.stem}.o")
        warnings.append(compile_relaxed([*compile_cmd, *DAQP_WARNINGS, f"-I{csrc / 'include'}",
                                         "-c", str(src), "-o", str(objs[-1])]))
    return objs, "".join(warnings)


def compile_harness(compile_cmd: list[str], csrc: Path, source: Path) -> Path:
    """The harness, held to our strict warnings; ``-isystem``: DAQP's headers are not."""
    obj = source.with_suffix(".o")
    compile_relaxed([*compile_cmd, *STRICT_WARNINGS, "-isystem", str(csrc / "include"), "-c",
                     str(source), "-o", str(obj)])  # -Werror: a warning fails the build
    return obj
