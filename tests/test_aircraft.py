"""Aircraft files for real records: started from a record (aircraft init), a shipped example, the keys documented."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_refused_in_one_line

from fdml.aircraft import CONSTANT_KEYS, KEY_MEANINGS, REQUIRED_KEYS, Aircraft, aircraft_template, load_aircraft
from fdml.cli import main
from fdml.errors import AircraftError
from fdml.record import Record

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "twinotter.json"
TO17 = "twin_otter/totter_lon_020213f1_017.mat"
#: Exact conversions to SI (NIST SP 811): foot, slug.
FT, SLUG = 0.3048, 14.593902937206364
TAIL = {"S_t": 9.29, "c_t": 1.47, "l_t": 7.6}


def _run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_template_from_a_sidpac_record_takes_its_geometry_mass_and_condition(tmp_path, capsys):
    from scipy.io import loadmat

    from fdml.io import data_path

    path = data_path(TO17)
    mat = loadmat(path)  # the file itself, converted here: independent of fdml's reader
    fd = mat["fdata"]
    expected = {
        "S_w": float(mat["sarea"].ravel()[0]) * FT**2,
        "c_w": float(mat["cbar"].ravel()[0]) * FT,
        "b": float(mat["bspan"].ravel()[0]) * FT,
        "mass": float(np.mean(fd[:, 47])) * SLUG,
        "Iy": float(np.mean(fd[:, 49])) * SLUG * FT**2,
        "rho": float(np.mean(fd[:, 28])) * SLUG / FT**3,
        "U": float(np.mean(fd[:, 1])) * FT,
    }
    out_file = tmp_path / "to.json"
    code, out, _ = _run(capsys, "aircraft", "init", path, "-o", out_file, "--name", "twinotter")
    assert code == 0
    d = json.loads(out_file.read_text())
    for k, v in expected.items():
        assert d[k] == pytest.approx(v, rel=1e-9), k
        assert "totter_lon_020213f1_017" in d["sources"][k]
    assert [k for k in REQUIRED_KEYS if d[k] is None] == ["S_t", "c_t", "l_t"]
    assert "left to fill" in out and all(k in out.split("left to fill")[1] for k in TAIL)
    # the file as written is refused, naming what is left to fill; filled in, it is an aircraft
    code, _, err = _run(capsys, "aircraft", "show", out_file)
    assert_refused_in_one_line(code, err, ["not filled in", "S_t", "c_t", "l_t"])
    out_file.write_text(json.dumps({**d, **TAIL}))
    ac = load_aircraft(out_file)
    assert ac.b == pytest.approx(expected["b"]) and ac.S_w == pytest.approx(expected["S_w"])


def test_template_of_a_record_without_geometry_lists_what_is_missing():
    t = np.arange(0.0, 2.0, 0.02)
    de = 0.01 * np.sin(3 * t)
    sig = {"de": de, "alpha": de, "q": de, "az": de}
    rec = Record(t, sig, name="bare", meta={"mass": 1200.0, "U": 50.0, "window_means": ["U"], "format": "csv"})
    tpl = aircraft_template(rec)
    d = tpl.as_file()
    assert d["name"] == "bare" and d["mass"] == 1200.0 and d["U"] == 50.0
    assert set(tpl.missing) == {"S_w", "c_w", "S_t", "c_t", "l_t", "Iy", "rho"}
    assert "airspeed" in d["sources"]["U"] and "b" not in d
    with pytest.raises(AircraftError, match="not filled in.*S_w.*Iy"):
        Aircraft.from_dict(d)
    d["sensors"] = {}  # another key added before writing stays out of the template's own values
    assert "sensors" not in tpl.as_file()


def test_shipped_example_is_an_aircraft_with_a_source_for_every_value():
    d = json.loads(EXAMPLE.read_text())
    ac = load_aircraft(EXAMPLE)
    given = [k for k in (*REQUIRED_KEYS[1:], "b", "lag_constants") if k in d]
    assert all(d["sources"].get(k) for k in given), [k for k in given if not d["sources"].get(k)]
    assert set(ac.assumed) >= set(TAIL) and ac.lag_status == "jones"
    assert ac.b == pytest.approx(19.81)


def test_shipped_example_agrees_with_its_record():
    from fdml.io import data_path, load_record

    ex = json.loads(EXAMPLE.read_text())
    d = aircraft_template(load_record(data_path(TO17))).as_file()
    for k in ("S_w", "c_w", "b", "mass", "Iy", "U", "rho"):
        assert ex[k] == pytest.approx(d[k], rel=5e-4), k  # the example rounds to 4-5 digits


def test_docs_list_every_key_and_cite_the_shipped_example():
    models = (ROOT / "docs" / "user" / "models.md").read_text()
    table = models.split("(aircraft-files)=")[1].split("\n## ")[1]
    documented = set(re.findall(r"^\| `([^|]*)", table, flags=re.M))
    keys = {k.strip("` ") for cell in documented for k in cell.split(",")}
    assert keys >= set(KEY_MEANINGS) | set(CONSTANT_KEYS), sorted(set(KEY_MEANINGS) | set(CONSTANT_KEYS) - keys)
    for doc in (ROOT / "docs").rglob("*.md"):
        for ref in re.findall(r"[\w/.-]*twinotter\.json", doc.read_text()):
            assert (ROOT / ref).is_file(), f"{doc.name} cites {ref}, which is not shipped"
