"""Shared helpers of the check scripts: run a command, copy a tree, compile one
translation unit, report what compiled against which commit."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path


def repo_root() -> Path:
    return Path(__file__).resolve().parents[3]


def run(cmd: list[str], cwd: Path | None = None, env: dict | None = None) -> str:
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        shown = " ".join(cmd if len(cmd) < 12 else cmd[:6] + ["..."] + cmd[-4:])
        sys.exit(f"failed: {shown}\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}")
    return proc.stdout


def copy_tree(src: Path, dst: Path) -> None:
    shutil.copytree(src, dst, dirs_exist_ok=True,
                    ignore=shutil.ignore_patterns("*.json", ".rollmpc-manifest", "__pycache__"))


def compile_unit(compiler: str, flags: list[str], src: Path, build: Path, unit: str | None = None,
                 cwd: Path | None = None) -> tuple[str, str]:
    """Compile src to an object in build/obj, from cwd (the build system's directory);
    returns (unit, '' or the compiler's output). unit names the result (default: the file)."""
    unit = unit or src.name
    obj = build / "obj" / (unit.replace("/", "_") + ".o")
    obj.parent.mkdir(parents=True, exist_ok=True)
    proc = subprocess.run([compiler, *flags, "-c", str(src), "-o", str(obj)],
                          capture_output=True, text=True, cwd=cwd)
    out = proc.stdout + proc.stderr
    return unit, out if (proc.returncode != 0 or out.strip()) else ""


def tree_commit(tree: Path) -> str:
    """The commit of a git checkout, else the COMMIT file an export may carry, else '?'."""
    proc = subprocess.run(["git", "-C", str(tree), "rev-parse", "HEAD"], capture_output=True,
                          text=True)
    if proc.returncode == 0:
        return proc.stdout.strip()
    marker = tree / "COMMIT"
    return marker.read_text().strip() if marker.exists() else "?"


class Report:
    """Per-unit results; finish() prints them and returns the exit status."""

    def __init__(self, name: str, tree: Path):
        self.name, self.tree, self.results = name, tree, []

    def add(self, result: tuple[str, str]) -> None:
        self.results.append(result)

    def finish(self) -> int:
        print(f"{self.name}: tree {self.tree} at commit {tree_commit(self.tree)}")
        for unit, out in self.results:
            print(f"  {'ok  ' if not out else 'FAIL'} {unit}")
            if out:
                print("    " + out.strip().replace("\n", "\n    "))
        bad = sum(1 for _, out in self.results if out)
        print(f"{self.name}: {len(self.results) - bad} compiled cleanly, {bad} failed")
        return 1 if bad else 0
