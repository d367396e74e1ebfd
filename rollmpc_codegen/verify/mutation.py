"""Mutation testing: plant each bug of :mod:`.mutants` in a copy of the repository and
record which tests notice it (docs/reliability.md, "Mutation testing").

    python -m rollmpc_codegen.verify.mutation [--only 1,3] [--json build/mutation.json]

(``make mutation``, part of ``make check-long``.)  The repository is copied once into a
temporary directory (without .git, build/ and caches).  First the union of every
mutant's test selection runs on the unchanged copy, which must pass.  Then, for each
mutant, its text is replaced, its selection runs with the copy first on PYTHONPATH, and
the original file is restored.  A mutant is *caught behaviourally* when a test other
than ``tests/codegen/test_generated_snapshot.py`` (the byte comparison with generated/) fails; the run
fails (exit 1) unless every mutant is.  Prints a markdown table; ``--json`` keeps the
failing test ids of every mutant.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

from .mutants import MUTANTS, Mutant

ROOT = Path(__file__).resolve().parents[2]
SKIP = shutil.ignore_patterns(".git", "build", ".venv", "__pycache__", ".pytest_cache",
                              "*.egg-info", ".hypothesis")
GENERATED_TEST = "tests/codegen/test_generated_snapshot.py"


def copy_repository(dest: Path) -> Path:
    """The repository's tree in ``dest/repo``, checked to be what Python imports there."""
    repo = dest / "repo"
    shutil.copytree(ROOT, repo, ignore=SKIP, symlinks=True)
    probe = subprocess.run([sys.executable, "-c", "import rollmpc_codegen; print(rollmpc_codegen.__file__)"],
                           cwd=repo, env=environment(repo), capture_output=True, text=True, check=True)
    if not Path(probe.stdout.strip()).is_relative_to(repo):
        raise RuntimeError(f"the copy imports rollmpc_codegen from {probe.stdout.strip()}")
    return repo


def environment(repo: Path) -> dict:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(repo), env.get("PYTHONPATH")]))
    return env


def run_tests(repo: Path, tests: tuple[str, ...], report: Path) -> tuple[list[str], int]:
    """Run pytest on ``tests`` in ``repo``; (the ids of the failing tests, exit status)."""
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={report}",
           *tests]
    proc = subprocess.run(cmd, cwd=repo, env=environment(repo), capture_output=True, text=True)
    failed = []
    if report.exists():
        for case in ET.parse(report).getroot().iter("testcase"):
            if case.find("failure") is not None or case.find("error") is not None:
                path = case.get("classname", "").replace(".", "/") + ".py"
                failed.append(f"{path}::{case.get('name')}")
        report.unlink()
    if proc.returncode not in (0, 1) and not failed:  # collection or usage error
        failed.append(f"pytest exit {proc.returncode}: {proc.stdout[-300:]}")
    return failed, proc.returncode


def plant(repo: Path, mutant: Mutant) -> str:
    """Replace the mutant's text in the copy; returns the original file's text."""
    path = repo / mutant.file
    text = path.read_text()
    count = text.count(mutant.old)
    if count != 1:
        raise ValueError(f"{mutant.file}: the mutant's text occurs {count} times, not once")
    path.write_text(text.replace(mutant.old, mutant.new))
    return text


def verdict(failed: list[str]) -> str:
    behavioural = [f for f in failed if not f.startswith(GENERATED_TEST)]
    if behavioural:
        return "behavioural"
    return "generated files only" if failed else "NOT CAUGHT"


def caught_by(failed: list[str]) -> str:
    """Failing tests grouped by file: ``test_x.py (3)``."""
    files: dict[str, int] = {}
    for f in failed:
        name = f.split("::")[0].rpartition("/")[2]
        files[name] = files.get(name, 0) + 1
    return ", ".join(f"{name} ({count})" for name, count in files.items()) or "-"


def table(rows: list[dict]) -> str:
    lines = ["| # | planted bug | file | caught by (failing tests) | verdict |",
             "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['index']} | {r['name']} | `{r['file']}` | {caught_by(r['failed'])} "
                     f"| {r['verdict']} |")
    return "\n".join(lines)


def commit() -> str:
    proc = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                           capture_output=True, text=True).stdout.strip()
    return (proc.stdout.strip() or "unknown") + (" (with uncommitted changes)" if dirty else "")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rollmpc_codegen.verify.mutation",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", help="comma-separated mutant numbers (1-based), default all")
    ap.add_argument("--json", type=Path, help="write the rows (with failing test ids) here")
    args = ap.parse_args(argv)
    chosen = [(i + 1, m) for i, m in enumerate(MUTANTS)]
    if args.only:
        keep = {int(v) for v in args.only.split(",")}
        chosen = [(i, m) for i, m in chosen if i in keep]
    rows = []
    with tempfile.TemporaryDirectory(prefix="rollmpc-mutation-") as tmp:
        repo, report = copy_repository(Path(tmp)), Path(tmp) / "report.xml"
        selection = tuple(dict.fromkeys(t for _, m in chosen for t in m.tests))
        t0 = time.monotonic()
        failed, status = run_tests(repo, selection, report)
        print(f"baseline: {len(selection)} selections, exit {status}, "
              f"{time.monotonic() - t0:.0f} s", file=sys.stderr, flush=True)
        if failed:
            print(f"the unchanged tree fails: {failed[:5]}", file=sys.stderr)
            return 2
        for index, mutant in chosen:
            t0 = time.monotonic()
            original = plant(repo, mutant)
            try:
                failed, _ = run_tests(repo, mutant.tests, report)
            finally:
                (repo / mutant.file).write_text(original)
            rows.append({"index": index, "name": mutant.name, "file": mutant.file,
                         "failed": failed, "verdict": verdict(failed)})
            print(f"{index:2d} {rows[-1]['verdict']:<20} {time.monotonic() - t0:5.0f} s  "
                  f"{mutant.name}", file=sys.stderr, flush=True)
    print(f"Mutation run on commit {commit()}: "
          f"`python -m rollmpc_codegen.verify.mutation{' --only ' + args.only if args.only else ''}`\n")
    print(table(rows))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"commit": commit(), "rows": rows}, indent=1) + "\n")
    return 0 if all(r["verdict"] == "behavioural" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
