"""Every stored mode array is declared once (rollmpc_codegen/qp/arrays.py): the C struct,
the array definitions and the designated initializers are rendered from the declaration."""
from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

from compile_flags import STRICT, compile_objects
from conftest import ROOT, edited_config, short_uav_config
from rollmpc_codegen.pipeline import generate
from rollmpc_codegen.qp.arrays import REAL, STORED_ARRAYS, declared_for

TREES = sorted(p.name for p in (ROOT / "generated").iterdir() if p.is_dir())


def _tree(path):
    ctx = json.loads(next(path.glob("*_context.json")).read_text())
    prefix = ctx["prefix"]
    return (ctx, prefix, (path / f"{prefix}_internal.h").read_text(),
            (path / f"{prefix}_data.c").read_text())


def _check_tree(path):
    ctx, prefix, header, data = _tree(path)
    sizes, arrays = declared_for(ctx)
    struct = re.search(r"typedef struct \{(.*?)\} " + prefix + "_mode_data;", header, re.S)
    members = re.findall(r"^    (?:int |const (\w+) \*)(\w+);", struct.group(1), re.M)
    assert members == [("", s.name) for s in sizes] + \
        [(f"{prefix}_real" if a.ctype == REAL else a.ctype, a.name) for a in arrays]
    definitions = re.findall(r"static const \w+ " + prefix + r"_mode(\d+)_(\w+)\[(\d+)\]", data)
    initializers = re.split(r"/\* mode \d+: \w+ \*/", data.split("_modes[")[1])[1:]
    assert len(initializers) == len(ctx["modes"])
    for j, (md, init) in enumerate(zip(ctx["modes"], initializers)):
        defined = [a.name for a in arrays if a.name in md["defined"]]
        assert [(name, int(size)) for k, name, size in definitions if int(k) == j] == \
            [(name, max(1, np.size(md[name]))) for name in defined]
        fields = re.findall(r"\.(\w+) = (\w+),", init)
        assert fields == [(s.name, str(md[s.name])) for s in sizes] + \
            [(a.name, f"{prefix}_mode{j}_{a.name}" if a.name in defined else "0")
             for a in arrays]


@pytest.mark.parametrize("tree", TREES)
def test_committed_trees_render_the_declaration(tree):
    _check_tree(ROOT / "generated" / tree)


# designs of features no example uses (general constraints), rendered by the test
FEATURE_DESIGNS = ("tests/data/constraints/quad_rates.yaml",
                   "tests/data/constraints/servo_terminal.yaml")


def test_features_add_their_members(tmp_path):
    # each feature of the declaration appears in some committed tree or feature design,
    # with its arrays (a feature's flag is absent from a context that lacks it)
    from rollmpc_codegen.pipeline import generate

    dirs = [ROOT / "generated" / t for t in TREES]
    for j, design in enumerate(FEATURE_DESIGNS):
        generate(ROOT / design, tmp_path / f"d{j}")
        dirs.append(tmp_path / f"d{j}")
    features = {a.feature for a in STORED_ARRAYS if a.feature}
    for feature in features:
        trees = [d for d in dirs if _tree(d)[0].get(feature)]
        assert trees, feature
        header = _tree(trees[0])[2]
        for a in STORED_ARRAYS:
            if a.feature == feature:
                assert f"*{a.name};" in header


def test_mode_without_output_rows_stores_a_null_pointer(tmp_path):
    def drop_inner_output_bounds(data):
        for key in ("y_min", "y_max"):
            data["modes"][0]["bounds"].pop(key)

    config = edited_config(tmp_path, short_uav_config(tmp_path, horizon=8), "no_out",
                           drop_inner_output_bounds)
    out = tmp_path / "gen"
    model, ctx = generate(config, out, "float")
    assert [m.data.has_output_rows for m in model.modes] == [False, True]
    assert [("GEinvGt_p" in m["defined"]) for m in ctx["modes"]] == [False, True]
    _check_tree(out)
    data = (out / "rollmpc_data.c").read_text()
    assert ".GEinvGt_p = 0," in data and ".GEinvGt_p = rollmpc_mode1_GEinvGt_p," in data
    proc = compile_objects("gcc", out, ["-O1", *STRICT], tmp_path / "obj")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr

    md = model.modes[1].data
    with pytest.raises(ValueError, match="Kx has shape"):
        dataclasses.replace(md, Kx=md.Kx[:, 1:])
    with pytest.raises(ValueError, match="GEinvGt_p has shape"):
        dataclasses.replace(md, GEinvGt_p=md.GEinvGt_p[1:])


@pytest.mark.parametrize("tree", TREES)
def test_scan_rows_list_each_kind_in_row_order(tree):
    """violated_kind() reads one kind's rows through scan_rows and appends them in the
    order it meets them, which must be the row order a scan of every row had: the m_box
    rows that are not output rows, ascending, then the output rows, ascending."""
    ctx = _tree(ROOT / "generated" / tree)[0]
    for md in ctx["modes"]:
        rows, m, m_box = np.asarray(md["scan_rows"]), md["m"], md["m_box"]
        q = np.asarray(md["row_q"])[rows]
        output = (q >= md["n"]) & (q < md["n"] + md["nyq"])
        assert sorted(rows.tolist()) == list(range(m))
        assert not output[:m_box].any() and output[m_box:].all()
        assert (np.diff(rows[:m_box]) > 0).all() and (np.diff(rows[m_box:]) > 0).all()
