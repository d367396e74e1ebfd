"""Shared fixtures: the paper's controller in both precisions, built once per session."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

# one BLAS thread (as `make test` sets): the QPs are small and threaded OpenBLAS is ~10x
# slower on the 2-core machines under load; effective when numpy is not imported yet
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
UAV = ROOT / "examples" / "uav_roll.yaml"


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", help="run the long (slow) tests")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="long run: use make check-long (pytest --runslow -m slow)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def require_tool(name: str, install: str) -> str:
    """Path of a command-line tool, or skip saying how to install it."""
    path = shutil.which(name)
    if path is None:
        pytest.skip(f"{name} not found; install with: {install}")
    return path


@pytest.fixture(scope="session")
def build_root(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("cbuild")


class Built:
    """Model, context and compiled C of one configuration."""

    def __init__(self, config: Path, precision: str, build_root: Path):
        from rollmpc_codegen.build import build_host_controller
        from rollmpc_codegen.generate import load_model

        self.model, self.ctx = load_model(config, precision)
        self.build_root = build_root
        self.c = build_host_controller(self.ctx, build_root)

    def fresh_c(self):
        """A second, independent controller instance from the same library."""
        from rollmpc_codegen.build import build_host_controller

        return build_host_controller(self.ctx, self.build_root)

    def reference(self):
        from rollmpc_codegen.controller_ref import ControllerRef

        return ControllerRef(self.ctx, [m.data for m in self.model.modes])


@pytest.fixture(scope="session", params=["double", "float"])
def uav(request, build_root) -> Built:
    return Built(UAV, request.param, build_root)


@pytest.fixture(scope="session")
def uav_double(build_root) -> Built:
    return Built(UAV, "double", build_root)


def variant_config(tmp_path: Path, name: str = "variant", **solver) -> Path:
    """examples/uav_roll.yaml with solver settings overridden, written to tmp_path."""
    import yaml

    data = yaml.safe_load(UAV.read_text())
    data["solver"] = {**data.get("solver", {}), **solver}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def short_uav_config(tmp_path: Path, horizon: int = 20, name: str = "uav_short", **solver) -> Path:
    """The UAV config with a shorter horizon: same plants and templates, small data (fast builds)."""
    import yaml

    path = variant_config(tmp_path, name, **solver)
    data = yaml.safe_load(path.read_text())
    data["horizon"] = horizon
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
