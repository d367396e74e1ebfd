"""target/cache_lines.py decodes each load and store's addresses (DataTracer) instead of
taking them from a unicorn memory hook, which skipped a 16-bit load on fw_lateral's steps
572 and 760. On a step where the hook runs right, both see the same bytes and the cache
the same misses."""
from __future__ import annotations

from pathlib import Path

import pytest

from conftest import require_tool

DESIGN = Path(__file__).resolve().parents[1] / "data" / "fast" / "dcmotor_cur.yaml"
ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"
STEP = 40  # braking at the current limit: the polish and its rows run


def touched_and_misses(model, ctx, build_root, hook_kind, make_callback):
    from rollmpc_codegen.target.cache_lines import Cache, emulator_at_step, run_step_with

    em, record = emulator_at_step(model, ctx, build_root, STEP)
    seen, cache = set(), Cache()
    original = cache.access

    def access(address, size=1):
        seen.update(range(address, address + size))
        original(address, size)
    cache.access = access
    u = run_step_with(em, ctx, [(hook_kind, make_callback(cache))])
    assert u.tobytes() == record.u[STEP].tobytes()
    return seen, cache.misses


def test_decoded_data_accesses_match_the_memory_hook(build_root):
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")
    from unicorn import UC_HOOK_CODE, UC_HOOK_MEM_READ, UC_HOOK_MEM_WRITE

    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.target.cache_lines import DataTracer

    model, ctx = load_model(DESIGN, "float", "stm32h743")
    by_hook = touched_and_misses(
        model, ctx, build_root, UC_HOOK_MEM_READ | UC_HOOK_MEM_WRITE,
        lambda cache: lambda uc, _kind, address, size, _value, _u: cache.access(address, size))
    decoded = touched_and_misses(model, ctx, build_root, UC_HOOK_CODE, DataTracer)
    assert len(decoded[0]) > 1000  # the step reads the design's data
    assert decoded == by_hook
