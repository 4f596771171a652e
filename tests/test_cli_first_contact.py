"""A new user's first commands (issue 21, set-up and commands): each works as printed.

Each test runs the command line as a user types it and checks what the user sees: the
exit code, the one-line messages, and numbers against an independent computation.
"""

import json

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
