"""The command line explains itself (docs/checks.md): ``--version``, a top-level help
that lists all eight commands in plain words (it listed five, and named them after the
paper: "bench: Table 2", "simulate ... on the paper scenario"), and a full ``--help`` per
subcommand: a description, every argument helped, the exit codes."""
from __future__ import annotations

import pytest

from rollmpc_codegen import __version__
from rollmpc_codegen.cli.main import SUBCOMMANDS, main, parser

COMMANDS = ("generate", "simulate", "bench", "report", "certify", "testvectors", "identify",
            "fly")


def subparsers() -> dict:
    return parser()._subparsers._group_actions[0].choices


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out == f"rollmpc {__version__}\n"


def test_the_top_level_help_lists_every_command_without_paper_jargon():
    text = parser().format_help()
    assert all(f"    {name}" in text for name in COMMANDS)
    assert len(SUBCOMMANDS) == len(COMMANDS) == len(subparsers())
    for jargon in ("Table 2", "paper scenario", "Fig. 2"):
        assert jargon not in text
    assert "exit codes: 0 done; 1 a tool failed" in text


@pytest.mark.parametrize("name", COMMANDS)
def test_every_subcommand_has_a_full_help(name):
    sub = subparsers()[name]
    assert len(sub.description) > 80 and sub.epilog.startswith("exit codes: ")
    unhelped = [a.dest for a in sub._actions if not a.help]
    assert unhelped == []
    text = sub.format_help()
    for jargon in ("Table 2:", "paper scenario", "Fig. 2 style"):
        assert jargon not in text


def test_report_documents_its_verdict_exit_code():
    assert "3 a verdict failed" in subparsers()["report"].epilog
    assert "3 a sampled QP stopped" in subparsers()["certify"].epilog
    assert "--check" in subparsers()["report"].format_help()
