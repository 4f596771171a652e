"""fdml compare: the missing-lag refusal, the evidence, the Comparison's round trip and the command.

Reference values: R. T. Jones's one-term constants (THEORY.md section 2), the
closed form of the concentrated log-likelihood, an MA(1) process's long-run
variance, and records made by an independent frequency-domain implementation of
the model (benchmarks/compare_calibration.py), not by fdml's model code.
"""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_refused_in_one_line

from fdml.aircraft import LAG_KEYS, Aircraft, get_aircraft, jones_lag_constants
from fdml.cli import main
from fdml.compare import Comparison, _long_run_variance, compare_steady_unsteady, loglik_contributions
from fdml.errors import AircraftError, FdmlError
from fdml.models import make_model
from fdml.simulate import simulate_maneuver

_BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "compare_calibration.py"
_spec = importlib.util.spec_from_file_location("compare_calibration", _BENCH)
calib = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(calib)

#: The ten required keys only: geometry, mass and flight condition (Navion values).
MINIMAL = {
    k: v
    for k, v in get_aircraft("navion").to_dict().items()
    if k in ("name", "S_w", "c_w", "S_t", "c_t", "l_t", "mass", "Iy", "U", "rho")
}


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def record_csv(tmp_path_factory):
    rec = simulate_maneuver(make_model("unsteady", "navion"), "3211", duration=12.0, noise=0.03, seed=4)
    path = tmp_path_factory.mktemp("cmp") / "navion.csv"
    rec.to_csv(path)
    return path


def _aircraft_file(tmp_path, **extra):
    path = tmp_path / "mine.json"
    path.write_text(json.dumps({**MINIMAL, **extra}))
    return path


# --- the missing lag constants -------------------------------------------------------------------
def test_jones_constants_are_the_published_ones():
    # THEORY.md section 2: AR 6 -> 1 - 0.361 exp(-0.381 s); AR 3 -> 1 - 0.283 exp(-0.540 s)
    assert jones_lag_constants(6.0)[:2] == pytest.approx((0.361, 0.381), abs=1e-12)
    assert jones_lag_constants(3.0)[:2] == pytest.approx((0.283, 0.540), abs=1e-12)
    # AR 4 lies half way in 1/AR: (1/4 - 1/6) / (1/3 - 1/6) = 1/2
    assert jones_lag_constants(4.0)[:2] == pytest.approx((0.322, 0.4605), abs=1e-12)
    assert jones_lag_constants(12.0)[:2] == pytest.approx((0.361, 0.381))  # held at the AR 6 end
    assert jones_lag_constants(12.0)[2] > jones_lag_constants(5.0)[2]  # ... with a doubled uncertainty


def test_unsteady_refused_without_lag_constants_and_the_ways_out():
    ac = Aircraft.from_dict(MINIMAL)
    with pytest.raises(AircraftError) as exc:
        make_model("unsteady", ac)
    msg = str(exc.value)
    assert all(k in msg for k in LAG_KEYS) and "jones" in msg and "free" in msg and "\n" not in msg
    make_model("steady", ac), make_model("derivatives", ac)  # the steady models need no lags
    jones = Aircraft.from_dict({**MINIMAL, "lag_constants": "jones"})
    ar = MINIMAL["S_w"] / MINIMAL["c_w"] ** 2
    assert jones.constants["y_w"] == pytest.approx(jones_lag_constants(ar)[0])
    assert set(jones.lag_uncertainty) == set(LAG_KEYS) and "y_w" in jones.assumed
    assert "Jones" in jones.sources["y_w"]
    assert make_model("unsteady", jones).parameters["y_w"].value == jones.constants["y_w"]
    none = Aircraft.from_dict({**MINIMAL, "lag_constants": "none"})
    assert make_model("unsteady", none).parameters["F"].value == 0.0
    given = Aircraft.from_dict({**MINIMAL, "F": 1.0, "lag_constants": "jones"})
    assert given.constants["F"] == 1.0 and "F" not in given.lag_uncertainty  # given values win
    assert Aircraft.from_dict(given.to_dict()) == given  # the source round-trips
    for name in ("navion", "sundowner", "do128"):  # the presets give their constants
        assert make_model("unsteady", name).aircraft.lag_status == "aircraft file"
    with pytest.raises(AircraftError, match="lag_constants must be one of"):
        Aircraft.from_dict({**MINIMAL, "lag_constants": "wagner"})


@pytest.mark.parametrize(
    "argv",
    [
        ["fit", "{rec}", "--aircraft", "{ac}", "--model", "unsteady"],
        ["fit", "{rec}", "--aircraft", "{ac}"],  # unsteady by the model rule
        ["simulate", "--aircraft", "{ac}", "-o", "{tmp}/x.csv"],
        ["response", "--aircraft", "{ac}"],
        ["compare", "{rec}", "--aircraft", "{ac}"],
    ],
)
def test_every_command_refuses_unsteady_without_lags(argv, tmp_path, record_csv, capsys):
    ac = _aircraft_file(tmp_path)
    args = [a.format(rec=record_csv, ac=ac, tmp=tmp_path) for a in argv]
    code, _, err = run(capsys, *args)
    assert_refused_in_one_line(code, err, ["y_w", "lag_constants", "jones", "free"])


def test_the_chosen_source_is_recorded_in_the_result(tmp_path, record_csv, capsys):
    ac = _aircraft_file(tmp_path, lag_constants="jones")
    code, out, _ = run(capsys, "fit", record_csv, "--aircraft", ac, "--json")
    lag = json.loads(out)["provenance"]["lag_constants"]
    assert code in (0, 1) and lag["source"] == "jones"
    assert lag["constants"]["y_w"]["uncertainty"] > 0 and "Jones" in lag["constants"]["y_w"]["source"]
    # freeing a lag constant is a way out: it starts at Jones's value and is estimated
    code, out, _ = run(capsys, "fit", record_csv, "--aircraft", _aircraft_file(tmp_path), "--free", "G", "--json")
    res = json.loads(out)
    assert "G" in res["params"] and res["provenance"]["lag_constants"]["source"] == "jones"


# --- the evidence --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def comparison():
    rec = calib.periodic_record("unsteady", "3211", 0.02, np.random.default_rng(3))
    return compare_steady_unsteady(rec, "navion")


def test_loglik_contributions_sum_to_the_concentrated_likelihood(comparison):
    # sum_i v_i^H R^-1 v_i = N tr(R^-1 R) = N n, so sum_i l_i = -N ln det(pi R) - N n (Eqs. 20-25)
    for res in (comparison.steady, comparison.unsteady):
        ll = np.concatenate(loglik_contributions(res))
        n_out, N = len(res.outputs), ll.size
        q = comparison.fit_quality()[res.kind if res.kind == "unsteady" else "steady"]
        want = -N * (q["ln_det_R"] + n_out * math.log(math.pi)) - N * n_out
        assert ll.sum() == pytest.approx(want, rel=1e-6)  # fit's R vs the residuals' (R floor 1e-12)


def test_long_run_variance_of_an_ma1_process():
    # d_i = e_i + e_(i-1): gamma_0 = 2, gamma_1 = 1; Bartlett weight at lag 1 with span 20 is 0.95,
    # so the expectation is N (2 + 2 * 0.95) = 3.9 N.  The estimate's relative sd is about
    # sqrt(4 L / (3 N)) = 4 % at N = 20000, L = 20: 15 % is over 3.5 sd.
    e = np.random.default_rng(0).standard_normal(20_001)
    d = e[1:] + e[:-1]
    assert _long_run_variance(d - d.mean(), 20) / d.size == pytest.approx(3.9, rel=0.15)
    assert _long_run_variance(d, 1) == pytest.approx(float(d @ d))  # span 1: independent frequencies


def test_identical_fits_favour_neither(comparison):
    same = Comparison(steady=comparison.unsteady, unsteady=comparison.unsteady)
    assert (same.evidence.statistic, same.evidence.p_value, same.evidence.favoured) == (0.0, 1.0, "neither")


def test_comparison_round_trip_summary_and_plot(comparison):
    back = Comparison.from_dict(json.loads(json.dumps(comparison.to_dict())))
    assert back.evidence == comparison.evidence
    for name, shift in comparison.shifts.items():
        assert back.shifts[name] == pytest.approx(shift)
    text = comparison.summary()
    assert "evidence" in text and "ln det R" in text and text == comparison.table()
    damaged = json.loads(json.dumps(comparison.to_dict()))
    damaged["unsteady"]["values"] = "not a value"  # the fit's messages name the comparison and the key
    with pytest.raises(FdmlError, match=r"^saved c.json: unsteady: key 'values'"):
        Comparison.from_dict(damaged, source="saved c.json")
    with pytest.raises(FdmlError, match=r"^saved c.json: key 'format' is not 'fdml.Comparison'"):
        Comparison.from_dict({**comparison.to_dict(), "format": "fdml.FitResult"}, source="saved c.json")
    assert comparison.evidence.favoured == "unsteady"  # 2 % noise: far beyond the 90 % crossing
    assert comparison.unsteady.provenance["lag_constants"]["source"] == "aircraft file"  # the navion preset
    fig = comparison.plot()
    assert len(fig.axes) == 7
    import matplotlib.pyplot as plt

    plt.close(fig)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore")  # the misspecified unsteady fits warn, as they should
def test_false_alarms_on_steady_truth_records():
    # 24 independent periodic records (an implementation outside fdml) with a steady truth.
    # The two-sided 5 % test favours "unsteady" wrongly in at most 2.5 % nominally; even at
    # the 5 % the issue allows, P(X >= 4 | n = 24, p = 0.05) = 0.03, so 4 or more means a
    # false-alarm rate above 5 % with about 97 % confidence.
    hits = 0
    for i in range(24):
        maneuver = (*calib.INPUTS, "multisine-h")[i % 4]
        rec = calib.periodic_record("steady", maneuver, 0.05, np.random.default_rng(700 + i))
        hits += calib.verdict(rec, maneuver) == "unsteady"
    assert hits <= 3


@pytest.mark.filterwarnings("ignore")
def test_unsteady_truth_is_detected_at_low_noise():
    # Unsteady truth, 2 % noise: the benchmark found 40/40 records favouring "unsteady" for the
    # 3-2-1-1, the doublet and the multisine fitted on its harmonics (power near 1).  With 12
    # records, even a power of 0.99 gives P(X <= 9) = 2e-4: fewer than 10 means lost power.
    # (The multisine on the default 0.1 rad/s grid has almost none: most of that grid lies
    # between its harmonics; see benchmarks/compare_calibration.py.)
    hits = 0
    for i in range(12):
        maneuver = ("3211", "doublet", "multisine-h")[i % 3]
        rec = calib.periodic_record("unsteady", maneuver, 0.02, np.random.default_rng(900 + i))
        hits += calib.verdict(rec, maneuver) == "unsteady"
    assert hits >= 10


def test_demo_prints_the_evidence(tmp_path, capsys):
    code, out, _ = run(capsys, "demo", "-o", tmp_path / "demo", "--no-figure")
    assert code == 0 and "evidence: Vuong z" in out and "favoured" in out


# --- the command ---------------------------------------------------------------------------------
@pytest.mark.slow
def test_compare_json_and_files(tmp_path, record_csv, capsys):
    code, out, _ = run(capsys, "compare", record_csv, "--aircraft", "navion", "-o", tmp_path / "c", "--json")
    d = json.loads(out)
    assert code == 0 and set(d) >= {"steady", "unsteady", "shifts", "evidence"}
    _, fit_out, _ = run(capsys, "fit", record_csv, "--aircraft", "navion", "--json")
    assert set(d["unsteady"]) == set(json.loads(fit_out)) - {"timing"}  # the schema of fdml fit --json
    assert set(d["evidence"]) >= {"statistic", "p_value", "favoured"}
    assert set(d["shifts"]) == {"Cz_a", "Cz_q", "Cz_de", "Cm_a", "Cm_q", "Cm_de"}
    assert (tmp_path / "c" / "compare.png").stat().st_size > 10_000
    back = Comparison.from_dict(json.loads((tmp_path / "c" / "comparison.json").read_text()))
    assert back.evidence.favoured == d["evidence"]["favoured"]
    code, text, _ = run(capsys, "compare", record_csv, "--aircraft", "navion", "--steady", "steady")
    assert code == 0 and "evidence" in text and "Cm_q" in text


def test_compare_fits_theta_when_asked_as_fit_does(tmp_path, capsys):
    """``--outputs alpha,q,az,theta``: both fits take theta (the command transformed the records with
    the default rows and stopped at "the spectra hold alpha, q, az")."""
    truth = make_model("unsteady", "navion", outputs=("theta",))
    path = tmp_path / "theta.csv"
    simulate_maneuver(truth, "3211", duration=12.0, noise=0.02, seed=3).to_csv(path)
    code, out, err = run(capsys, "compare", path, "--aircraft", "navion", "--outputs", "alpha,q,az,theta", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["unsteady"]["outputs"] == d["steady"]["outputs"] == ["alpha", "q", "az", "theta"]


def test_compare_bad_input(tmp_path, record_csv, capsys):
    no_tail = {k: v for k, v in MINIMAL.items() if k != "S_t"}
    (tmp_path / "notail.json").write_text(json.dumps(no_tail))
    cases = [
        (["compare", record_csv, "--aircraft", tmp_path / "notail.json"], ["missing key", "S_t"]),
        (["compare", record_csv], ["--aircraft"]),
        (["compare", record_csv, "--aircraft", "navion", "--gust"], ["alpha_w", "--gust"]),
    ]
    for argv, expected in cases:
        code, _, err = run(capsys, *argv)
        assert_refused_in_one_line(code, err, expected)


def test_compare_refuses_records_of_two_aircraft(capsys):
    from fdml.io import data_path

    hfb, attas = data_path("hfb320/hfb320_1_10.asc"), data_path("attas/fAttasElv1.mat")
    code, _, err = run(capsys, "compare", hfb, attas, "--aircraft", "navion")
    assert_refused_in_one_line(code, err, ["mix aircraft", "HFB-320", "ATTAS"])
    totter = data_path("twin_otter/totter_lon_020213f1_017.mat")  # SIDPAC: no name, but its geometry differs
    code, _, err = run(capsys, "compare", totter, hfb, "--aircraft", "navion")
    assert_refused_in_one_line(code, err, ["mix aircraft", "S_w"])
