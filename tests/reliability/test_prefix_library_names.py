"""A prefix whose generated identifiers are the C library's is refused (one line naming
``prefix``, exit 2, nothing written): ``aio`` defined aio_init, glibc's, and 15 of the 24
such prefixes the audit found did not compile where the library's header is visible."""
from __future__ import annotations

import re

import pytest
import yaml

from conftest import ROOT, UAV, edited_config
from rollmpc_codegen.cli.main import main
from rollmpc_codegen.codegen.c_names import c_identifiers, library_names
from rollmpc_codegen.config import ConfigError, load, parse
from rollmpc_codegen.config.schema import PREFIX_PATTERN

AUDIT = ("aio", "cnd", "mtx", "sem", "pthread_mutex", "pthread_cond", "inotify",
         "posix_spawnattr")


def _with_prefix(tmp_path, prefix):
    def edit(data):
        data["prefix"] = prefix
    return edited_config(tmp_path, UAV, f"p_{prefix}", edit)


@pytest.mark.parametrize("prefix", AUDIT + ("shm", "atomic", "pthread_rwlock"))
def test_prefix_colliding_with_the_library_is_refused(tmp_path, capsys, prefix):
    out = tmp_path / "out"
    rc = main(["generate", str(_with_prefix(tmp_path, prefix)), "-o", str(out)])
    err = capsys.readouterr().err.splitlines()
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith("rollmpc: error: prefix: ") and "library" in err[0], err
    assert not out.exists()


def test_every_prefix_that_would_define_a_library_name_is_refused():
    """Independent of the template scan the check uses: each library name that is a
    prefix plus an identifier tail of a rendered tree (generated/uav_roll: rollmpc_init,
    ROLLMPC_R, ...) gives a prefix, and every such prefix is refused."""
    tree = ROOT / "generated" / "uav_roll"
    seen = set()
    for f in tree.glob("*.[ch]"):
        seen |= c_identifiers(f.read_text())
    tails = {n[len("rollmpc_"):] for n in seen if n.startswith("rollmpc_")}
    upper = {n[len("ROLLMPC_"):] for n in seen if n.startswith("ROLLMPC_")}
    candidates = set()
    for name in library_names():
        for i in (m.start() for m in re.finditer("_", name)):
            head, tail = name[:i], name[i + 1:]
            if tail in tails and re.fullmatch(PREFIX_PATTERN, head):
                candidates.add(head)
            if tail in upper and re.fullmatch(PREFIX_PATTERN, head.lower()) and head.isupper():
                candidates.add(head.lower())
    assert set(AUDIT) <= candidates and len(candidates) >= 20, sorted(candidates)
    accepted = []
    for prefix in sorted(candidates):
        try:
            load_prefix(prefix)
        except ConfigError as exc:
            assert exc.key == "prefix", exc
        else:
            accepted.append(prefix)
    assert not accepted


def load_prefix(prefix):
    data = yaml.safe_load(UAV.read_text())
    data["prefix"] = prefix
    return parse(data)


@pytest.mark.parametrize("example", sorted(p.stem for p in (ROOT / "examples").glob("*.yaml")))
def test_the_examples_prefixes_pass(example):
    load(ROOT / "examples" / f"{example}.yaml")
