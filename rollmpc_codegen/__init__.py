"""rollmpc: YAML -> switched linear MPC -> static C99 with a Hildreth-family QP solver.

Pipeline (one folder per stage, pipeline.py runs them): config -> model -> qp (+ features)
-> codegen; then host / target / sim on the compiled C. The Python API (api.py):
``Design``, ``Mode`` and ``CompiledController``, imported on first use so that
``import rollmpc_codegen`` stays cheap.
"""
__version__ = "0.1.0"

from .model.blas_kernels import pin_kernels as _pin_kernels

_pin_kernels()  # before any module of ours imports NumPy: model/blas_kernels.py says why

# name -> the module that defines it (PEP 562: loaded when first asked for)
_LAZY = {"Design": "api", "Mode": "api", "CompiledController": "api", "ConfigError": "config",
         "DesignWarning": "config", "RollmpcWarning": "config"}
__all__ = ["__version__", *_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
