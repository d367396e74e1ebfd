"""The ``generate`` pipeline: config file -> model -> context -> rendered sources on disk."""
from __future__ import annotations

from pathlib import Path

from . import config as config_mod
from .context import ControllerModel, build_context, build_model
from .render import render_sources, write_atomically


def load_model(config_path: str | Path, precision: str | None = None) -> tuple[ControllerModel, dict]:
    """Validate the config and compute every static matrix; returns (model, context)."""
    cfg = config_mod.load(config_path, precision)
    model = build_model(cfg)
    return model, build_context(model)


def generate(config_path: str | Path, out_dir: str | Path,
             precision: str | None = None) -> tuple[ControllerModel, dict]:
    """Render the controller for ``config_path`` into ``out_dir`` (replaced atomically)."""
    model, ctx = load_model(config_path, precision)
    write_atomically(render_sources(ctx), Path(out_dir))
    return model, ctx
