"""Status codes are declared once (rollmpc_codegen/status.py): the C enum, the C message
table, the reference's names and docs/c-api.md's table all say the same."""
from __future__ import annotations

import re

import pytest

from conftest import ROOT
from rollmpc_codegen.sim.metrics import status_counts
from rollmpc_codegen.status import STATUS_NAMES, UNKNOWN_MESSAGE, Status, context_statuses

# (committed tree, file prefix, built with runtime_bounds)
TREES = [("uav_roll", "rollmpc", False), ("uav_roll_f32", "rollmpc", False),
         ("chain_runtime_bounds", "chain_rb", True), ("chain_runtime_bounds_f32", "chain_rb", True)]


def _expected(runtime_bounds: bool) -> list[Status]:
    return [s for s in Status if runtime_bounds or not s.runtime_bounds_only]


@pytest.mark.parametrize("tree,prefix,runtime_bounds", TREES)
def test_c_enum_is_the_declaration(tree, prefix, runtime_bounds):
    header = (ROOT / "generated" / tree / f"{prefix}.h").read_text()
    enum = re.search(r"typedef enum \{(.*?)\} " + prefix + "_status;", header, re.S).group(1)
    codes = re.findall(r"/\*\* (.*?) \*/\n    " + prefix.upper() + r"_(\w+) = (\d+)", enum, re.S)
    assert [(name, int(code)) for _, name, code in codes] == \
        [(s.name, int(s)) for s in _expected(runtime_bounds)]
    docs = [doc.replace("\n     *  ", " ") for doc, _, _ in codes]
    assert docs == [s["doc"] for s in context_statuses(prefix, runtime_bounds)]
    assert all(s.meaning.replace("P_", f"{prefix}_")[1:] in doc
               for s, doc in zip(_expected(runtime_bounds), docs))


@pytest.mark.parametrize("tree,prefix,runtime_bounds", TREES)
def test_c_message_table_is_the_declaration(tree, prefix, runtime_bounds):
    source = (ROOT / "generated" / tree / f"{prefix}_controller.c").read_text()
    body = re.search(r"_status_message\(int status\)\n\{(.*?)\n\}", source, re.S).group(1)
    table = re.findall(prefix.upper() + r'_(\w+): return "(.*?)";', body)
    assert table == [(s.name, s.message) for s in _expected(runtime_bounds)]
    assert re.search(r'default: return "(.*?)";', body).group(1) == UNKNOWN_MESSAGE


def test_compiled_messages_are_the_declaration(uav_double):
    for s in STATUS_NAMES:
        assert uav_double.c.status_message(s) == s.message
    # the runtime_bounds codes are unknown to a build without run-time bounds
    assert uav_double.c.status_message(Status.BAD_BOUNDS) == UNKNOWN_MESSAGE


def test_c_api_table_is_the_declaration():
    reference = (ROOT / "docs" / "c-api.md").read_text()
    rows = re.findall(r"^\| (\d+) \| `(\w+)` \| (.*) \| (.*) \|$", reference, re.M)
    assert rows == [(str(int(s)), s.name, s.meaning, s.command) for s in Status]


def test_every_code_a_build_returns_is_counted_under_its_own_name():
    """The summaries of simulate, bench and report count statuses by name: each code a
    build without run-time bounds returns has a name of its own there (MEASUREMENT_CLIPPED
    and TIME_LIMIT included), and a code no build returns keeps its number."""
    returned = [int(s) for s in Status if not s.runtime_bounds_only]
    counts = status_counts(returned + [int(Status.OPTIMAL), 99])
    assert len(counts) == len(returned) + 1 and sum(counts.values()) == len(returned) + 2
    assert counts["optimal"] == 2 and counts["99"] == 1
    assert counts["time_limit"] == counts["measurement_clipped"] == 1


def test_messages_are_distinct_c_string_literals():
    """A user tells the statuses apart by P_status_message(); each text is pasted into a C
    string literal as it is."""
    messages = [s.message for s in Status] + [UNKNOWN_MESSAGE]
    assert len(set(messages)) == len(messages)
    assert not any('"' in m or "\\" in m for m in messages)
