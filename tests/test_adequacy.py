"""Every fit checks its own adequacy (fdml.adequacy): score tests of the effect library, residual checks."""

import importlib.util
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import fdml
from fdml.adequacy import ALPHA, advice
from fdml.cli import main
from fdml.errors import AdequacyWarning, FdmlError
from fdml.io import data_path, load_record
from fdml.models import with_effects
from fdml.results import FitResult
from fdml.simulate import simulate_maneuver
from fdml.warning_log import RecordedWarning

HZ = 2 * math.pi
TO_BAND = (0.1 * HZ, 1.5 * HZ, 0.02 * HZ)  # the Twin Otter band, 0.1-1.5 Hz at 0.02 Hz
BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "adequacy_false_alarms.py"
NAVION = fdml.make_model("derivatives", "navion")
NOISE = {"alpha": 5e-4, "q": 1e-3, "az": 3e-3}
TAU = 0.04  # s: the withheld alpha-sensor delay, 4 samples at 100 Hz


def _twin_otter():
    try:
        return load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
    except (FdmlError, OSError):
        pytest.skip("Twin Otter data not available (set FDML_DATA)")


def _delayed_record(seed=3):
    """A 12 s 3-2-1-1 from the time-domain simulator with alpha delayed by TAU, shifted sample by sample."""
    dt = 0.01
    k = round(TAU / dt)
    sim = simulate_maneuver(
        NAVION, "3211", duration=12.0 + TAU, dt=dt, noise=NOISE, seed=seed, amplitude=math.radians(2.0)
    )
    n = sim.t.size - k
    sig = {name: sim[name][k:] for name in ("de", "q", "az")}
    sig["alpha"] = sim["alpha"][:n]  # alpha measured at t is the true alpha at t - TAU
    return fdml.Record(sim.t[:n], sig, name="delayed alpha", check_units=False)


@pytest.fixture(scope="module")
def delayed_fit():
    rec = _delayed_record()
    with pytest.warns(AdequacyWarning) as rec_w:
        res = fdml.fit(rec, NAVION)
    return rec, res, [str(w.message) for w in rec_w if issubclass(w.category, AdequacyWarning)]


def test_twin_otter_plain_fit_flags_the_alpha_delay():
    rec = _twin_otter()
    model = fdml.make_model("dimensional", airspeed=float(rec.meta["U"]))
    # named first, alone or as the best of a set the data cannot split: on this record the short-period
    # identity weighs the delay against a 1.4 m vane offset at its alias threshold (LRs 15.35 apart against
    # 15.4), so "the delay, or a vane offset" is as honest an answer as "the delay"
    with pytest.warns(AdequacyWarning, match=r"time_delay@alpha"):
        res = fdml.fit(rec, model, band=TO_BAND)
    assert res.adequacy.verdict.key == "time_delay@alpha"
    flagged = {e.key: e for e in res.adequacy.flagged}
    assert "time_delay@alpha" in flagged
    e = flagged["time_delay@alpha"]
    assert e.p_holm < ALPHA and e.channel == "alpha"
    # issue 8: refitted with the delay, tau = 21.6 ms on this record; the one-step estimate is a
    # linearisation from tau = 0 (and the score statistic weights with the null's inflated R), so it
    # falls short of the refit; 10-30 ms brackets it without admitting a sign or order-of-magnitude error
    assert 0.010 < e.expected["tau_alpha"] < 0.030


def test_withheld_alpha_delay_is_flagged_with_a_plausible_value(delayed_fit):
    _, res, msgs = delayed_fit
    a = res.adequacy
    assert a.flagged and a.flagged[0].key == "time_delay@alpha"
    tau = a.flagged[0].expected["tau_alpha"]
    # one Gauss-Newton step from 0: the phase -omega tau is linearised (error ~ (omega tau)^2 / 6, < 3 % at
    # 10 rad/s) and the base parameters absorb part of it; 30-50 ms is +-25 % of the 40 ms simulated
    assert 0.030 < tau < 0.050
    assert any("time_delay@alpha" in m and "--effect time_delay:alpha" in m for m in msgs)
    assert res.warnings[-1] == RecordedWarning("AdequacyWarning", msgs[-1])  # kept in the result, as every warning


def test_refit_with_the_flagged_effect_is_adequate(delayed_fit):
    rec, _, _ = delayed_fit
    with warnings.catch_warnings():
        warnings.simplefilter("error", AdequacyWarning)
        res = fdml.fit(rec, with_effects(NAVION, "time_delay:alpha"))
    assert res.adequacy.adequate
    assert "time_delay@alpha" not in {e.key for e in res.adequacy.effects}  # already in the model
    assert abs(res["tau_alpha"] - TAU) < 4 * res.errors["tau_alpha"]


def test_json_round_trip_and_validation(delayed_fit):
    _, res, _ = delayed_fit
    back = FitResult.from_dict(json.loads(res.to_json()))
    assert back.adequacy == res.adequacy
    d = json.loads(res.to_json())
    d["adequacy"]["effects"][0]["p_holm"] = "small"
    with pytest.raises(FdmlError, match=r"adequacy\.effects\[0\]\.p_holm"):
        FitResult.from_dict(d)
    del d["adequacy"]  # results saved before the check existed still load
    assert FitResult.from_dict(d).adequacy is None


def test_summary_section(delayed_fit):
    _, res, _ = delayed_fit
    text = str(res.summary())
    assert "adequacy:" in text and "FLAGGED time_delay@alpha" in text
    quiet = fdml.fit(simulate_maneuver(NAVION, "3211", duration=12.0, noise=NOISE, seed=11), NAVION)
    assert quiet.adequacy.adequate and "nothing flagged" in str(quiet.summary())


def test_adequacy_false_skips_the_check(delayed_fit):
    rec, _, _ = delayed_fit
    with warnings.catch_warnings():
        warnings.simplefilter("error", AdequacyWarning)
        res = fdml.fit(rec, NAVION, adequacy=False)
    assert res.adequacy is None and "adequacy:" not in str(res.summary())


def test_cli_json_and_the_quoted_command(tmp_path, capsys, delayed_fit):
    rec, _, _ = delayed_fit
    path = rec.to_csv(tmp_path / "delayed.csv")
    assert main(["fit", str(path), "--model", "derivatives", "--aircraft", "navion", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["adequacy"]["adequate"] is False
    assert out["adequacy"]["flagged"][0]["key"] == "time_delay@alpha"
    assert out["adequacy"]["flagged"][0]["expected"]["tau_alpha"] > 0
    # the result's warning quotes the running command with --effect added, and the diagnosis of the same records
    (msg,) = [w["message"] for w in out["warnings"] if w["category"] == "AdequacyWarning"]
    assert f"fdml fit {path} --aircraft navion --model derivatives --effect time_delay:alpha" in msg, msg
    assert f"fdml diagnose {path} --aircraft navion --model derivatives" in msg, msg
    # the advice is a function of its arguments: the library's fit gives the generic command and the Python call
    generic = advice(delayed_fit[1].adequacy)
    assert "fdml fit RECORD ... --effect time_delay:alpha" in generic and "fdml.diagnose.diagnose" in generic
    quoted = advice(
        delayed_fit[1].adequacy, fit_argv=["fdml", "fit", "r.csv"], diagnose_argv=["fdml", "diagnose", "r.csv"]
    )
    assert "fdml fit r.csv --effect time_delay:alpha" in quoted and "fdml diagnose r.csv" in quoted


def _bench():
    spec = importlib.util.spec_from_file_location("adequacy_false_alarms", BENCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.slow
def test_false_alarm_rate_is_consistent_with_the_level():
    """60 time-domain records from the fitted model (benchmarks/adequacy_false_alarms.py has 500+).

    At the stated family level 0.01, P(Binomial(60, 0.01) >= 5) = 3.7e-4: the test fails by chance with
    probability below 0.001 when the check holds its level.
    """
    bench = _bench()
    model, band = bench.truth_model()
    flags = [bench.one((model, band, 10_000 + i))[0] for i in range(60)]
    checked = [f for f in flags if f is not None]
    assert len(checked) >= 55
    alarms = sum(1 for f in checked if f)
    limit = int(stats.binom.isf(1e-3, len(checked), ALPHA))  # largest count with P(X > limit) <= 1e-3
    assert alarms <= limit, f"{alarms} false alarms in {len(checked)} records (allowed {limit})"


def test_clopper_pearson_matches_the_closed_form_for_zero_successes():
    # k = 0: the upper bound solves (1 - p)^n = alpha/2 (closed form)
    lo, hi = _bench().clopper_pearson(0, 500)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / 500), rel=1e-9)
    assert np.isfinite(hi)
