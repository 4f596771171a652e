"""Bad input is refused with one clear line, never a silent wrong answer (issue 14).

Every case here gave, before the change, a silent wrong answer (exit 0 or a
fit on the wrong data), "internal error" (exit 1), a table of NaN, or a
misleading message.  The command-line table runs each through
``fdml.cli.main`` and asserts exit code 2, exactly one line on stderr, the
option or path named, and no traceback; the library tests pin the behaviour
behind it.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import assert_refused_in_one_line

from fdml.aircraft import MAX_AIRSPEED, Aircraft, get_aircraft
from fdml.cli import main
from fdml.errors import AircraftError, BandError, FdmlError, ParameterError, RecordError
from fdml.estimate import fit
from fdml.fourier import MAX_BAND_FREQUENCIES, check_band
from fdml.io import read_csv_mapped, read_fdml_csv
from fdml.models import make_model
from fdml.record import Record, add_noise, read_csv
from fdml.simulate import simulate_maneuver
from fdml.spectral import spectra

MAPPED = ["--columns", "t=t,de=de,alpha=alpha,q=q,az=az", "--units", "de=rad,alpha=rad,q=rad/s,az=g"]
STEADY = ["--aircraft", "navion", "--model", "steady"]


def _simulated(seed: int = 1) -> Record:
    """A noisy Navion 3-2-1-1, 10 s at 50 Hz (steady model), as fdml simulate writes it."""
    rec = simulate_maneuver(make_model("steady", "navion"), "3211", seed=seed)
    return add_noise(rec, 0.02, np.random.default_rng(seed), relative=True)


def _write_csv(path, header, rows, encoding="utf-8"):
    lines = [",".join(header)] + [",".join(repr(float(v)) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding=encoding)
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Records and aircraft files, good and bad, in one folder: name -> path (str)."""
    d = tmp_path_factory.mktemp("bad_inputs")
    rec = _simulated()
    header = ["t", "de", "alpha", "q", "az"]
    cols = [rec.t] + [rec[k] for k in header[1:]]
    rows = np.column_stack(cols)
    out = {"dir": d}
    out["a"] = rec.to_csv(d / "a.csv")
    out["copy"] = rec.to_csv(d / "copy_of_a.csv")
    out["bom"] = _write_csv(d / "bom.csv", header, rows, encoding="utf-8-sig")
    # a second alpha column (in degrees, as a data logger might add): which one is alpha?
    out["dup"] = _write_csv(d / "dup.csv", header + ["alpha"], np.column_stack(cols + [np.degrees(rec["alpha"])]))
    ms = rows.copy()
    ms[:, 0] *= 1e3
    out["ms"] = _write_csv(d / "ms.csv", header, ms)
    us = rows.copy()
    us[:, 0] *= 1e6
    out["us"] = _write_csv(d / "us.csv", header, us)
    navion = get_aircraft("navion").to_dict()
    for name, change in {
        "ac_bool": {"mass": True},
        "ac_str": {"mass": "1247"},
        "ac_neg": {"Iy": -4067.0},
        "ac_sources": {"sources": ["POH"]},
        "ac_srcval": {"sources": {"mass": 1247}},
        "ac_assumed": {"assumed": "mass"},
        "ac_U50": {"U": 1e50},
        "ac_U154": {"U": 1e154},
        "ac_good": {},
    }.items():
        (d / f"{name}.json").write_text(json.dumps({**navion, **change}))
        out[name] = d / f"{name}.json"
    (d / "ac_nan.json").write_text(json.dumps({**navion, "rho": float("nan")}))  # json writes NaN
    out["ac_nan"] = d / "ac_nan.json"
    (d / "ac_latin1.json").write_bytes(
        json.dumps({**navion, "description": "Caf\u00e9"}, ensure_ascii=False).encode("latin-1")
    )
    out["ac_latin1"] = d / "ac_latin1.json"
    (d / "ac_invalid.json").write_text('{"name": "navion", "mass": ')
    out["ac_invalid"] = d / "ac_invalid.json"
    (d / "ac_folder.json").mkdir()
    out["ac_folder"] = d / "ac_folder.json"
    return {k: str(v) for k, v in out.items()}


# (id, command line with {placeholders} from `files`, texts the one stderr line must contain)
CASES = [
    ("duplicate-column", ["fit", "{dup}", *STEADY], ["{dup}", "'alpha'", "2 times"]),
    ("duplicate-column-mapped", ["fit", "{dup}", *MAPPED, *STEADY], ["{dup}", "'alpha'", "2 times"]),
    ("time-in-ms", ["fit", "{ms}", *STEADY], ["{ms}", "milliseconds", "sample interval 20", "give time in seconds"]),
    ("time-in-us", ["fit", "{us}", *STEADY], ["{us}", "microseconds", "give time in seconds"]),
    ("time-in-ms-mapped", ["fit", "{ms}", *MAPPED, *STEADY], ["{ms}", "milliseconds"]),
    ("sign-not-unit", ["fit", "{a}", *MAPPED, "--sign", "az=-1.9", *STEADY], ["--sign az=-1.9", "+1 or -1", "--units"]),
    ("sign-not-number", ["fit", "{a}", *MAPPED, "--sign", "az=down", *STEADY], ["--sign az=down"]),
    ("fix-and-free", ["fit", "{a}", *STEADY, "--fix", "Cm_de=-1.4", "--free", "Cm_de"], ["Cm_de", "--fix", "--free"]),
    (
        "fix-and-free-batch",
        [
            "batch",
            "{a}",
            *STEADY,
            "--fix",
            "Cm_de=-1.4",
            "--free",
            "Cm_de",
            "--output",
            "{dir}/b1",
            "--serial",
            "--no-progress",
        ],
        ["Cm_de", "--fix", "--free"],
    ),
    ("same-file-twice", ["fit", "{a}", "{a}", *STEADY], ["{a}", "same samples", "twice"]),
    ("copy-of-a-file", ["fit", "{a}", "{copy}", *STEADY], ["{a}", "{copy}", "same samples"]),
    ("aircraft-bool", ["response", "--aircraft", "{ac_bool}", "--model", "steady"], ["{ac_bool}", "mass", "True"]),
    ("aircraft-string", ["response", "--aircraft", "{ac_str}", "--model", "steady"], ["{ac_str}", "mass", "'1247'"]),
    ("aircraft-negative", ["response", "--aircraft", "{ac_neg}", "--model", "steady"], ["{ac_neg}", "Iy", "positive"]),
    ("aircraft-nan", ["response", "--aircraft", "{ac_nan}", "--model", "steady"], ["{ac_nan}", "NaN"]),
    (
        "aircraft-sources-list",
        ["response", "--aircraft", "{ac_sources}", "--model", "steady"],
        ["{ac_sources}", "sources"],
    ),
    (
        "aircraft-sources-number",
        ["response", "--aircraft", "{ac_srcval}", "--model", "steady"],
        ["{ac_srcval}", "sources"],
    ),
    (
        "aircraft-assumed-str",
        ["response", "--aircraft", "{ac_assumed}", "--model", "steady"],
        ["{ac_assumed}", "assumed"],
    ),
    ("aircraft-latin1", ["response", "--aircraft", "{ac_latin1}", "--model", "steady"], ["{ac_latin1}", "UTF-8"]),
    (
        "aircraft-invalid-json",
        ["response", "--aircraft", "{ac_invalid}", "--model", "steady"],
        ["{ac_invalid}", "not valid JSON"],
    ),
    ("aircraft-folder", ["response", "--aircraft", "{ac_folder}", "--model", "steady"], ["{ac_folder}", "folder"]),
    ("aircraft-U-1e50", ["fit", "{a}", "--aircraft", "{ac_U50}", "--model", "steady"], ["{ac_U50}", "airspeed"]),
    ("aircraft-U-1e154", ["response", "--aircraft", "{ac_U154}", "--model", "steady"], ["{ac_U154}", "airspeed"]),
    ("airspeed-1e50", ["response", "--model", "dimensional", "--airspeed", "1e50"], ["airspeed", "1e+50"]),
    ("airspeed-1e154", ["response", "--model", "dimensional", "--airspeed", "1e154"], ["airspeed"]),
    ("huge-band", ["fit", "{a}", *STEADY, "--band", "0.001:1e9:0.001"], ["--band", "frequencies"]),
    ("huge-band-check", ["check", "{a}", "--band", "0.001:1e9:0.001"], ["--band", "frequencies"]),
    (
        "inverted-band-montecarlo",
        ["montecarlo", *STEADY, "-n", "4", "--workers", "1", "--no-progress", "--band", "10:1:1"],
        ["--band", "below"],
    ),
    (
        "four-part-band-batch",
        ["batch", "{a}", *STEADY, "--band", "1:2:0.1:4", "--output", "{dir}/b2", "--serial", "--no-progress"],
        ["--band", "LO:HI[:STEP]"],
    ),
    ("inverted-band-response", ["response", *STEADY, "--band", "10:1:1"], ["--band"]),
    ("negative-seed", ["simulate", *STEADY, "--seed", "-1", "-o", "{dir}/s.csv"], ["--seed", "-1"]),
    (
        "negative-workers-montecarlo",
        ["montecarlo", *STEADY, "-n", "4", "--workers", "-2", "--no-progress"],
        ["--workers", "-2"],
    ),
    (
        "zero-workers-batch",
        ["batch", "{a}", *STEADY, "--workers", "0", "--output", "{dir}/b3", "--no-progress"],
        ["--workers"],
    ),
]


@pytest.mark.parametrize("argv, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_command_line_refuses_with_one_line(files, capsys, argv, expected):
    try:
        code = main([a.format(**files) for a in argv])
    except SystemExit as exc:  # argparse usage errors (--seed -1, --workers -2) exit through SystemExit(2)
        code = exc.code
    assert_refused_in_one_line(code, capsys.readouterr().err, [t.format(**files) for t in expected])


def test_bom_csv_is_read_like_the_plain_file(files):
    plain, bom = read_csv(files["a"]), read_csv(files["bom"])
    assert np.array_equal(bom.t, plain.t)
    for k in ("de", "alpha", "q", "az"):
        assert np.array_equal(bom[k], plain[k])
    mapped = read_csv_mapped(
        files["bom"],
        {"t": "t", "de": "de", "alpha": "alpha", "q": "q", "az": "az"},
        {"de": "rad", "alpha": "rad", "q": "rad/s", "az": "g"},
    )
    assert np.array_equal(mapped["alpha"], plain["alpha"])


def test_bom_csv_fits_on_the_command_line(files, capsys):
    assert main(["fit", files["bom"], *STEADY, "--json"]) in (0, 1)  # 1 only if not converged
    assert json.loads(capsys.readouterr().out)["records"] == ["bom"]


def test_duplicate_column_is_an_error_at_load(files):
    with pytest.raises(RecordError, match=r"column 'alpha' appears 2 times") as info:
        read_fdml_csv(files["dup"])
    assert files["dup"] in str(info.value)


def test_repeated_ignored_column_is_harmless(tmp_path):
    rec = _simulated()
    cols = [rec.t] + [rec[k] for k in ("de", "alpha", "q", "az")]
    path = _write_csv(
        tmp_path / "notes.csv", ["t", "de", "alpha", "q", "az", "note", "note"], np.column_stack(cols + [rec.t, rec.t])
    )
    assert np.array_equal(read_csv(path)["alpha"], rec["alpha"])


@pytest.mark.parametrize("factor, unit", [(1e3, "milliseconds"), (1e6, "microseconds")])
def test_time_not_in_seconds_is_a_time_unit_error(factor, unit):
    rec = _simulated()
    with pytest.raises(RecordError, match=f"time looks like {unit}"):
        Record(rec.t * factor, rec.signals, name="r")


def test_time_in_ms_at_2_khz_is_caught_by_the_record_length():
    # 0.5 ms interval in ms reads as 2 Hz: a plausible rate, but 20 s of it is 40,000 "s" (11 h)
    t = np.arange(40_001) * 0.5
    with pytest.raises(RecordError, match="milliseconds"):
        Record(t, {k: np.zeros_like(t) for k in ("de", "alpha", "q", "az")})


@pytest.mark.parametrize("dt, n", [(1.0, 300), (0.5, 600), (1 / 2000, 20_000)])
def test_plausible_sample_rates_in_seconds_pass(dt, n):
    t = np.arange(n) * dt  # 1 Hz and 2 Hz for 5 min, 2 kHz for 10 s
    assert Record(t, {k: np.zeros(n) for k in ("de", "alpha", "q", "az")}).n == n


def test_fix_as_a_string_is_one_name():
    rec = _simulated()
    model = make_model("steady", "navion")
    by_str = fit(rec, model, fix="Cm_de", max_iter=2)
    by_list = fit(rec, model, fix=["Cm_de"], max_iter=2)
    assert not by_str.model.parameters["Cm_de"].free
    assert by_str.model.parameters.free_names == by_list.model.parameters.free_names
    two = fit(rec, model, fix="Cm_de, Cz_de", max_iter=2)
    assert {"Cm_de", "Cz_de"}.isdisjoint(two.model.parameters.free_names)


def test_free_as_a_string_is_one_name():
    model = make_model("steady", "navion")
    assert "tau_de" not in model.parameters.free_names  # fixed by default
    res = fit(_simulated(), model, free="tau_de", max_iter=2)
    assert "tau_de" in res.model.parameters.free_names


@pytest.mark.parametrize("fix", [{"Cm_de": -1.4}, ["Cm_de"], "Cm_de"])
def test_fix_and_free_the_same_parameter_is_refused(fix):
    with pytest.raises(ParameterError, match="Cm_de named in both fix and free"):
        fit(_simulated(), make_model("steady", "navion"), fix=fix, free=["Cm_de"])


def test_the_same_record_twice_is_refused():
    rec = _simulated()
    model = make_model("steady", "navion")
    with pytest.raises(RecordError, match="same samples"):
        fit([rec, rec], model)
    shifted = replace(rec, t=rec.t + 100.0, name="later")  # same samples, another time origin
    with pytest.raises(RecordError, match=r"'later'"):
        fit([rec, shifted], model)
    data = replace(spectra(rec), record=None)  # spectra only: compared as spectra
    with pytest.raises(RecordError, match="same samples"):
        fit([data, replace(data, name="again")], model)


def test_two_different_records_still_fit_together():
    res = fit([_simulated(1), _simulated(2)], make_model("steady", "navion"), max_iter=3)
    assert res.model.parameters["Cm_de"].free  # the fit ran on both: no duplicate refused


@pytest.mark.parametrize(
    "key, value",
    [
        ("mass", True),
        ("mass", "1247"),
        ("S_w", None),
        ("rho", float("nan")),
        ("c_w", -1.7),
        ("U", MAX_AIRSPEED * 1.01),
        ("Cm_de", False),
        ("sources", {"mass": 3}),
        ("sources", "POH"),
        ("assumed", "mass"),
        ("assumed", ["not_a_key"]),
    ],
)
def test_aircraft_values_must_be_real_and_physical(key, value):
    d = {**get_aircraft("navion").to_dict(), key: value}
    with pytest.raises(AircraftError, match=f"my.json: .*{key}"):
        Aircraft.from_dict(d, origin="my.json")


def test_presets_still_load():
    for name in ("navion", "sundowner", "do128"):
        ac = get_aircraft(name)
        assert 0 < ac.U <= MAX_AIRSPEED


def test_dimensional_airspeed_limit():
    with pytest.raises(ParameterError, match="airspeed"):
        make_model("dimensional", None, airspeed=MAX_AIRSPEED * 1.01)
    assert make_model("dimensional", None, airspeed=MAX_AIRSPEED).U == MAX_AIRSPEED


def test_frequency_response_never_returns_nan():
    model = make_model("dimensional", None, airspeed=100.0)
    with np.errstate(all="ignore"), pytest.raises(ParameterError, match="not finite"):
        model.frequency_response([0.1, 1.0], {"Z_de": 1e308, "M_de": 1e308})


def test_band_frequency_limit_is_exact():
    step = 1.0
    *_, count = check_band(1.0, float(MAX_BAND_FREQUENCIES), step)
    assert count == MAX_BAND_FREQUENCIES
    with pytest.raises(BandError, match="frequencies"):
        check_band(1.0, float(MAX_BAND_FREQUENCIES) + 1, step)
    with pytest.raises(BandError, match="frequencies"):
        check_band(1e-300, 1e308, 1e-300)  # (hi - lo) / step overflows to inf


@pytest.mark.parametrize("band", ["10:1:1", "1:2:0.1:4", "0:10:0.1", "0.1:10:0", "nan:1:0.1"])
def test_every_band_goes_through_one_check(band, files, tmp_path):
    from fdml.batch import ModelSpec, run_batch
    from fdml.quality import check_quality

    rec = _simulated()
    with pytest.raises(BandError):
        spectra(rec, band=band)
    with pytest.raises(BandError):
        check_quality(rec, band=band)
    with pytest.raises(BandError):
        run_batch(
            [files["a"]],
            ModelSpec(kind="steady", aircraft="navion"),
            tmp_path / "b",
            engine="serial",
            fit_kwargs={"band": band},
        )
    assert not (tmp_path / "b" / "table.csv").exists()  # refused before any record was fitted


def test_diagnosis_band_uses_the_same_check():
    from fdml.diagnose.data import parse_diag_band

    for band in ("0:10", "inf:10", "1:nan"):
        with pytest.raises(BandError):
            parse_diag_band(band)
    assert parse_diag_band("0.3:12") == (0.3, 12.0)


def test_library_seed_and_workers():
    from fdml.batch import ModelSpec
    from fdml.montecarlo import monte_carlo

    with pytest.raises(ParameterError, match="seed"):
        simulate_maneuver(make_model("steady", "navion"), seed=-1)
    with pytest.raises(FdmlError, match="workers"):
        monte_carlo(ModelSpec(kind="steady", aircraft="navion"), n=4, workers=-2)


def test_mapped_sign_must_be_exactly_one(files):
    cols = {"t": "t", "de": "de", "alpha": "alpha", "q": "q", "az": "az"}
    units = {"de": "rad", "alpha": "rad", "q": "rad/s", "az": "g"}
    for bad in (-1.9, True, 2):
        with pytest.raises(RecordError, match="sign of az"):
            read_csv_mapped(files["a"], cols, units, sign={"az": bad})
