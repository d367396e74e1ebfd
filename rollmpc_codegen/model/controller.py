"""The offline model of a whole controller: per mode, the plant, its QP, its observer and the
data the C stores.  Plain frozen data, built by :func:`rollmpc_codegen.pipeline.build_model`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import ControllerConfig
from ..qp.condense import CondensedQP
from ..qp.storage import ModeData, dtype_of
from .plant import DiscretePlant


@dataclass(frozen=True)
class ModeModel:
    plant: DiscretePlant
    qp: CondensedQP
    observer_gain: np.ndarray
    observer_poles: tuple
    data: ModeData


@dataclass(frozen=True)
class ControllerModel:
    config: ControllerConfig
    modes: tuple[ModeModel, ...]

    @property
    def dtype(self):
        return dtype_of(self.config.precision)
