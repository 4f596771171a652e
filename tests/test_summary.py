"""Summaries: the same numbers in text, Markdown, HTML, LaTeX and a DataFrame; flags; comparisons."""

import dataclasses
import math
import pickle
import re
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import fdml
from fdml.compare import compare_steady_unsteady
from fdml.record import Record, add_noise
from fdml.simulate import simulate_maneuver
from fdml.summary import Summary

pytestmark = pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")


@pytest.fixture(scope="module")
def rec():
    r = simulate_maneuver(fdml.make_model("unsteady", "navion"), "3211", duration=10.0, dt=0.02)
    r = add_noise(r, 0.02, np.random.default_rng(11), relative=True)
    return Record(r.t, r.signals, name="nav_3211", meta=r.meta, check_units=False)


@pytest.fixture(scope="module")
def res(rec):
    return fdml.fit(rec, fdml.make_model("derivatives", "navion"), band=(0.2, 8, 0.2))


@pytest.fixture(scope="module")
def cmp(rec):
    return compare_steady_unsteady(rec, "navion", band=(0.2, 8, 0.2))


def _expected(res):
    """name -> (value, stderr) of every estimated and derived quantity."""
    out = {n: (v, s) for n, v, s in zip(res.names, res.values, res.stderr)}
    out.update(res.derived)
    return out


def _check_rows(rows, expected, seen_min):
    """rows: {name: [value text, stderr text, ...]}; values to 6, standard errors to 4 digits."""
    hits = 0
    for name, (v, s) in expected.items():
        if name not in rows:
            continue
        hits += 1
        assert float(rows[name][0]) == pytest.approx(v, rel=5e-6, abs=1e-300)
        assert float(rows[name][1]) == pytest.approx(s, rel=5e-4)
    assert hits >= seen_min


# --- text ---------------------------------------------------------------------------------------


def test_summary_is_the_text_table(res):
    s = res.summary()
    assert isinstance(s, Summary) and isinstance(s, str)
    assert str(s) == s.as_text() and repr(s) == s.as_text()
    assert str(res) == s
    for key in (
        "model:",
        "records: nav_3211",
        "band: 0.2-8 rad/s",
        "boundary terms: estimated",
        "biases: output biases alpha,q,az",
        "standard errors: white",
        "converged after",
        "J = det R",
    ):
        assert key in s, key
    for n in res.names + tuple(res.derived):
        assert re.search(rf"^{re.escape(n)}\s", s, re.M), n
    assert "Cz_adot" in s and "fixed" in s  # fixed parameters listed and flagged
    assert pickle.loads(pickle.dumps(s)) == s


def test_text_numbers_parse_back(res):
    rows = {}
    for line in res.summary().splitlines():
        parts = line.split()
        if len(parts) >= 3 and (parts[0] in res.names or parts[0] in res.derived):
            rows[parts[0]] = parts[1:]
    _check_rows(rows, _expected(res), len(res.names) + len(res.derived))


def test_flags_fixed_at_bound_not_identifiable(res):
    pytest.importorskip("pandas")  # the optional extra fdml[pandas]
    cov = np.array(res.cov)
    i = res.names.index("Cm_a")
    cov[i, i] = math.inf  # its standard error, derived from cov, is infinite
    bad = dataclasses.replace(res, cov=cov, at_bound=("Cz_q",))
    s = bad.summary()
    assert "at bound" in s and "not identifiable" in s
    f = bad.to_frame()
    assert f.loc["Cz_q", "flags"] == "at bound"
    assert f.loc["Cm_a", "flags"] == "not identifiable" and math.isinf(f.loc["Cm_a", "rel_err_pct"])
    assert f.loc["Cz_adot", "flags"] == "fixed" and math.isnan(f.loc["Cz_adot", "stderr"])
    assert re.search(r"^Cm_a\s+\S+\s+inf\s+inf\s+not identifiable", s, re.M)


# --- Markdown, HTML, LaTeX ------------------------------------------------------------------


def _md_rows(md):
    rows = {}
    for line in md.splitlines():
        if line.startswith("| ") and not line.startswith("| parameter") and not line.startswith("| derived"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            rows[cells[0]] = cells[1:]
    return rows


def test_markdown(res):
    md = res.summary().as_markdown()
    assert md.startswith("### fdml fit: derivatives model")
    assert "**Estimates**" in md and "**Derived set (delta method)**" in md
    assert "| parameter | value | std err | rel err % | flags | unit |" in md
    # every table row has as many cells as the header
    for block in md.split("\n\n"):
        lines = [l for l in block.splitlines() if l.startswith("|")]
        if lines:
            assert len({l.count("|") for l in lines}) == 1
    _check_rows(_md_rows(md), _expected(res), len(res.names) + len(res.derived))


def test_html_is_well_formed_and_holds_the_numbers(res):
    h = res.summary().as_html()
    root = ET.fromstring(h)  # raises on unbalanced tags or bare ampersands
    assert root.tag == "div"
    assert res._repr_html_() == h and res.summary()._repr_html_() == h
    rows = {}
    for table in root.iter("table"):
        if "fdml-table" not in table.get("class", ""):
            continue
        for tr in table.find("tbody"):
            cells = ["".join(td.itertext()) for td in tr]
            rows[cells[0]] = cells[1:]
    _check_rows(rows, _expected(res), len(res.names) + len(res.derived))
    caps = [c.text for c in root.iter("caption")]
    assert caps[:2] == ["Estimates", "Derived set (delta method)"]


def test_latex_tabular(res):
    tex = res.summary().as_latex()
    assert tex.count(r"\begin{tabular}") == tex.count(r"\end{tabular}") >= 3
    assert tex.count(r"\begin{center}") == tex.count(r"\end{center}") == 1
    assert tex.count("{") == tex.count("}")
    assert "Cz\\_a" in tex and "bias\\_alpha" in tex and "1/s\\^{}2" in tex
    rows = {}
    for line in tex.splitlines():
        if line.endswith(r"\\") and "&" in line:
            cells = [c.strip() for c in line[:-2].split("&")]
            rows[cells[0].replace("\\_", "_")] = cells[1:]
    _check_rows(rows, _expected(res), len(res.names) + len(res.derived))
    # every row of a tabular has as many cells as its column spec
    for spec, body in re.findall(r"\\begin\{tabular\}\{(\w+)\}(.*?)\\end\{tabular\}", tex, re.S):
        for line in body.splitlines():
            if line.endswith(r"\\") and not line.startswith(r"\hline"):
                assert line.count("&") == len(spec) - 1
    assert res.summary()._repr_latex_() == tex


# --- DataFrame -------------------------------------------------------------------------------


def test_to_frame_holds_the_raw_numbers(res):
    pytest.importorskip("pandas")  # the optional extra fdml[pandas]
    f = res.to_frame()
    assert list(f.columns) == ["value", "stderr", "rel_err_pct", "flags", "unit"]
    assert f.index.name == "parameter"
    np.testing.assert_array_equal(f.loc[list(res.names), "value"].to_numpy(), res.values)
    np.testing.assert_array_equal(f.loc[list(res.names), "stderr"].to_numpy(), res.stderr)
    assert f.loc["Cm_a", "unit"] == "1/rad"
    assert f.attrs["header"]["outputs"] == "alpha, q, az"
    d = res.summary().to_frame("derived")
    for k, (v, s) in res.derived.items():
        assert d.loc[k, "value"] == v and d.loc[k, "stderr"] == s
    assert d.loc["M_a", "unit"] == "1/s^2"


def test_to_frame_without_pandas_names_the_extra(res, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r"fdml\[pandas\]"):
        res.summary().to_frame()


def test_unknown_table(res):
    pytest.importorskip("pandas")  # the optional extra fdml[pandas]
    with pytest.raises(KeyError, match="parameters"):
        res.summary().to_frame("nope")


# --- steady versus unsteady ------------------------------------------------------------------


def test_comparison_table_formats(cmp):
    pytest.importorskip("pandas")  # the optional extra fdml[pandas]
    ref = {"Cz_a": (-4.99, -4.90), "Cm_q": (-12.77, -14.68)}
    t = cmp.table(reference=ref)
    assert isinstance(t, str) and "shift/sigma" in t and "paper unst." in t
    f = t.to_frame()
    assert list(f.index) == ["Cz_a", "Cz_q", "Cz_de", "Cm_a", "Cm_q", "Cm_de"]
    for n, (v, s) in cmp.unsteady_set.items():
        assert f.loc[n, "unsteady"] == v and f.loc[n, "unsteady_stderr"] == s
    for n, (v, s) in cmp.steady_set.items():
        assert f.loc[n, "steady"] == v
        z = (v - cmp.unsteady_set[n][0]) / math.hypot(s, cmp.unsteady_set[n][1])
        assert f.loc[n, "shift_sigma"] == pytest.approx(z)
    assert f.loc["Cz_a", "reference_unsteady"] == -4.99 and math.isnan(f.loc["Cz_q", "reference_steady"])
    md = t.as_markdown()
    row = next(l for l in md.splitlines() if l.startswith("| Cm_q |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[1]) == pytest.approx(cmp.unsteady_set["Cm_q"][0], rel=5e-4)
    assert float(cells[3]) == pytest.approx(cmp.steady_set["Cm_q"][0], rel=5e-4)
    assert float(cells[-1]) == -14.68
    ET.fromstring(t.as_html())
    assert cmp._repr_html_() == cmp.table().as_html()
    tex = t.as_latex()
    assert tex.count(r"\begin{tabular}") == tex.count(r"\end{tabular}") == 2
    assert "shift/sigma" in tex


def test_digits(res):
    s4 = res.summary(digits=4)
    i = res.names.index("Cz_a")
    assert f"{res.values[i]:.4g}" in s4.split("Cz_a", 1)[1].splitlines()[0]
