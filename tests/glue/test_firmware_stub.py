"""firmware_stub: the stub and the generated C compile under PX4's and ArduPilot's flags,
`make firmware` cross-compiles warning-free, and the host-HAL stub closes the loop
against the simulated plant (tracking, failsafe counting, bit-identical to P_step)."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import ROOT, UAV, require_tool
from rollmpc_codegen.parts import DEFAULT_PART, PARTS
from rollmpc_codegen.pipeline import generate

ARM_HINT = "apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi"
STUB = ROOT / "firmware_stub"
# PX4's C warning flags (cmake/px4_add_common_flags.cmake) and ArduPilot's frame limit
PX4_CFLAGS = ["-Werror", "-Wdouble-promotion", "-Wfloat-equal", "-Wshadow", "-Wcast-align",
              "-Wstrict-prototypes", "-Wbad-function-cast", "-Wnested-externs", "-fno-common"]
ARDUPILOT_CFLAGS = ["-Werror", "-Wframe-larger-than=1300", "-fsingle-precision-constant"]
STUB_SOURCES = [STUB / "rollctl.c", STUB / "app_main.c", STUB / "host" / "rollctl_hal_host.c"]


@pytest.fixture(scope="module")
def trees(tmp_path_factory) -> dict[str, Path]:
    """The paper's controller generated in both precisions (once per module)."""
    out = {}
    for precision in ("float", "double"):
        out[precision] = tmp_path_factory.mktemp(f"fw_{precision}") / "uav_roll"
        generate(UAV, out[precision], precision)
    return out


@pytest.fixture(scope="module")
def generated_f32(trees) -> Path:
    return trees["float"]


@pytest.mark.parametrize("precision", ["float", "double"])
def test_generated_c_and_stub_compile_under_autopilot_flags(trees, tmp_path, precision):
    """PX4's and ArduPilot's flags together (a superset: any warning of either fails).

    The double tree is built without -fsingle-precision-constant: that flag rounds every
    unsuffixed literal, the whole of the double data, to float (firmware_stub/README.md).
    """
    generated = trees[precision]
    sources = sorted(generated.glob("*.c")) + STUB_SOURCES
    flags = set(PX4_CFLAGS) | set(ARDUPILOT_CFLAGS)
    if precision == "double":
        flags.discard("-fsingle-precision-constant")
    for src in sources:
        cmd = ["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", *sorted(flags), f"-I{generated}",
               f"-I{STUB}", "-c", str(src), "-o", str(tmp_path / (src.stem + ".o"))]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        assert proc.returncode == 0 and proc.stderr == "", f"{src.name}: {proc.stderr}"


@pytest.mark.parametrize("part, precision", [(None, "float"), ("stm32h743", "double"),
                                             ("stm32l562", "float")],
                         ids=["default", "stm32h743-double", "stm32l562"])
def test_make_firmware_is_warning_free(generated_f32, tmp_path, part, precision):
    """The stub builds for the part its tree was generated for (<prefix>_target.mk): the
    core's flags, the part's flash and RAM regions (the default: the STM32F427's)."""
    require_tool("arm-none-eabi-gcc", ARM_HINT)
    tree = generated_f32
    if part is not None:
        tree = tmp_path / "gen"
        generate(UAV, tree, precision, part=part)
    decl = PARTS[part or DEFAULT_PART]
    proc = subprocess.run(["make", "--no-print-directory", "firmware", "size",
                           f"FW_GEN={tree}", f"FW_BUILD={tmp_path / 'fw'}"],
                          cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert not re.search(r"warning:", proc.stdout + proc.stderr)
    assert " ".join(decl.core.cflags) in proc.stdout
    elf = tmp_path / "fw" / f"rollctl_{decl.core.short}.elf"
    assert elf.exists()
    m = re.search(r"flash (\d+) B \(text \+ data\), static RAM (\d+) B", proc.stdout)
    assert m, proc.stdout
    flash, ram = int(m.group(1)), int(m.group(2))
    assert 0 < flash <= decl.flash.kib * 1024 and 0 < ram <= decl.ram.kib * 1024
    # the vector table: initial SP at the top of the part's RAM region, reset vector in
    # Thumb state
    from elftools.elf.elffile import ELFFile

    with open(elf, "rb") as fh:
        ef = ELFFile(fh)
        vec = ef.get_section_by_name(".isr_vector")
        assert vec["sh_addr"] == decl.flash.origin
        sp, reset = np.frombuffer(vec.data()[:8], "<u4")
        symbols = {s.name: s["st_value"] for s in ef.get_section_by_name(".symtab").iter_symbols()}
        double_ops = b"vmul.f64" in subprocess.run(
            ["arm-none-eabi-objdump", "-d", str(elf)], capture_output=True).stdout
    assert sp == decl.ram.origin + decl.ram.kib * 1024
    assert reset == symbols["Reset_Handler"] and reset & 1
    assert double_ops == (precision == "double")  # the M7's FPU computes the double tree


def test_px4_parameter_names_fit_16_characters():
    module = yaml.safe_load((STUB / "integration" / "px4" / "rollmpc" / "module.yaml").read_text())
    names = [n for group in module["parameters"] for n in group["definitions"]]
    assert names and all(len(n) <= 16 for n in names), names
    cmake = (STUB / "integration" / "px4" / "rollmpc" / "CMakeLists.txt").read_text()
    stack_max = int(re.search(r"STACK_MAX\s+(\d+)", cmake).group(1))
    assert stack_max <= 2240  # the nav_and_controllers work queue's whole stack


# ----------------------------------------------------------------------------- host loop
@pytest.fixture(scope="module")
def host_stub(generated_f32, tmp_path_factory) -> Path:
    build = tmp_path_factory.mktemp("fw_host")
    proc = subprocess.run(["make", "--no-print-directory", "-f", "firmware_stub/firmware.mk",
                           "host", f"FW_GEN={generated_f32}", f"FW_BUILD={build}"],
                          cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0 and not re.search(r"warning:", proc.stderr), proc.stderr
    return build / "rollctl_host"


class StubProcess:
    """The host stub behind a pipe: one sample per line in, one line out."""

    def __init__(self, exe: Path):
        self.proc = subprocess.Popen([str(exe)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True, bufsize=1)

    def sample(self, roll, rate, cmd, valid=True, preview=()):
        fields = [float(roll).hex(), float(rate).hex(), float(cmd).hex(), "1" if valid else "0",
                  *(float(p).hex() for p in preview)]
        self.proc.stdin.write(" ".join(fields) + "\n")
        self.proc.stdin.flush()
        parts = self.proc.stdout.readline().split()
        u = np.array([float.fromhex(p) for p in parts[:2]])
        return u, int(parts[2]), int(parts[3]), int(parts[4])

    def close(self) -> int:
        self.proc.stdin.close()
        return self.proc.wait(timeout=10)


def test_host_stub_closes_the_loop_with_failsafe(host_stub, generated_f32, build_root):
    """-20 deg command held over the horizon; one missing IMU sample at step 300."""
    from rollmpc_codegen.host.build import build_host_controller
    from rollmpc_codegen.pipeline import load_model
    from rollmpc_codegen.sim.scenario import SimulatedPlant

    model, ctx = load_model(UAV, "float")
    plant = SimulatedPlant(model.config)
    direct = build_host_controller(ctx, build_root)  # the same C without the stub
    stub = StubProcess(host_stub)
    bad, steps, cmd = 300, 700, -20.0
    ys, us, events = [], [], []
    for k in range(steps):
        y = plant.outputs()[0]
        rate = plant.schedule_signal()[0]
        valid = k != bad
        u, status, failsafe, mode = stub.sample(y, rate, cmd, valid)
        nan = np.float32(np.nan)
        ref_status, ref_u = direct.step([y if valid else nan], [rate if valid else nan],
                                        np.full(ctx["horizon"], cmd))
        # the stub adds nothing to the controller while it is optimal, and on the missing
        # sample both hold the last (good) command
        assert u.astype(np.float32).tobytes() == ref_u.tobytes(), k
        assert status == ref_status
        if k == bad:
            assert status == 4 and np.array_equal(u, us[-1])
        ys.append(y)
        us.append(u)
        events.append(failsafe)
        plant.advance(u)
    assert stub.close() == 0
    assert events[bad - 1] == 0 and events[bad] == 1 and events[-1] == 1
    assert np.abs(np.array(us)).max() <= 15.0
    assert abs(ys[-1] - cmd) < 0.05, ys[-1]  # settled on the command
    assert min(ys) > cmd - 2.0  # no large overshoot


def test_host_stub_uses_the_preview(host_stub, generated_f32, build_root):
    from rollmpc_codegen.host.build import build_host_controller
    from rollmpc_codegen.pipeline import load_model

    model, ctx = load_model(UAV, "float")
    direct = build_host_controller(ctx, build_root)
    stub = StubProcess(host_stub)
    N = ctx["horizon"]
    for k in range(30):
        preview = np.linspace(0.0, -5.0, 40) + 0.1 * k  # shorter than N: held at its end
        r = np.concatenate([preview, np.full(N - len(preview), preview[-1])])
        u, status, _, _ = stub.sample(0.1 * k, 0.0, 99.0, True, preview)
        ref_status, ref_u = direct.step([0.1 * k], [0.0], r)
        assert status == ref_status
        assert u.astype(np.float32).tobytes() == ref_u.tobytes(), k
    assert stub.close() == 0
