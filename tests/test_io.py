"""Loaders for real flight records: units, signs, windows, trim, and every bad-input case.

The real records are read from $FDML_DATA.  With FDML_DATA set, a missing file is
an error naming it (fdml.io.data_path raises); unset, those tests skip naming FDML_DATA.
"""

import math
import shutil

import numpy as np
import pytest
from scipy.io import loadmat, savemat

from fdml.constants import DEG, FT, G0, SLUG
from fdml.errors import RecordError
from fdml.io import (
    data_dir,
    data_path,
    detect_format,
    load_record,
    load_records,
    read_csv_mapped,
    read_dlr_asc,
    read_dlr_mat,
    read_sidpac,
)
from fdml.io.units import normalise_unit, to_si, unit_factor
from fdml.record import Record

TO17 = "twin_otter/totter_lon_020213f1_017.mat"
TO18 = "twin_otter/totter_lon_020213f1_018.mat"
HFB = "hfb320/hfb320_1_10.asc"
ATTAS = "attas/fAttasElv1.mat"


def _slope_corr(x, y):
    return float(np.polyfit(x, y, 1)[0]), float(np.corrcoef(x, y)[0, 1])


# --- the data folder ---------------------------------------------------------------------------
def test_missing_data_file_is_an_error_naming_it(tmp_path, monkeypatch):
    monkeypatch.setenv("FDML_DATA", str(tmp_path))
    with pytest.raises(RecordError) as exc:
        data_path(TO17)
    assert TO17 in str(exc.value) and str(tmp_path) in str(exc.value)


def test_fdml_data_must_be_a_directory(tmp_path, monkeypatch):
    monkeypatch.setenv("FDML_DATA", str(tmp_path / "nowhere"))
    with pytest.raises(RecordError, match="nowhere"):
        data_dir()
    with pytest.raises(RecordError, match="twin_otter"):
        data_path(TO17)


def test_data_dir_is_fdml_data_only(tmp_path, monkeypatch):
    """No search up the tree: without FDML_DATA there is no data folder, even beside a shared/data."""
    (tmp_path / "shared" / "data").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "shared")
    monkeypatch.delenv("FDML_DATA", raising=False)
    with pytest.raises(RecordError, match="FDML_DATA is not set"):
        data_dir()
    monkeypatch.setenv("FDML_DATA", str(tmp_path / "shared" / "data"))
    assert data_dir() == tmp_path / "shared" / "data"


def test_real_record_tests_skip_naming_fdml_data(monkeypatch):
    """tests/conftest.py turns data_path without FDML_DATA into a skip whose reason names it."""
    monkeypatch.delenv("FDML_DATA", raising=False)
    with pytest.raises(pytest.skip.Exception, match="FDML_DATA"):
        data_path(TO17)


# --- Twin Otter (SIDPAC) ----------------------------------------------------------------------
@pytest.mark.parametrize("rel, n", [(TO17, 301), (TO18, 401)])
def test_twin_otter_shapes_units_and_signs(rel, n):
    path = data_path(rel)
    rec = read_sidpac(path)
    raw = loadmat(str(path))["fdata"]
    assert rec.n == n and rec.dt == pytest.approx(0.02, rel=1e-9)
    assert rec.t[0] == 0.0 and rec.duration == pytest.approx((n - 1) * 0.02)
    assert set(rec.signals) == {"de", "alpha", "q", "az", "theta", "V", "qdot", "ax", "h", "qbar"}
    # exact conversions of the README's columns (factors are exact definitions)
    np.testing.assert_allclose(rec["alpha"], raw[:, 3] * DEG, rtol=1e-15)
    np.testing.assert_allclose(rec["q"], raw[:, 5] * DEG, rtol=1e-15)
    np.testing.assert_allclose(rec["de"], raw[:, 13] * DEG, rtol=1e-15)
    np.testing.assert_allclose(rec["az"], raw[:, 12], rtol=1e-15)  # already g, positive down
    np.testing.assert_allclose(rec["V"], raw[:, 1] * FT, rtol=1e-15)
    np.testing.assert_allclose(rec["h"], raw[:, 29] * FT, rtol=1e-15)
    # README: about 240 ft/s and 7,100 ft
    assert rec.meta["U"] == pytest.approx(240 * FT, rel=0.02)
    assert np.mean(rec["h"]) / FT == pytest.approx(7150, abs=60)
    # flight condition and geometry in SI
    assert rec.meta["S_w"] == pytest.approx(422.48 * FT**2, rel=1e-4)
    assert rec.meta["c_w"] == pytest.approx(6.496 * FT, rel=1e-3)
    assert rec.meta["b"] == pytest.approx(64.99 * FT, rel=1e-3)
    assert rec.meta["mass"] == pytest.approx(np.mean(raw[:, 47]) * SLUG, rel=1e-12)
    assert rec.meta["Iy"] == pytest.approx(np.mean(raw[:, 49]) * SLUG * FT**2, rel=1e-12)
    assert rec.meta["rho"] == pytest.approx(np.mean(raw[:, 28]) * SLUG / FT**3, rel=1e-12)
    assert 1.0 < rec.meta["rho"] < 1.06  # 7,100 ft standard atmosphere: 1.03 kg/m^3
    # a_z is the body-z specific force positive down: about -1 g in the leading trim
    assert -1.05 < rec.meta["trim_values"]["az"] < -0.95
    # physical sign checks (nose-up q is d theta/dt; slope below 1 is theta's slow update, see
    # test_quality; a sign error would make it negative)
    s, c = _slope_corr(rec["q"], np.gradient(rec["theta"], rec.dt))
    assert c > 0.95 and 0.8 < s < 1.1
    # a_z = (U/g)(alpha_dot - q) (THEORY Eq. 5) holds with slope near +1 (a flipped a_z gives -1)
    pred = rec.meta["U"] / G0 * (np.gradient(rec["alpha"], rec.dt) - rec["q"])
    s, c = _slope_corr(pred, rec["az"])
    assert c > 0.8 and 0.85 < s < 1.2


def test_twin_otter_original_measurements_differ_by_sidpac_corrections():
    path = data_path(TO18)
    corrected, original = read_sidpac(path), read_sidpac(path, original=True)
    assert original.meta["matrix"] == "fdatao"
    dq = corrected["q"] - original["q"]
    # a pure bias correction: constant to rounding
    assert np.ptp(dq) < 1e-12 and abs(dq[0]) / DEG == pytest.approx(0.0367, abs=1e-4)
    np.testing.assert_array_equal(corrected["de"], original["de"])


def test_twin_otter_window_and_trim():
    path = data_path(TO17)
    full = read_sidpac(path)
    w = read_sidpac(path, t0=1.0, t1=3.0)
    assert w.t[0] == pytest.approx(1.0) and w.t[-1] == pytest.approx(3.0) and w.n == 101
    assert w.meta["window"] == [1.0, 3.0]
    np.testing.assert_array_equal(w["q"], full["q"][50:151])
    assert w.meta["U"] == pytest.approx(np.mean(full["V"][50:151]), rel=1e-12)
    # trim kept by default, removed on request, and reported either way
    assert full["az"][0] < -0.9 and "trim" not in full.meta
    tr = read_sidpac(path, trim="first")
    assert tr["az"][0] == 0.0 and tr.meta["trim"]["az"] == pytest.approx(full["az"][0])
    tm = read_sidpac(path, trim="mean")
    assert tm.meta["trim"]["az"] == pytest.approx(full.meta["trim_values"]["az"], rel=1e-12)


# --- HFB-320 and ATTAS -------------------------------------------------------------------------
def test_hfb320_asc():
    path = data_path(HFB)
    rec = read_dlr_asc(path)
    raw = np.loadtxt(path)
    assert rec.n == 601 and rec.dt == pytest.approx(0.1, rel=1e-6) and rec.duration == pytest.approx(60, rel=1e-6)
    np.testing.assert_allclose(rec["az"], raw[:, 10] / G0, rtol=1e-15)
    np.testing.assert_allclose(rec["alpha"], raw[:, 5], rtol=1e-15)
    np.testing.assert_allclose(rec["de"], raw[:, 1], rtol=1e-15)
    assert rec["az"][0] == pytest.approx(-9.86526 / G0)  # README: about -9.87 m/s^2 in trim
    assert rec.meta["mass"] == 7472.0 and rec.meta["S_w"] == pytest.approx(30.1, abs=0.01)
    assert rec.meta["U"] == pytest.approx(np.mean(raw[:, 4]))
    # density from qbar and V agrees with the book's 0.792 kg/m^3 to 0.5 %
    assert rec.meta["rho_from_data"] == pytest.approx(0.792, rel=5e-3)
    s, c = _slope_corr(rec["q"], np.gradient(rec["theta"], rec.dt))
    assert c > 0.9 and 0.9 < s < 1.1
    w = read_dlr_asc(path, t0=10, t1=30)
    assert w.t[0] == pytest.approx(10, abs=1e-4) and w.n == 201


def test_attas_mat():
    path = data_path(ATTAS)
    rec = read_dlr_mat(path)
    raw = loadmat(str(path))["fAttasElv1"]
    assert rec.n == 626 and rec.dt == pytest.approx(0.04) and rec.duration == pytest.approx(25)
    np.testing.assert_allclose(rec["alpha"], raw[:, 12] * DEG, rtol=1e-15)
    np.testing.assert_allclose(rec["q"], raw[:, 7] * DEG, rtol=1e-15)
    np.testing.assert_allclose(rec["de"], raw[:, 21] * DEG, rtol=1e-15)
    np.testing.assert_allclose(rec["az"], raw[:, 3] / G0, rtol=1e-15)
    assert rec.meta["U"] == pytest.approx(129, abs=1.5)  # README: about 129 m/s
    assert -1.05 < rec.meta["trim_values"]["az"] < -0.95
    assert rec.meta["trim_values"]["h"] / FT == pytest.approx(16000, abs=50)
    s, c = _slope_corr(rec["q"], np.gradient(rec["theta"], rec.dt))
    assert c > 0.99 and 0.9 < s < 1.05
    assert rec.meta["rho"] == pytest.approx(0.727, abs=0.002)


@pytest.mark.parametrize("rel, fmt", [(TO17, "sidpac"), (HFB, "dlr-asc"), (ATTAS, "dlr-mat")])
def test_load_record_detects_format(rel, fmt):
    path = data_path(rel)
    assert detect_format(path)[0] == fmt
    a = load_record(path, t0=2.0, t1=4.0)
    b = load_record(path, format=fmt, t0=2.0, t1=4.0)
    np.testing.assert_array_equal(a["alpha"], b["alpha"])
    assert a.meta["format"] == fmt


# --- CSV with a column map ---------------------------------------------------------------------
def _write_foreign_csv(path, t, de, alpha, q, az, V, sep=","):
    """A CSV in degrees, deg/s, normal load factor n_z (g, positive up) and knots."""
    head = sep.join(["time (s)", "elev_deg", "AOA [deg]", "pitch_rate", "nz", "KTAS"])
    rows = [sep.join(f"{v:.17g}" for v in r) for r in zip(t, de / DEG, alpha / DEG, q / DEG, -az, V / (1852 / 3600))]
    path.write_text(head + "\n" + "\n".join(rows) + "\n")


def _truth(n=200, dt=0.02):
    t = np.arange(n) * dt
    return (
        t,
        0.02 * np.sin(3 * t),
        0.05 + 0.01 * np.sin(2 * t),
        0.03 * np.cos(2 * t),
        -1.0 + 0.1 * np.sin(2 * t),
        60 + 0 * t,
    )


def test_csv_mapped_round_trip(tmp_path):
    t, de, alpha, q, az, V = _truth()
    f = tmp_path / "foreign.csv"
    _write_foreign_csv(f, t, de, alpha, q, az, V)
    rec = read_csv_mapped(
        f,
        columns={"t": "time", "de": "elev_deg", "alpha": "AOA", "q": "pitch_rate", "az": "nz", "V": "KTAS"},
        units={"de": "deg", "q": "deg/sec", "az": "g", "V": "kts"},
        sign={"az": -1},
    )
    for got, want in ((rec["de"], de), (rec["alpha"], alpha), (rec["q"], q), (rec["az"], az), (rec["V"], V)):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-15)
    assert rec.meta["U"] == pytest.approx(60.0)
    assert rec.meta["conversion"]["alpha"]["unit"] == "deg"  # from the header
    assert rec.meta["sign"]["az"] == -1


def test_csv_mapped_semicolon_and_ms(tmp_path):
    t, de, alpha, q, az, V = _truth()
    f = tmp_path / "semi.csv"
    lines = ["ms;de;a;qq;acc"] + [f"{1000 * a};{b};{c};{d};{e * G0}" for a, b, c, d, e in zip(t, de, alpha, q, az)]
    f.write_text("\n".join(lines))
    rec = read_csv_mapped(
        f,
        {"t": "ms", "de": "de", "alpha": "a", "q": "qq", "az": "acc"},
        units={"t": "ms", "de": "rad", "alpha": "rad", "q": "rad/s", "az": "m/s^2"},
    )
    np.testing.assert_allclose(rec.t, t, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(rec["az"], az, rtol=1e-12)


def test_fdml_csv_through_load_record(tmp_path):
    t, de, alpha, q, az, V = _truth()
    f = Record(t, {"de": de, "alpha": alpha, "q": q, "az": az}).to_csv(tmp_path / "own.csv")
    rec = load_record(f, t0=1.0)
    assert rec.meta["format"] == "csv" and rec.t[0] == pytest.approx(1.0)


# --- bad input ---------------------------------------------------------------------------------
def test_corrupt_and_truncated_mat(tmp_path):
    bad = tmp_path / "noise.mat"
    bad.write_bytes(np.random.default_rng(1).bytes(4000))
    with pytest.raises(RecordError, match="noise.mat"):
        read_sidpac(bad)
    src = data_path(TO17).read_bytes()
    cut = tmp_path / "cut.mat"
    cut.write_bytes(src[: len(src) // 2])
    with pytest.raises(RecordError, match="cut.mat"):
        load_record(cut, format="sidpac")
    empty = tmp_path / "empty.mat"
    empty.write_bytes(b"")
    with pytest.raises(RecordError, match="empty"):
        read_sidpac(empty)


def test_mat_without_the_expected_matrix(tmp_path):
    f = tmp_path / "other.mat"
    savemat(str(f), {"something": np.ones((10, 3))})
    with pytest.raises(RecordError, match="no 'fdata'.*something"):
        read_sidpac(f)
    with pytest.raises(RecordError, match="3 columns"):
        read_dlr_mat(f, layout="attas")
    with pytest.raises(RecordError, match="known DLR layout"):
        load_record(f)


def test_sidpac_with_a_foreign_column_order(tmp_path):
    m = loadmat(str(data_path(TO17)))
    lab = m["varlab"].copy()
    lab[3], lab[5] = lab[5], lab[3]  # swap the alpha and q labels
    f = tmp_path / "swapped.mat"
    savemat(str(f), {"fdata": m["fdata"], "varlab": lab, "t": m["t"]})
    with pytest.raises(RecordError, match="column 4 is labelled"):
        read_sidpac(f)


def test_truncated_and_corrupt_asc(tmp_path):
    text = data_path(HFB).read_text()
    cut = tmp_path / "cut.asc"
    cut.write_text(text[: len(text) - 60])  # ends inside the last line
    with pytest.raises(RecordError, match=r"cut.asc: line 601 has \d+ values"):
        read_dlr_asc(cut)
    lines = text.splitlines()
    lines[300] = lines[300].replace("0", "O", 1)
    bad = tmp_path / "bad.asc"
    bad.write_text("\n".join(lines))
    with pytest.raises(RecordError, match="bad.asc: line 301 is not numeric"):
        read_dlr_asc(bad)
    with pytest.raises(RecordError, match="unknown DLR layout"):
        read_dlr_asc(data_path(HFB), layout="b747")


def test_csv_map_errors(tmp_path):
    t, de, alpha, q, az, V = _truth()
    f = tmp_path / "foreign.csv"
    _write_foreign_csv(f, t, de, alpha, q, az, V)
    cols = {"t": "time", "de": "elev_deg", "alpha": "AOA", "q": "pitch_rate", "az": "nz"}
    units = {"de": "deg", "q": "deg/s", "az": "g"}
    with pytest.raises(RecordError, match="foreign.csv: no column 'pitch' \\(mapped to q\\)"):
        read_csv_mapped(f, {**cols, "q": "pitch"}, units)
    with pytest.raises(RecordError, match="unknown unit 'furlong/s'"):
        read_csv_mapped(f, cols, {**units, "q": "furlong/s"})
    with pytest.raises(RecordError, match="mixed units for alpha.*'deg'.*'rad'"):
        read_csv_mapped(f, cols, {**units, "alpha": "rad"})
    with pytest.raises(RecordError, match="unit 'deg' measures angle, but this channel is a specific force"):
        read_csv_mapped(f, cols, {**units, "az": "deg"})
    with pytest.raises(RecordError, match="no unit for de"):
        read_csv_mapped(f, cols, {"q": "deg/s", "az": "g"})
    with pytest.raises(RecordError, match="sign of az must be"):
        read_csv_mapped(f, cols, units, sign={"az": 2})
    with pytest.raises(RecordError, match="lacks az"):
        read_csv_mapped(f, {k: v for k, v in cols.items() if k != "az"}, {"de": "deg", "q": "deg/s"})
    with pytest.raises(RecordError, match="unknown fdml signal"):
        read_csv_mapped(f, {**cols, "beta": "x"}, units)
    # degrees declared as radians are caught by the record's unit check
    with pytest.raises(RecordError, match="looks like"):
        read_csv_mapped(f, cols, {**units, "de": "rad"})
    lines = f.read_text().splitlines()
    trunc = tmp_path / "trunc.csv"
    trunc.write_text("\n".join(lines[:-1] + [lines[-1].rsplit(",", 2)[0]]))
    with pytest.raises(RecordError, match=f"trunc.csv: line {len(lines)} has 4 fields"):
        read_csv_mapped(trunc, cols, units)
    lines[10] = lines[10].replace(lines[10].split(",")[2], "abc", 1)
    nonnum = tmp_path / "nonnum.csv"
    nonnum.write_text("\n".join(lines))
    with pytest.raises(RecordError, match="line 11, column 'AOA \\[deg\\]': 'abc' is not a number"):
        read_csv_mapped(nonnum, cols, units)


def test_window_outside_record_names_file():
    path = data_path(TO17)
    with pytest.raises(RecordError, match="totter_lon_020213f1_017.mat.*outside the record"):
        read_sidpac(path, t0=5.0, t1=9.0)
    with pytest.raises(RecordError, match="not before its end"):
        read_sidpac(path, t0=3.0, t1=2.0)
    with pytest.raises(RecordError, match="only 2 samples"):
        read_sidpac(path, t0=1.0, t1=1.02)


def test_different_sample_rates_together(tmp_path):
    t, de, alpha, q, az, V = _truth(200, 0.02)
    a = Record(t, {"de": de, "alpha": alpha, "q": q, "az": az}).to_csv(tmp_path / "fast.csv")
    t2 = np.arange(100) * 0.04
    b = Record(t2, {"de": 0.01 * np.sin(t2), "alpha": 0 * t2, "q": 0 * t2, "az": 0 * t2 - 1}).to_csv(
        tmp_path / "slow.csv"
    )
    with pytest.raises(RecordError, match="different sample rates.*fast.csv: 50 Hz.*slow.csv: 25 Hz"):
        load_records([a, b])
    assert len(load_records([a, a])) == 2


def test_load_record_rejects_options_and_formats(tmp_path):
    path = data_path(HFB)
    with pytest.raises(RecordError, match="original.*do not apply to format 'dlr-asc'"):
        load_record(path, original=True)
    with pytest.raises(RecordError, match="unknown record format"):
        load_record(path, format="excel")
    f = tmp_path / "x.bin"
    f.write_text("1 2 3")
    with pytest.raises(RecordError, match="cannot tell the record format"):
        load_record(f)
    with pytest.raises(RecordError, match="does not exist"):
        load_record(tmp_path / "absent.mat")
    with pytest.raises(RecordError, match="unknown trim mode"):
        read_sidpac(data_path(TO17), trim="median")


# --- units ---------------------------------------------------------------------------------------
def test_unit_spellings_and_factors():
    assert normalise_unit("deg/sec") == "deg/s"
    assert normalise_unit(" M/S2 ") == "m/s^2"
    assert normalise_unit("ft/sec**2") == "ft/s^2"
    assert normalise_unit("lbf/ft2") == "lbf/ft^2"
    assert unit_factor("kt", "speed") == pytest.approx(1852 / 3600, rel=1e-15)
    assert unit_factor("ft/s^2", "specific force") == pytest.approx(0.3048 / 9.80665, rel=1e-15)
    assert unit_factor("m/s^2", "specific force") * G0 == pytest.approx(1.0, rel=1e-15)
    np.testing.assert_allclose(to_si([180.0], "deg", "alpha"), [math.pi], rtol=1e-15)
    with pytest.raises(RecordError, match="measures speed"):
        unit_factor("kt", "angle")


def test_loaders_do_not_touch_the_source(tmp_path):
    src = data_path(TO17)
    copy = tmp_path / "copy.mat"
    shutil.copy(src, copy)
    before = copy.read_bytes()
    read_sidpac(copy, trim="first")
    assert copy.read_bytes() == before


# --- the command line reads every format ---------------------------------------------------------
def test_fdml_fit_reads_a_sidpac_record(capsys):
    import json

    from fdml.cli import main

    path = data_path(TO17)
    code = main(["fit", str(path), "--model", "dimensional", "--airspeed", "73.25", "--band", "0.63:9.4:0.1", "--json"])
    d = json.loads(capsys.readouterr().out)
    assert code == 0 and d["converged"]
    # a statically stable aircraft with a conventional elevator (trailing edge down: nose down)
    assert d["params"]["M_a"]["value"] < 0 and d["params"]["M_de"]["value"] < 0
    # short-period frequency sqrt(Z_a M_q - M_a) of a Twin Otter: 3-5 rad/s (0.5-0.8 Hz)
    p = {k: v["value"] for k, v in d["params"].items()}
    wn = math.sqrt(p["Z_a"] * p["M_q"] - p["M_a"] * (1 + p["Z_q"]))
    assert 3.0 < wn < 5.0


def test_fdml_fit_rejects_mixed_rates_and_bad_maps(tmp_path, capsys):
    from fdml.cli import main

    code = main(["fit", str(data_path(TO17)), str(data_path(ATTAS)), "--model", "dimensional", "--airspeed", "80"])
    err = capsys.readouterr().err
    assert code == 2 and "different sample rates" in err and "fAttasElv1.mat: 25 Hz" in err
    t, de, alpha, q, az, V = _truth()
    f = tmp_path / "foreign.csv"
    _write_foreign_csv(f, t, de, alpha, q, az, V)
    code = main(
        [
            "fit",
            str(f),
            "--model",
            "dimensional",
            "--airspeed",
            "60",
            "--columns",
            "t=time,de=elev_deg,alpha=AOA,q=pitch_rate,az=n_z",
            "--units",
            "de=deg,q=deg/s,az=g",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "no column 'n_z' (mapped to az)" in err
    code = main(["fit", str(f), "--model", "dimensional", "--airspeed", "60", "--units", "de=deg"])
    err = capsys.readouterr().err
    assert code == 2 and "give --columns too" in err
