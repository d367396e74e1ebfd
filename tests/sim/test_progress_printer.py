"""The progress bar of long runs: redrawn in place on a terminal, whole lines in a log."""
from __future__ import annotations

import io

from rollmpc_codegen.sim.simulate import progress_printer


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def run(stream, total: int = 100) -> str:
    report = progress_printer(total, "simulate", stream)
    for k in range(total):
        report(k)
    return stream.getvalue()


def test_a_log_gets_a_few_whole_lines_without_carriage_returns():
    text = run(io.StringIO())
    lines = text.splitlines()
    assert "\r" not in text and text.endswith("\n")
    assert len(lines) == 5  # 1 %, 26 %, 51 %, 76 %, 100 %
    assert lines[-1] == "simulate [####################] 100.0% (100/100)"


def test_a_terminal_redraws_one_line():
    text = run(Terminal())
    assert text.count("\r") == 21 and text.count("\n") == 1  # every 5 %, then done
    assert text.endswith("simulate [####################] 100.0% (100/100)\n")


def test_an_empty_phase_prints_its_label_once():
    stream = io.StringIO()
    assert progress_printer(0, "building", stream) is None
    assert stream.getvalue() == "building\n"
