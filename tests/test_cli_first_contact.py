"""A new user's first commands (issue 21, set-up and commands): each works as printed.

Each test runs the command line as a user types it and checks what the user sees: the
exit code, the one-line messages, and numbers against an independent computation.
"""

import argparse
import json
import re
import shlex

import numpy as np
import pytest

from fdml.aircraft import LAG_KEYS, get_aircraft
from fdml.cli import main


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# --- item 2: lag constants given by --set, --fix or --free count as given ---------------------------
@pytest.fixture
def no_lag_aircraft(tmp_path):
    """(file, lags): the Sundowner preset written without its lag constants, and those constants."""
    d = get_aircraft("sundowner").to_dict()
    lags = {k: d.pop(k) for k in LAG_KEYS}
    d["sources"] = {k: v for k, v in d["sources"].items() if k not in lags}
    d["assumed"] = [k for k in d["assumed"] if k not in lags]
    path = tmp_path / "no_lags.json"
    path.write_text(json.dumps(d))
    return path, lags


def _response(capsys, *argv):
    code, out, err = run(capsys, "response", "--model", "unsteady", "--band", "0.5:12:0.5", "--json", *argv)
    assert code == 0, err
    d = json.loads(out)
    return np.array(d["real"]) + 1j * np.array(d["imag"])


def test_response_with_lag_constants_by_set_equals_the_aircraft_that_carries_them(capsys, no_lag_aircraft):
    path, lags = no_lag_aircraft
    sets = [x for k, v in lags.items() for x in ("--set", f"{k}={v!r}")]
    G = _response(capsys, "--aircraft", path, *sets)
    oracle = _response(capsys, "--aircraft", "sundowner")  # the preset: the same constants in the aircraft file
    # the same model evaluated on the same constants: equal to rounding
    np.testing.assert_allclose(G, oracle, rtol=1e-12, atol=0)


def test_fit_with_lag_constants_by_fix_or_free_is_not_refused(tmp_path, capsys, no_lag_aircraft):
    path, lags = no_lag_aircraft
    rec = tmp_path / "sd.csv"
    code, _, err = run(capsys, "simulate", "--aircraft", "sundowner", "--duration", "8", "--noise", "0.02", "-o", rec)
    assert code == 0, err

    def fit(*argv):
        code, out, err = run(capsys, "fit", rec, "--model", "unsteady", "--json", *argv)
        assert code == 0, err
        return json.loads(out)

    fixes = [x for k, v in lags.items() for x in ("--fix", f"{k}={v!r}")]
    by_fix = fit("--aircraft", path, *fixes)
    oracle = fit("--aircraft", "sundowner", *fixes)
    for name, p in oracle["params"].items():  # the same fit: equal to rounding
        assert by_fix["params"][name]["value"] == pytest.approx(p["value"], rel=1e-9, abs=1e-15), name
    assert {k: c["source"] for k, c in by_fix["provenance"]["lag_constants"]["constants"].items()} == dict.fromkeys(
        LAG_KEYS, "--fix"
    )
    # a freed constant with the others fixed: estimated, and the rest as given
    freed = fit("--aircraft", path, "--free", "y_w", *fixes[2:])
    assert "y_w" in freed["params"] and freed["fixed"]["z_w"] == lags["z_w"]


def test_batch_model_spec_with_lag_constants_by_fix_builds_the_aircrafts_model(no_lag_aircraft):
    from fdml.batch import ModelSpec
    from fdml.models import make_model

    path, lags = no_lag_aircraft
    built = ModelSpec(kind="unsteady", aircraft=str(path), fix=lags).normalized().build()
    oracle = make_model("unsteady", "sundowner")
    w = np.linspace(0.5, 12, 24)
    np.testing.assert_allclose(built.frequency_response(w), oracle.frequency_response(w), rtol=1e-12, atol=0)


# --- item 3: a noise-free record converges at the floating-point floor -----------------------------
@pytest.mark.slow
def test_noise_free_fit_converges_at_the_floor_saves_reports_and_exits_0(tmp_path, capsys):
    from fdml.models import make_model
    from fdml.results import load_result

    rec, out = tmp_path / "clean.csv", tmp_path / "clean.json"
    assert run(capsys, "simulate", "--aircraft", "navion", "--model", "steady", "--noise", "0", "-o", rec)[0] == 0
    code, text, err = run(capsys, "fit", rec, "--aircraft", "navion", "--model", "steady", "-o", out)
    assert code == 0, err
    assert "NOT converged" not in text and "converged at the floating-point floor" in text
    res = load_result(out)
    assert res.converged
    truth = make_model("steady", "navion").parameters.values
    for name in ("CLa_w", "CLa_t", "deps_da", "Cm_de", "Cz_de"):
        # the record differs from the model only by the simulator's discretisation (residuals about
        # 1e-4 of each output's RMS at dt = 0.02 s), which the estimates follow at that order
        assert res.params[name] == pytest.approx(truth[name], rel=1e-3), name
    code, _, err = run(capsys, "report", out, "-o", tmp_path / "rep")
    assert code == 0, err
    assert "converged at the floating-point floor" in (tmp_path / "rep" / "report.md").read_text()


# --- item 4: fdml batch takes each record's airspeed, and says when --airspeed disagrees -----------
@pytest.fixture
def record_with_airspeed(tmp_path):
    """(csv, mapping options, U): a noisy dimensional-model record at 60 m/s with an airspeed column V."""
    from fdml.models import make_model
    from fdml.record import add_noise
    from fdml.simulate import simulate_maneuver

    U = 60.0
    rec = add_noise(
        simulate_maneuver(make_model("dimensional", airspeed=U), "3211", duration=10.0, dt=0.02),
        0.02,
        np.random.default_rng(4),
        relative=True,
    )
    V = U + 0.5 * np.sin(rec.t)  # the record's airspeed varies a little; its mean is what the rule takes
    path = tmp_path / "rec.csv"
    cols = np.column_stack([rec.t, rec["de"], rec["alpha"], rec["q"], rec["az"], V])
    np.savetxt(path, cols, delimiter=",", header="t,de,alpha,q,az,V", comments="")
    opts = ["--columns", "t=t,de=de,alpha=alpha,q=q,az=az,V=V", "--units", "de=rad,alpha=rad,q=rad/s,az=g,V=m/s"]
    return path, opts, float(np.mean(V))


def _batch_result(capsys, tmp_path, rec, opts, *extra):
    out = tmp_path / "batch"
    code, _, err = run(capsys, "batch", rec, *opts, "--serial", "--no-progress", "-o", out, *extra)
    assert code == 0, err
    return json.loads((out / "results" / "rec.json").read_text())


def test_batch_without_airspeed_uses_each_records_mean_airspeed_as_fit_does(tmp_path, capsys, record_with_airspeed):
    rec, opts, U = record_with_airspeed
    res = _batch_result(capsys, tmp_path, rec, opts)
    assert res["provenance"]["airspeed"]["source"] == "record"
    assert res["provenance"]["airspeed"]["value"] == pytest.approx(U, rel=1e-12)
    code, out, err = run(capsys, "fit", rec, *opts, "--json")
    assert code == 0, err
    fitted = json.loads(out)
    names = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")
    batch = dict(zip(res["names"], res["values"]))
    for name in names:  # the same model at the same airspeed, the same fit: equal to rounding
        assert batch[name] == pytest.approx(fitted["params"][name]["value"], rel=1e-9), name


def test_batch_with_a_wrong_airspeed_reports_the_mismatch_and_its_provenance(tmp_path, capsys, record_with_airspeed):
    rec, opts, U = record_with_airspeed
    res = _batch_result(capsys, tmp_path, rec, opts, "--airspeed", "35")
    assert [f["code"] for f in res["findings"]] == ["airspeed.mismatch"]
    assert res["findings"][0]["expected"] == pytest.approx(U, rel=1e-12)
    assert res["provenance"]["airspeed"]["value"] == 35.0
    table = (tmp_path / "batch" / "table.csv").read_text()
    assert "airspeed.mismatch" in table


# --- item 5: advice that can be run as printed ----------------------------------------------------
def _options_of(command: str) -> set:
    """Every option string the parser of ``fdml COMMAND`` accepts."""
    from fdml.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {flag for a in sub.choices[command]._actions for flag in a.option_strings}


def _assert_named_options_exist(message: str, command: str) -> None:
    """Every ``--option`` the message names is an option of ``fdml COMMAND``."""
    named = set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", message))
    assert named, message
    assert named <= _options_of(command), (named - _options_of(command), message)


def test_fit_advice_commands_parse_and_run_as_printed(tmp_path, capsys):
    from fdml.cli import build_parser

    rec = tmp_path / "td.csv"
    argv = ["simulate", "--airspeed", "60", "--effect", "time_delay:alpha", "--set", "tau_alpha=0.1"]
    assert run(capsys, *argv, "--noise", "0.02", "--seed", "1", "-o", rec)[0] == 0
    effects = ["sensor_offset:az", "sensor_scale:q"]
    code, out, err = run(
        capsys, "fit", rec, "--airspeed", "60", "--effect", effects[0], "--effect", effects[1], "--json"
    )
    assert code == 0, err
    msg = next(w["message"] for w in json.loads(out)["warnings"] if w["category"] == "AdequacyWarning")
    refit, diagnose = re.search(
        r"Refit with it: (fdml fit .*); or run the full diagnosis: (fdml diagnose .*)$", msg
    ).groups()
    for command in (refit, diagnose):
        args = build_parser().parse_args(shlex.split(command)[1:])  # exits with code 2 on an unrecognised argument
        assert args.effect[:2] == effects, command
    assert build_parser().parse_args(shlex.split(refit)[1:]).effect == [*effects, "time_delay:alpha"]
    code, _, err = run(capsys, *shlex.split(refit)[1:])
    assert code == 0, err


def _adequacy(whiteness: bool, coherence: bool):
    from fdml.adequacy import Adequacy, ResidualCheck

    def check(name, failed):
        return ResidualCheck(name, 30.0 if failed else 1.0, 1e-9 if failed else 0.5, 1e-8 if failed else 1.0, 3, "r/q")

    return Adequacy(0.01, (), (), whiteness=check("whiteness", whiteness), coherence=check("coherence", coherence))


def test_residual_advice_spells_cov_type_as_run_and_only_where_it_helps():
    from fdml.adequacy import advice

    argv = {"fit_argv": ["fdml", "fit", "r.csv"], "diagnose_argv": ["fdml", "diagnose", "r.csv"]}
    white = _adequacy(whiteness=True, coherence=False)
    on_cli = advice(white, **argv)
    given = advice(white, cov_type="colored", **argv)
    coherence = advice(_adequacy(whiteness=False, coherence=True), **argv)
    assert "--cov-type colored" in on_cli and "cov_type" not in on_cli
    _assert_named_options_exist(on_cli, "fit")
    assert "try" not in given and "--cov-type" not in given  # already given: not suggested again
    assert "colored" not in coherence  # a coherence with the input is model error: coloured bounds do not help
    assert 'cov_type="colored"' in advice(white)  # in Python, the keyword (and the option beside it)
    assert "diagnos" not in advice(white, in_diagnosis=True)  # the diagnosis's own fits: not to the diagnosis


def test_the_diagnosis_does_not_advise_running_the_diagnosis(tmp_path, capsys):
    from fdml.io import data_path

    rec = data_path("hfb320/hfb320_1_10.asc")
    code, _, err = run(capsys, "diagnose", rec, "--t1", "20", "-o", tmp_path / "d.json")
    assert code == 0, err
    report = json.loads((tmp_path / "d.json").read_text())
    messages = [w["message"] for w in report["warnings"]]
    assert messages  # the record's recommended fit fails the whiteness check: the warning is there ...
    assert not any("fdml diagnose" in m for m in messages), messages  # ... without sending the user back


def test_unit_check_message_names_an_option_that_reads_the_record(tmp_path, capsys):
    from fdml.models import make_model
    from fdml.simulate import simulate_maneuver

    rec = simulate_maneuver(make_model("dimensional", airspeed=60.0), "3211", duration=6.0, dt=0.02)
    path = tmp_path / "large_angles.csv"
    big = {k: (rec[k] * 200 if k in ("alpha", "q") else rec[k]) for k in ("de", "alpha", "q", "az")}
    np.savetxt(path, np.column_stack([rec.t, *big.values()]), delimiter=",", header="t,de,alpha,q,az", comments="")
    code, _, err = run(capsys, "check", path)
    assert code == 2 and "--no-unit-check" in err and "check_units=False" in err.replace("Python: ", "")
    _assert_named_options_exist(err, "check")
    code, _, err = run(capsys, "check", path, "--no-unit-check")
    assert code == 0, err


def test_csv_unit_message_names_the_units_option_as_spelled(tmp_path, capsys):
    from fdml.models import make_model
    from fdml.simulate import simulate_maneuver

    rec = simulate_maneuver(make_model("dimensional", airspeed=60.0), "3211", duration=6.0, dt=0.02)
    path = tmp_path / "mapped.csv"
    cols = [rec.t, rec["de"], rec["alpha"], rec["q"], rec["az"]]
    np.savetxt(path, np.column_stack(cols), delimiter=",", header="time,elev,aoa,q,nz", comments="")
    mapping = ["--columns", "t=time,de=elev,alpha=aoa,q=q,az=nz"]
    code, _, err = run(capsys, "check", path, *mapping)
    assert code == 2 and "--units de=UNIT" in err, err
    _assert_named_options_exist(err, "check")
    code, _, err = run(capsys, "check", path, *mapping, "--units", "de=rad,alpha=rad,q=rad/s,az=g")
    assert code == 0, err


def test_dlr_mat_with_two_matrices_names_the_variable_option(tmp_path, capsys):
    from scipy.io import savemat

    from fdml.constants import G0
    from fdml.models import make_model
    from fdml.simulate import simulate_maneuver

    rec = simulate_maneuver(make_model("dimensional", airspeed=100.0), "3211", duration=8.0, dt=0.1)
    M = np.zeros((rec.t.size, 20))  # the HFB-320 layout (fdml.io.dlr.LAYOUTS): 1-based columns below
    M[:, 0], M[:, 1], M[:, 4], M[:, 5], M[:, 7] = rec.t, rec["de"], 100.0, rec["alpha"], rec["q"]
    M[:, 10] = G0 * (rec["az"] - 1.0)  # body-z specific force, m/s^2: -1 g in trim
    path = tmp_path / "two.mat"
    savemat(path, {"first": M, "second": M})
    code, _, err = run(capsys, "check", path)
    assert code == 2 and "--variable NAME" in err, err
    _assert_named_options_exist(err, "check")
    code, _, err = run(capsys, "check", path, "--variable", "second")
    assert code == 0, err


def test_compatibility_message_names_a_runnable_estimate_option(capsys):
    from fdml.io import data_path

    rec = data_path("twin_otter/totter_lon_020213f1_017.mat")
    code, out, err = run(capsys, "check", rec, "--compat")
    assert code == 0, err
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("K_az"))
    command = re.search(r"to estimate it: (fdml check --compat --estimate \S+);", line).group(1)
    code, out, err = run(capsys, *shlex.split(command)[1:], rec)
    assert code == 0, err
    assert not any(ln.strip().startswith("K_az") and "not estimated" in ln for ln in out.splitlines())


# --- item 7: one band syntax, LO:HI[:STEP], everywhere ----------------------------------------------
def test_fit_and_batch_accept_lo_hi_with_the_documented_default_step(tmp_path, capsys, record_with_airspeed):
    from fdml.spectral import DEFAULT_STEP

    rec, opts, _ = record_with_airspeed
    code, out, err = run(capsys, "fit", rec, *opts, "--band", "1:8", "--json")
    assert code == 0, err
    short = json.loads(out)
    code, out, err = run(capsys, "fit", rec, *opts, "--band", f"1:8:{DEFAULT_STEP}", "--json")
    assert code == 0, err
    full = json.loads(out)
    assert short["band"] == full["band"] == [1.0, 8.0, DEFAULT_STEP]
    assert short["params"] == full["params"]  # the same grid: the same fit
    res = _batch_result(capsys, tmp_path, rec, opts, "--band", "1:8")
    n_freq = sum(len(s["omega"]) for s in res["spectra"])  # the file keeps the spectra; n_freq is derived
    assert n_freq == full["n_freq"] and res["values"][0] == full["params"][res["names"][0]]["value"]
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    assert f"without :STEP the step is {DEFAULT_STEP:g}" in " ".join(capsys.readouterr().out.split())


# --- item 6: a band typed in Hz ----------------------------------------------------------------------
@pytest.fixture
def short_record(tmp_path):
    """A 7.5 s noisy 3-2-1-1 of the dimensional model at 60 m/s (short period about 3.5 rad/s)."""
    from fdml.models import make_model
    from fdml.record import add_noise
    from fdml.simulate import simulate_maneuver

    model = make_model("dimensional", airspeed=60.0)
    rec = add_noise(
        simulate_maneuver(model, "3211", duration=7.5, dt=0.02), 0.02, np.random.default_rng(7), relative=True
    )
    return rec.to_csv(tmp_path / "short.csv"), model


def _band_findings(capsys, rec, *band):
    code, out, err = run(capsys, "fit", rec, "--airspeed", "60", *band, "--json")
    assert code in (0, 1), err
    d = json.loads(out)
    return [f for f in d["findings"] if f["code"] == "band.hz"], d


def test_a_band_typed_in_hz_is_named_with_its_rad_per_s_band(capsys, short_record):
    rec, model = short_record
    found, _ = _band_findings(capsys, rec, "--band", "0.1:1.5:0.02")
    assert len(found) == 1, found
    msg = found[0]["message"]
    assert "looks like Hz" in msg
    # the rad/s band is the typed one times 2 pi
    rad = re.search(r"--band (\S+) ", msg).group(1)
    assert [float(x) for x in rad.split(":")] == pytest.approx([2 * np.pi * x for x in (0.1, 1.5, 0.02)], rel=1e-3)
    _assert_named_options_exist(msg, "fit")
    # the short period of the truth lies above the typed band: the reason given
    assert model.short_period_frequency() > 1.5 and "below the fitted short-period frequency" in msg
    again, fitted = _band_findings(capsys, rec, "--band", rad)
    assert again == [] and fitted["converged"]


def test_rad_per_s_and_default_bands_are_not_taken_for_hz(capsys, short_record):
    rec, _ = short_record
    assert _band_findings(capsys, rec, "--band", "0.5:12:0.2")[0] == []
    assert _band_findings(capsys, rec)[0] == []  # the default band, 0.1:10:0.1


def test_short_period_frequency_is_the_modulus_of_the_eigenvalues():
    from fdml.models import make_model

    m = make_model("dimensional", "navion")
    p = m.parameters.values
    A = np.array([[p["Z_a"], 1 + p["Z_q"]], [p["M_a"], p["M_q"]]])  # docs/theory.md: the classical short period
    # a complex pair: both eigenvalues have modulus omega_n
    assert m.short_period_frequency() == pytest.approx(np.abs(np.linalg.eigvals(A)), rel=1e-12)


# --- item 8: -v anywhere, showing messages ------------------------------------------------------------
def test_verbose_after_the_command_shows_warnings_as_messages(capsys, short_record):
    rec, _ = short_record
    code, _, err_after = run(capsys, "fit", rec, "--airspeed", "60", "--band", "0.1:1.5:0.02", "-v")
    assert code in (0, 1), err_after
    code, _, err_before = run(capsys, "-v", "fit", rec, "--airspeed", "60", "--band", "0.1:1.5:0.02")
    assert err_after == err_before
    lines = err_after.splitlines()
    assert any("band.hz" in ln for ln in lines), err_after  # the warnings are shown ...
    for ln in lines:  # ... each as a message: no source file, line number or code line of a Python warning
        assert ln.startswith("fdml: ") and ".py:" not in ln and "site-packages" not in ln, ln
    assert run(capsys, "fit", rec, "--airspeed", "60", "--band", "0.1:1.5:0.02")[2] == ""  # quiet without -v


# --- item 9: a wrong --format names the format the file looks like -----------------------------------
@pytest.fixture
def dlr_mat(tmp_path):
    """A DLR .mat record in the HFB-320 layout (20 columns, fdml.io.dlr.LAYOUTS), from a simulation."""
    from scipy.io import savemat

    from fdml.constants import G0
    from fdml.models import make_model
    from fdml.simulate import simulate_maneuver

    rec = simulate_maneuver(make_model("dimensional", airspeed=100.0), "3211", duration=8.0, dt=0.1)
    M = np.zeros((rec.t.size, 20))
    M[:, 0], M[:, 1], M[:, 4], M[:, 5], M[:, 7] = rec.t, rec["de"], 100.0, rec["alpha"], rec["q"]
    M[:, 10] = G0 * (rec["az"] - 1.0)
    path = tmp_path / "hfb.mat"
    savemat(path, {"hfb": M})
    return path


@pytest.mark.parametrize("wrong", ["csv", "dlr-asc", "sidpac"])
def test_a_wrong_format_on_a_mat_file_names_the_format_it_looks_like(capsys, dlr_mat, wrong):
    from conftest import assert_refused_in_one_line

    code, _, err = run(capsys, "check", dlr_mat, "--format", wrong)
    assert_refused_in_one_line(code, err, [f"--format {wrong} does not fit", "--format dlr-mat"])
    assert "codec" not in err and "corrupt" not in err
    assert run(capsys, "check", dlr_mat, "--format", "dlr-mat")[0] == 0  # the format named reads it


def test_a_wrong_format_on_a_csv_names_csv(tmp_path, capsys, short_record):
    from conftest import assert_refused_in_one_line

    rec, _ = short_record
    for wrong in ("sidpac", "dlr-mat", "dlr-asc"):
        code, _, err = run(capsys, "check", rec, "--format", wrong)
        assert_refused_in_one_line(code, err, [f"--format {wrong} does not fit", "--format csv"])
    code, _, err = run(capsys, "check", rec, "--format", "csv-map")  # was an internal error (no column map)
    assert_refused_in_one_line(code, err, ["csv-map needs --columns"])
