"""The parts (rollmpc_codegen/parts.py): each declaration is selected by target.part or
target.core, judges the design (work budget, footprint, report's verdict), renders the
tree's P_target.mk, and runs on its emulated core bit for bit with the host build in the
precision its FPU computes. The invariants at the top hold for every declared part and
core, so a new part is tested by declaring it."""
from __future__ import annotations

import json
import subprocess

import pytest

from conftest import UAV, config_error, require_tool, short_uav_config
from rollmpc_codegen.config import load
from rollmpc_codegen.config.canonical import canonical_json
from rollmpc_codegen.parts import CORES, DEFAULT_PART, PARTS
from rollmpc_codegen.qp.work import STEP_FIXED_UNITS

ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"


def target_tools():
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    for module in ("unicorn", "capstone", "elftools"):
        pytest.importorskip(module, reason="pip install 'rollmpc-codegen[target]'")


# ----------------------------------------------------------------------------- declarations
@pytest.mark.parametrize("name", sorted(PARTS))
def test_every_part_is_complete(name):
    p = PARTS[name]
    assert p.name == name and p.core in CORES.values() and p.cpu_mhz > 0
    assert p.flash.origin in (0x0, 0x08000000) and p.flash.kib >= 256 and p.ram.kib >= 64
    assert 0x20000000 <= p.ram.origin < 0x30000000 and p.boards  # the ARMv7-M SRAM region


@pytest.mark.parametrize("name", sorted(CORES))
def test_every_core_is_complete(name):
    """Its flags select the FPU it declares, unicorn knows its CPU, its cycle model
    exists, and it has a work-unit cost in every precision its FPU computes."""
    from rollmpc_codegen.target.cycle_models import MODELS

    core = CORES[name]
    fpu = next(f for f in core.cflags if f.startswith("-mfpu="))
    assert ("-sp-" not in fpu) == core.fpu_double and "-mfloat-abi=hard" in core.cflags
    assert core.cycle_model in MODELS and core.code_bytes >= 32 * 1024
    precisions = dict(core.work_unit_cycles)
    assert set(precisions) == ({"float", "double"} if core.fpu_double else {"float"})
    assert all(0 < c <= 30 for c in precisions.values())
    assert core.cycles_per_work_unit("double") == precisions[core.judged_precision("double")]
    unicorn = pytest.importorskip("unicorn", reason="pip install 'rollmpc-codegen[target]'")
    assert hasattr(unicorn.arm_const, core.emulator_cpu)


# ----------------------------------------------------------------------------- config
def test_a_part_gives_its_core_clock_and_memory(tmp_path):
    cfg = load(short_uav_config(tmp_path), part="stm32h743")
    t = cfg.target
    assert (t.part, t.core, t.cpu_mhz, t.flash_kib, t.ram_kib) == \
        ("stm32h743", "cortex-m7", 480.0, 2048.0, 512.0)
    assert cfg.cycles_per_sample == 4_800_000 and "STM32H743" in t.label


@pytest.mark.parametrize("target, expect", [
    ({"part": "stm32f765", "cpu_mhz": 200}, ("stm32f765", "cortex-m7", 200.0, 2048.0)),
    ({"core": "cortex-m33", "cpu_mhz": 64}, (None, "cortex-m33", 64.0, None)),
    ({}, (None, "cortex-m4f", 168.0, None)),
])
def test_the_target_section(tmp_path, target, expect):
    import yaml

    path = short_uav_config(tmp_path)
    data = yaml.safe_load(path.read_text())
    data["target"] = target
    t = load_data(data).target
    assert (t.part, t.core, t.cpu_mhz, t.flash_kib) == expect


def load_data(data):
    from rollmpc_codegen.config import parse

    return parse(data)


@pytest.mark.parametrize("target, message", [
    ({"part": "stm32f999"}, "target.part: unknown part 'stm32f999'; one of "),
    ({"core": "cortex-m0"}, "target.core: unknown core 'cortex-m0'; one of "),
    ({"part": "stm32h743", "core": "cortex-m4f"}, "target.core: stm32h743 is a cortex-m7"),
])
def test_a_bad_target_is_one_error_naming_the_key(tmp_path, target, message):
    import yaml

    data = yaml.safe_load(short_uav_config(tmp_path).read_text())
    data["target"] = target
    assert str(config_error(data, load_data)).startswith(message)


def test_an_unknown_part_option_names_the_option(capsys):
    from rollmpc_codegen.cli.main import main

    assert main(["generate", str(UAV), "--part", "stm32f999", "-o", "/nonexistent/x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rollmpc: error: --part: unknown part")


def test_the_default_part_keeps_every_design_hash(tmp_path):
    """A config that names no part has no part or core in its canonical text (so the
    generated trees of every example keep their hash); naming one changes the hash."""
    path = short_uav_config(tmp_path)
    plain = load(path)
    assert '"part"' not in canonical_json(plain) and '"core"' not in canonical_json(plain)
    assert load(path, part=DEFAULT_PART).config_hash != plain.config_hash
    assert plain.target.core == PARTS[DEFAULT_PART].core.name
    assert plain.target.cpu_mhz == PARTS[DEFAULT_PART].cpu_mhz


# ----------------------------------------------------------------------------- judged on it
def auto_budget(tmp_path, precision, part):
    from rollmpc_codegen.pipeline import load_model

    path = short_uav_config(tmp_path, work_budget="auto")
    return load_model(path, precision, part)[1]


@pytest.mark.parametrize("part, precision", [(None, "float"), (None, "double"),
                                             ("stm32h743", "float"), ("stm32h743", "double"),
                                             ("stm32l562", "float")])
def test_the_auto_work_budget_is_the_parts(tmp_path, part, precision):
    """Half of Ts at the part's clock over its core's cycles per unit in the precision it
    runs (the M4F's double tree is judged as its float build), less the step's fixed
    units, and P_target.mk names it."""
    ctx = auto_budget(tmp_path, precision, part)
    decl = PARTS[part or DEFAULT_PART]
    per_unit = decl.core.cycles_per_work_unit(precision)
    assert ctx["solver"]["work_budget"] == \
        int(0.01 * 0.5 * decl.cpu_mhz * 1e6 / per_unit) - STEP_FIXED_UNITS
    from rollmpc_codegen.codegen.render import render_sources

    mk = render_sources(ctx)["rollmpc_target.mk"]
    assert f"rollmpc_target_cflags := {' '.join(decl.core.cflags)}\n" in mk
    assert f"rollmpc_target_ram_origin := 0x{decl.ram.origin:08X}\n" in mk
    assert f"rollmpc_target_cpu_hz := {int(decl.cpu_mhz * 1e6)}\n" in mk


def test_the_footprint_is_judged_in_the_precision_the_fpu_runs(tmp_path):
    from rollmpc_codegen.qp.footprint import predict

    path = short_uav_config(tmp_path)
    m4f, m7 = predict(load(path, "double")), predict(load(path, "double", "stm32h743"))
    assert (m4f.judged, m7.judged) == ("float", "double")
    assert m7.flash_bytes - m7.code_bytes == m7.data_bytes  # the double data, in flash
    assert m4f.flash_bytes - m4f.code_bytes < m4f.data_bytes  # its float build's
    assert m7.summary()[0].startswith("predicted on STM32H743")


# ----------------------------------------------------------------------------- on the core
@pytest.mark.parametrize("part, precision", [("stm32h743", "double"),
                                             pytest.param("stm32h743", "float",
                                                          marks=pytest.mark.slow),
                                             ("stm32l562", "float")])
def test_report_on_the_part_is_bit_exact(tmp_path, build_root, part, precision):
    """Host C == the emulated part, in the precision it runs, through the first reference
    step (the preview reaches it at step 980); the M7's double build computes with the
    FPU's double instructions, which unicorn's M7 executes (its M33 refuses them)."""
    target_tools()
    from rollmpc_codegen.target.report import run_report

    rep = run_report(short_uav_config(tmp_path), precision=precision, part=part, steps=1010,
                     sample_every=100, hardest=2, host_repeats=1, build_dir=build_root)
    assert rep["bit_exact_vs_host"] and rep["state_bit_exact"] and rep["mismatches"] == 0
    assert rep["budget"]["part"] == part and rep["budget"]["cpu_mhz"] == PARTS[part].cpu_mhz
    assert rep["cflags"].startswith(" ".join(PARTS[part].core.cflags))
    assert PARTS[part].core.label in rep["cycle_model"]
    assert rep["worst_step"] >= 980 and rep["worst_step_cycles"] > rep["median_step_cycles"]


def test_a_double_build_uses_the_fpu_on_the_m7_and_libgcc_on_the_m4f(tmp_path, build_root):
    target_tools()
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.target.build import build_target

    dumps = {}
    for part in ("stm32h743", "stm32f427"):
        _model, ctx = load_model(short_uav_config(tmp_path), "double", part)
        elf = build_target(ctx, build_root).elf
        dumps[part] = subprocess.run(["arm-none-eabi-objdump", "-d", str(elf)],
                                     capture_output=True, text=True).stdout
    assert "vmul.f64" in dumps["stm32h743"] and "__aeabi_dmul" not in dumps["stm32h743"]
    assert "vmul.f64" not in dumps["stm32f427"] and "__aeabi_dmul" in dumps["stm32f427"]


def test_the_report_cli_takes_the_part(tmp_path, build_root, capsys):
    target_tools()
    from rollmpc_codegen.cli.main import main

    out = tmp_path / "r.json"
    assert main(["report", str(short_uav_config(tmp_path)), "--part", "stm32f765",
                 "--precision", "double", "--steps", "30", "--sample-every", "10",
                 "--hardest", "1", "--host-repeats", "1", "--quiet", "--json", str(out),
                 "--build-dir", str(build_root)]) == 0
    rep = json.loads(out.read_text())
    assert rep["budget"]["part"] == "stm32f765" and rep["precision"] == "double"
    assert "on STM32F765 (Cortex-M7 (FPv5-D16)) at 216 MHz the worst step fits" in \
        capsys.readouterr().out
