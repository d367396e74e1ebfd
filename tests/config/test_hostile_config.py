"""Hostile configurations (docs/reliability.md, "Hostile input"): each finding of an audit, with the exact one-line
message, exit code 2 and nothing written (docs/reliability.md, "Hostile input").

Each test failed on the old behaviour (46cf995): a name ending in a newline and the prefix
``math`` were accepted, an alias bomb took minutes and gigabytes, ``R: 1e308`` printed
three lines naming no key, ``delta: 1e-50`` became ``0.0f``, ``horizon: 10000`` condensed
for minutes.  The cases that ran for minutes (or hung) then run in a subprocess with a
timeout and an address-space limit, so that on old code they fail instead of stalling.
"""
from __future__ import annotations

import copy
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from rollmpc_codegen.cli import main as cli
from rollmpc_codegen.config import ConfigError, load, parse
from rollmpc_codegen.config.errors import ECHO_MAX
from rollmpc_codegen.config.schema import RESERVED_PREFIXES
from rollmpc_codegen.pipeline import load_model_from_config
from rollmpc_codegen.qp.arrays import REAL, declared_for
from rollmpc_codegen.qp.sizes import (C_TYPE_BYTES, features_of, mode_sizes, stored_bytes,
                                      struct_bytes)
from test_config_errors import (BASE, ROOT, UAV, _assert_nothing_written, _write, both, drop,
                                set_, text)

EXAMPLES = sorted((ROOT / "examples").glob("*.yaml"))
SLOW_BEFORE = 120  # s: the old code ran longer than this on every subprocess case


@pytest.fixture(autouse=True)
def no_debug(monkeypatch):
    monkeypatch.delenv("ROLLMPC_DEBUG", raising=False)  # it turns errors into tracebacks


def _generate(tmp_path: Path, capsys, mutate) -> str:
    """``rollmpc generate`` in process on the mutated paper config: its stderr, after
    checking exit code 2, an empty stdout and nothing written."""
    config = _write(tmp_path, mutate)
    (tmp_path / "gen").mkdir()
    out = tmp_path / "gen" / "out"
    rc = cli.main(["generate", str(config), "-o", str(out)])
    captured = capsys.readouterr()
    assert rc == 2, captured.err
    assert captured.out == ""
    _assert_nothing_written(out)
    return captured.err


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))


def _generate_bounded(tmp_path: Path, config: Path) -> tuple[str, float]:
    """``rollmpc generate`` in a subprocess (timeout, 2 GiB of address space): its stderr
    after checking exit code 2 and nothing written, and its wall time."""
    (tmp_path / "gen").mkdir()
    out = tmp_path / "gen" / "out"
    env = {k: v for k, v in os.environ.items() if k != "ROLLMPC_DEBUG"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env["OPENBLAS_NUM_THREADS"] = "1"
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "rollmpc_codegen.cli.main", "generate", str(config), "-o",
         str(out)], capture_output=True, text=True, env=env, timeout=SLOW_BEFORE,
        preexec_fn=_limit_memory)
    assert proc.returncode == 2, proc.stderr[:2000]
    _assert_nothing_written(out)
    return proc.stderr, time.perf_counter() - start


# --------------------------------------------------------------------------- 1. names
NEWLINE_NAMES = [
    pytest.param(set_("prefix", "rollmpc\n"), "prefix: must be a lower-case C identifier of "
                 "at most 31 characters, got 'rollmpc\\n'", id="prefix"),
    pytest.param(set_("outputs", ["roll\n"]), "outputs[0]: must be a C identifier-like name, "
                 "got 'roll\\n'", id="output"),
    pytest.param(set_("actuators", ["inner", "outer\n"]), "actuators[1]: must be a C "
                 "identifier-like name, got 'outer\\n'", id="actuator"),
    pytest.param(set_("modes[1].name", "outer\n"), "modes[1].name: must be an identifier-like "
                 "name, got 'outer\\n'", id="mode-name"),
    pytest.param(set_("scheduler.signal", "roll_rate\n"), "scheduler.signal: must be an "
                 "identifier-like name, got 'roll_rate\\n'", id="schedule-signal"),
]


@pytest.mark.parametrize("mutate, message", NEWLINE_NAMES)
def test_a_name_ending_in_a_newline_is_refused(tmp_path, capsys, mutate, message):
    assert _generate(tmp_path, capsys, mutate) == f"rollmpc: error: {message}\n"


# --------------------------------------------------------------------------- 2. prefixes
# Written out here, from the standards, rather than taken from schema.py: the test checks
# that list.  C89/C90, C95, C99, C11 and C23 headers.
C_STANDARD = ("assert complex ctype errno fenv float inttypes iso646 limits locale math "
              "setjmp signal stdalign stdarg stdatomic stdbit stdbool stdckdint stddef stdint "
              "stdio stdlib stdnoreturn string tgmath threads time uchar wchar wctype").split()
COMMON_SYSTEM = "unistd pthread fcntl malloc alloca strings memory endian arm_math main".split()


@pytest.mark.parametrize("prefix", C_STANDARD + COMMON_SYSTEM)
def test_a_prefix_that_shadows_a_system_header_is_refused(prefix):
    data = copy.deepcopy(BASE)
    data["prefix"] = prefix
    with pytest.raises(ConfigError) as err:
        parse(data)
    assert str(err.value) == (f"prefix: {prefix!r} would write {prefix}.h, which shadows the "
                              f"system header <{prefix}.h>; choose another prefix")


def test_the_reserved_list_is_the_standard_and_the_common_headers():
    assert set(C_STANDARD + COMMON_SYSTEM) <= set(RESERVED_PREFIXES)
    assert len(set(RESERVED_PREFIXES)) == len(RESERVED_PREFIXES)
    for fine in ("rollmpc", "math_ctrl", "mathx", "timing", "uav_roll"):  # still allowed
        assert parse(dict(BASE, prefix=fine)).prefix == fine


def test_prefix_math_writes_nothing(tmp_path, capsys):
    err = _generate(tmp_path, capsys, set_("prefix", "math"))
    assert err == ("rollmpc: error: prefix: 'math' would write math.h, which shadows the "
                   "system header <math.h>; choose another prefix\n")


# --------------------------------------------------------------------------- 3. YAML
ANCHORS = "[" + ", ".join(["&a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"] + [
    f"&a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 9)]) + "]"


def _bomb(target: str, alias: str) -> str:
    """The paper's config with nine levels of nine-fold aliases (9^9 ones, 387 million)
    anchored under ``units`` (parsed last, written first) and aliased at ``target``."""
    body = UAV.read_text().replace("units: {outputs: deg, actuators: deg, schedule: deg/s}",
                                   "")
    assert target in body
    return f"units: {{outputs: {ANCHORS}}}\n" + body.replace(target, alias, 1)


BOMBS = [
    pytest.param("weights: {Q: 10, R: 10, P: 1.0e6}", "weights: {Q: [[*a8]], R: 10, P: 1.0e6}",
                 id="weights-Q"),
    pytest.param("outputs: [roll]", "outputs: *a8", id="outputs"),
]


@pytest.mark.parametrize("target, alias", BOMBS)
def test_an_alias_bomb_is_refused_at_once(tmp_path, target, alias):
    config = tmp_path / "bomb.yaml"
    config.write_text(_bomb(target, alias))
    assert config.stat().st_size < 3000
    err, seconds = _generate_bounded(tmp_path, config)
    # refused on line 1, where the anchors already repeat 9 + 9 * 10 + ... nodes
    assert err == ("rollmpc: error: <yaml line 1>: the aliases repeat more than 10000 nodes "
                   "(an alias bomb?)\n")
    assert seconds < 60  # was 108 s and 2.19 GB (weights.Q), > 300 s (outputs)


YAML_CASES = [
    pytest.param(text("prefix: &p [rollmpc, *p]\n"), "<yaml line 1>: alias *p inside its own "
                 "anchor (a recursive structure)", id="recursive-alias"),
    pytest.param(text("prefix: " + "[" * 2000 + "]" * 2000 + "\n"),  # was a RecursionError
                 "<yaml line 1>: nested deeper than 32 levels", id="deep-nesting"),
    pytest.param(text("prefix: [" + ", ".join(["1"] * 100_001) + "]\n"),
                 "<yaml line 1>: more than 100000 YAML nodes", id="too-many-nodes"),
    pytest.param(set_("modes[0].weights.Q", [[1.0] * 300]), "modes[0].weights.Q[0]: has 300 "
                 "entries; at most 256 supported", id="long-row"),
    pytest.param(set_("outputs", [f"y{i}" for i in range(257)]), "outputs: has 257 entries; "
                 "at most 256 supported", id="many-names"),
    pytest.param(set_("simulation.reference", {"levels": [0.0] * 257, "segment": 1.0}),
                 "simulation.reference.levels: has 257 entries; at most 256 supported",
                 id="many-levels"),
]


@pytest.mark.parametrize("mutate, message", YAML_CASES)
def test_hostile_yaml_is_refused(tmp_path, capsys, mutate, message):
    assert _generate(tmp_path, capsys, mutate) == f"rollmpc: error: {message}\n"


def test_a_file_beyond_one_mebibyte_is_refused(tmp_path, capsys):
    padding = "# " + "x" * (1 << 20) + "\n"  # a valid config after a long comment
    err = _generate(tmp_path, capsys, text(padding + UAV.read_text()))
    assert err == (f"rollmpc: error: {tmp_path / 'config.yaml'}: larger than 1048576 bytes "
                   "(the limit of a configuration file)\n")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
def test_dev_zero_is_read_with_a_limit():
    with pytest.raises(ConfigError) as err:  # was a MemoryError after filling the memory
        load("/dev/zero")
    assert str(err.value) == ("/dev/zero: larger than 1048576 bytes (the limit of a "
                              "configuration file)")


def test_a_fifo_without_a_writer_does_not_hang(tmp_path):
    fifo = tmp_path / "config.fifo"
    os.mkfifo(fifo)
    err, seconds = _generate_bounded(tmp_path, fifo)  # was: waiting for a writer forever
    assert err == "rollmpc: error: <top>: the file is empty\n"


ECHOED = [
    pytest.param(set_("prefix", "x" * 100_000), "prefix: must be a lower-case C identifier",
                 id="long-value"),
    pytest.param(set_("k" * 100_000, 1), "kkkk", id="long-unknown-key"),
    pytest.param(set_("modes[0].weights.Q", [[[1.0] * 250 for _ in range(250)]]),
                 "modes[0].weights.Q[0][0]: must be a number, got [1.0, 1.0,", id="long-matrix"),
]


@pytest.mark.parametrize("mutate, start", ECHOED)
def test_every_echoed_value_is_bounded(tmp_path, capsys, mutate, start):
    err = _generate(tmp_path, capsys, mutate)
    (line,) = err.splitlines()
    assert line.startswith(f"rollmpc: error: {start}")
    assert len(line) <= len("rollmpc: error: : ") + 2 * ECHO_MAX  # was up to 522 MB
    assert "characters] ..." in line


# --------------------------------------------------------------------------- 4. numbers
WEIGHT_RANGE = ("is out of range in double precision: a nonzero weight w needs 1.11e-308 "
                "<= |w| <= 2.25e+307 (2w and 1/(2w) are stored)")


def _state_space(A, B, C):
    """Mode 0 becomes a discrete state-space plant (scheduled on the output)."""
    return both(set_("modes[0].plant", {"state_space": {"A": A, "B": B, "C": C,
                                                        "discrete": True}}),
                drop("modes[0].observer"), set_("simulation", {"schedule_source": "output"}))


NUMERIC = [
    pytest.param(set_("modes[0].weights.R", 1e308),  # was 3 lines: a warning, LinAlgError
                 f"modes[0].weights.R: 1e+308 {WEIGHT_RANGE}", id="R-1e308"),
    pytest.param(both(set_("modes[0].weights.Q", 5e-324), set_("modes[0].weights.P", 5e-324)),
                 f"modes[0].weights.Q: 5e-324 {WEIGHT_RANGE}", id="Q-P-5e-324"),
    pytest.param(set_("modes[0].weights.Q", 1e308), f"modes[0].weights.Q: 1e+308 "
                 f"{WEIGHT_RANGE}", id="Q-1e308"),
    pytest.param(_state_space([[0.5]], [[1e160]], [[1.0]]),  # weights in range, E overflows
                 "modes[0].weights: the QP Hessian E = 2(Psi + Gamma' Omega Gamma) overflows "
                 "double: the weights and the plant's gains are too large together",
                 id="hessian-overflow"),
    pytest.param(both(_state_space([[10.0]], [[1.0]], [[1.0]]), set_("horizon", 400)),
                 "modes[0].plant: its predictions overflow double over the horizon (N = 400): "
                 "the plant grows too fast for this horizon", id="prediction-overflow"),
]


@pytest.mark.filterwarnings("error::RuntimeWarning")  # a warning would be a second line
@pytest.mark.parametrize("mutate, message", NUMERIC)
def test_every_numeric_failure_names_its_key(tmp_path, capsys, mutate, message):
    err = _generate(tmp_path, capsys, mutate)
    assert err.startswith(f"rollmpc: error: {message}") and err.count("\n") == 1, err


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_numerically_singular_hessian_says_why(tmp_path, capsys):
    """Was "not positive definite (min eigenvalue 20)" for Q = 1e308: a positive minimum.
    Now the message gives both ends of the spectrum and the rule (round-off decides the
    sign of the minimum, so its value is not asserted)."""
    err = _generate(tmp_path, capsys, set_("modes[0].weights.P", 1e30))
    assert err.startswith("rollmpc: error: modes[0].weights: the QP Hessian E = 2(Psi + "
                          "Gamma' Omega Gamma) is not positive definite (min eigenvalue ")
    assert err.endswith(", max 1.78e+28: the min must exceed 1e-12 of the max)\n")


# --------------------------------------------------------------------------- 5. precision
FLOAT_RANGE = "(nonzero magnitudes from 1.18e-38 to 3.4e+38)"
FLOAT = set_("precision", "float")
REPRESENTABLE = [
    pytest.param(both(FLOAT, set_(f"solver.{name}", 1e-50)), f"solver.{name}: 1e-50 is not "
                 f"representable in float precision: it would be 0 {FLOAT_RANGE}", id=name)
    for name in ("delta", "feasibility_tol", "sigma", "omega", "dependence_tol")
] + [
    pytest.param(both(FLOAT, set_("solver.delta", 1e-40)), "solver.delta: 1e-40 is not "
                 f"representable in float precision: it would be the subnormal 1e-40 "
                 f"{FLOAT_RANGE}", id="delta-subnormal"),
    pytest.param(both(FLOAT, set_("modes[1].bounds.u_max", 1e-45)), "modes[1].bounds.u_max: "
                 "1e-45 is not representable in float precision: it would be the subnormal "
                 f"1.4e-45 {FLOAT_RANGE}", id="u_max-subnormal"),
    pytest.param(both(FLOAT, set_("sample_time", 1e-50)), "sample_time: 1e-50 is not "
                 f"representable in float precision: it would be 0 {FLOAT_RANGE}",
                 id="sample_time"),
    pytest.param(set_("solver.delta", 1e-310), "solver.delta: 1e-310 is not representable in "
                 "double precision: it would be the subnormal 1e-310 (nonzero magnitudes from "
                 "2.23e-308 to 1.8e+308)", id="delta-subnormal-double"),
]


@pytest.mark.parametrize("mutate, message", REPRESENTABLE)
def test_a_constant_the_c_cannot_represent_is_refused(tmp_path, capsys, mutate, message):
    assert _generate(tmp_path, capsys, mutate) == f"rollmpc: error: {message}\n"


# --------------------------------------------------------------------------- 6. sizes
def _no_output_bounds(d):
    for mode in d["modes"]:
        del mode["bounds"]["y_min"], mode["bounds"]["y_max"]


def test_a_long_horizon_is_refused_before_the_maths(tmp_path):
    config = _write(tmp_path, both(set_("horizon", 10_000), _no_output_bounds))
    err, seconds = _generate_bounded(tmp_path, config)  # was still condensing after 300 s
    assert err == ("rollmpc: error: horizon: too long: condensing modes[0] would need "
                   "2,400,000,000 bytes of dense N x N matrices; at most 536,870,912 "
                   "supported\n")
    assert seconds < 60


SIZES = [
    pytest.param(both(set_("horizon", 30_000), set_("control_horizon", 1), _no_output_bounds),
                 "horizon: too long: condensing modes[0] would need 21,600,000,000 bytes of "
                 "dense N x N matrices; at most 536,870,912 supported", id="condensing"),
    pytest.param(both(set_("horizon", 32_767), set_("control_horizon", 1), _no_output_bounds),
                 "horizon: too long: modes[0] would have 32768 row quantities (n + N ny, plus "
                 "n with Δu bounds, plus the signals'); at most 32767 supported", id="row-quantities"),
    pytest.param(both(set_("horizon", 10**9), set_("control_horizon", 10**9 - 1)),
                 "horizon: too long: 1000000000 stages need more than the 32767 QP rows and "
                 "row quantities the C can index", id="horizon-1e9"),
    pytest.param(both(set_("modes[0].plant.transfer_function", {
        "num": [1.0], "den": [1.0] + [0.0] * 254 + [1.0]}),  # order 255, + integrator
        set_("modes[0].observer", {"disturbance": "input"})),  # + 1 disturbance state
        "modes[0].plant: its prediction model would have up to 257 states; at most 256 "
        "supported", id="states"),
]


def test_stored_data_beyond_the_limit_is_refused(tmp_path, capsys):
    err = _generate(tmp_path, capsys, both(set_("horizon", 1000), _no_output_bounds))
    assert err == ("rollmpc: error: horizon: too long: the stored data would take 32,332,632 "
                   "bytes (modes[0]: n = 1000 variables, m = 2000 rows); at most 16,777,216 "
                   "supported\n")


@pytest.mark.parametrize("mutate, message", SIZES)
def test_a_controller_beyond_the_size_limits_is_refused(tmp_path, mutate, message):
    err, seconds = _generate_bounded(tmp_path, _write(tmp_path, mutate))
    assert err == f"rollmpc: error: {message}\n"
    assert seconds < 60


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_the_predicted_sizes_are_those_of_the_maths(path):
    """Every example: n, m and the working set exactly, nx exactly or (transfer-function
    matrices, before their minimal realisation) from above; the stored bytes are those of
    the context's arrays whenever nx is exact."""
    cfg = load(path, "float")
    model, ctx = load_model_from_config(cfg)
    predicted = tuple(mode_sizes(cfg, m) for m in cfg.modes)
    for s, mm, mode in zip(predicted, model.modes, cfg.modes):
        d = mm.data
        assert (s.N, s.nu, s.ny, s.n, s.m, s.m_box, s.nt, s.w_cap, s.has_output_rows,
                s.ny_pred) == (d.N, d.nu, d.ny, d.n, d.m, d.m_box, d.nt, d.w_cap,
                               d.has_output_rows, d.ny_pred)
        assert s.nx == d.nx if mode.plant.tf_matrix is None else s.nx >= d.nx
    _, arrays = declared_for(features_of(cfg))
    actual = sum(np.asarray(entry[a.name]).size * (4 if a.ctype == REAL else
                                                   C_TYPE_BYTES[a.ctype])
                 for entry in ctx["modes"] for a in arrays if a.name in entry["defined"])
    if all(s.nx == mm.data.nx for s, mm in zip(predicted, model.modes)):
        assert stored_bytes(cfg, predicted) == actual
    else:
        assert stored_bytes(cfg, predicted) > actual


def test_the_predicted_struct_size_is_that_of_the_c(uav):
    """P_ctrl's arrays: at most its sizeof, short only by its scalars and padding."""
    cfg = uav.model.config
    predicted = struct_bytes(cfg, tuple(mode_sizes(cfg, m) for m in cfg.modes))
    assert predicted <= uav.c._fn["ctrl_size"]() <= predicted + 128
