"""fdml.design: inputs within limits, predicted bounds against Monte Carlo, discrimination power."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import stats

from fdml import fit
from fdml import maneuvers as mv
from fdml.design import (
    Design,
    Limits,
    classic_input,
    design,
    detection_probability,
    discriminate,
    minimum_detectable,
    multisine_input,
    predict,
    read_input,
)
from fdml.design.discrimination import _best_match, noncentrality, required_noncentrality
from fdml.design.prediction import noise_stds, response
from fdml.errors import BandError, FdmlError, ParameterError
from fdml.estimate import prepare
from fdml.models import make_model, with_effects
from fdml.record import add_noise

LIM = Limits(amplitude=math.radians(1.0), duration=12.0, dt=0.02)


# --- generators -------------------------------------------------------------------------------
def test_schroeder_phases_flat_closed_form():
    K = 17
    k = np.arange(1, K + 1)
    assert np.allclose(mv.schroeder_phases(np.ones(K)), -np.pi * k * (k - 1) / K, atol=1e-12)


def test_min_crest_keeps_spectrum_and_lowers_crest_factor():
    t = mv.time_vector(20.0, 0.02)
    a = np.linspace(1.0, 0.3, mv.multisine_frequencies(t, 0.5, 15.0).size)
    sch = mv.multisine(t, 1.0, 0.5, 15.0, phases="schroeder", amplitudes=a, zero_start=False)
    low = mv.multisine(t, 1.0, 0.5, 15.0, phases="min-crest", amplitudes=a, zero_start=False)
    assert mv.crest_factor(low) < mv.crest_factor(sch) - 0.1
    # the amplitude spectrum over one period is the one asked for (DFT bins of the harmonics)
    k = np.round(mv.multisine_frequencies(t, 0.5, 15.0) * 20.0 / (2 * np.pi)).astype(int)
    mag = np.abs(np.fft.rfft(low[:-1]))[k]
    assert np.allclose(mag / mag[0], a / a[0], rtol=1e-9)


def test_two_inputs_have_orthogonal_harmonics():
    inp = multisine_input(LIM, (0.5, 10.0), second="alpha_w")
    de, aw = inp.signals["de"][:-1], inp.signals["alpha_w"][:-1]  # one period
    assert abs(de @ aw) < 1e-10 * np.linalg.norm(de) * np.linalg.norm(aw)
    assert not set(inp.options["harmonics"]) & set(inp.options["second_harmonics"])


@pytest.mark.parametrize("kind", ["linear", "log"])
def test_sweep_covers_its_band(kind):
    t = mv.time_vector(20.0, 0.01)
    lo, hi = 1.0, 12.0
    u = mv.sweep(t, 1.0, lo, hi, kind=kind, taper=0.0)
    # zero crossings of sin(phase): phase(T) / pi, with phase(T) = T (lo + hi) / 2 (linear)
    # or T (hi - lo) / ln(hi / lo) (log)
    total = 20.0 * ((lo + hi) / 2 if kind == "linear" else (hi - lo) / math.log(hi / lo))
    crossings = np.count_nonzero(np.diff(np.signbit(u[1:])))
    assert abs(crossings - total / np.pi) <= 2
    assert u[0] == 0.0 and np.max(np.abs(u)) <= 1.0


def test_rate_limit_respected_and_reported():
    lim = Limits(amplitude=math.radians(3.0), duration=12.0, dt=0.02, rate=math.radians(15.0))
    for kind in ("doublet", "3211", "sweep", "min-crest"):
        rep = classic_input(kind, lim, (0.5, 10.0)).report()
        assert rep["within_limits"], (kind, rep)
        assert rep["rate"] <= lim.rate * (1 + 1e-6)
    ms = classic_input("min-crest", lim, (0.5, 10.0))
    # a 3 deg multisine up to 10 rad/s moves faster than 15 deg/s: it is scaled below 3 deg
    assert ms.options["amplitude_fraction"] < 1.0
    assert ms.report()["peak"] == pytest.approx(3.0 * math.pi / 180 * ms.options["amplitude_fraction"], rel=1e-9)


def test_limits_no_input_can_meet():
    lim = Limits(amplitude=math.radians(3.0), duration=12.0, dt=0.02, rate=math.radians(1.0))
    with pytest.raises(ParameterError, match="rate limit"):
        classic_input("3211", lim)
    with pytest.raises(ParameterError, match="longer than"):
        classic_input("3211", Limits(amplitude=0.01, duration=5.0), unit=1.0)
    with pytest.raises(BandError, match="Nyquist"):
        classic_input("sweep", LIM, (0.5, 200.0))


def test_input_csv_round_trip(tmp_path):
    inp = classic_input("3211", LIM)
    inp.to_csv(tmp_path / "card.csv")
    assert (tmp_path / "card.csv").read_text().splitlines()[0] == "t,de"
    back = read_input(tmp_path / "card.csv")
    assert np.allclose(back.de, inp.de, rtol=0, atol=1e-15)


# --- prediction against Monte Carlo -----------------------------------------------------------
#: Trials per case; the scatter of an estimated std over N trials is chi: (N-1) s^2 / sigma^2 ~ chi2(N-1).
N_TRIALS = 30
#: Two-sided probability of a false failure per parameter (20 comparisons: ~2 % per run).
ALPHA = 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["unsteady", "steady"])
@pytest.mark.parametrize("inp_kind", ["3211", "min-crest"])
def test_predicted_stderr_matches_monte_carlo(kind, inp_kind):
    model = make_model(kind, "navion")
    inp = classic_input(inp_kind, LIM, (0.5, 10.0))
    pred = predict(model, inp, noise=0.05)
    rec = response(model, inp)
    rng = np.random.default_rng(11)
    names = list(pred.to_dict())
    est = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(N_TRIALS):
            res = fit(add_noise(rec, pred.noise, rng), model, adequacy=False, check=False)
            est.append([res.params[n] for n in names])
    s = np.std(np.array(est), axis=0, ddof=1)
    ratio = s / np.array([pred.stderr[n] for n in names])
    df = N_TRIALS - 1
    lo, hi = (math.sqrt(stats.chi2.ppf(q, df) / df) for q in (ALPHA / 2, 1 - ALPHA / 2))
    assert np.all((ratio > lo) & (ratio < hi)), dict(zip(names, ratio.round(3)))


def test_prediction_scales_with_noise_and_amplitude():
    """Linear model, white noise: stderr proportional to noise std / input amplitude."""
    model = make_model("steady", "navion")
    a = predict(model, classic_input("3211", LIM), noise={"alpha": 1e-4, "q": 1e-4, "az": 1e-3})
    big = Limits(amplitude=2 * LIM.amplitude, duration=LIM.duration, dt=LIM.dt)
    b = predict(model, classic_input("3211", big), noise={"alpha": 2e-4, "q": 2e-4, "az": 2e-3})
    for n in a.to_dict():
        assert b.stderr[n] == pytest.approx(a.stderr[n], rel=1e-6)


# --- discrimination ---------------------------------------------------------------------------
def test_detection_probability_closed_form():
    # ncx2 with 1 dof is (sqrt(lam) + Z)^2: P = Phi(sqrt(lam) - z) + Phi(-sqrt(lam) - z), z = z_(1-a/2)
    for lam in (0.5, 4.0, 13.0):
        z = stats.norm.isf(0.025)
        r = math.sqrt(lam)
        assert detection_probability(lam, 0.05) == pytest.approx(stats.norm.cdf(r - z) + stats.norm.cdf(-r - z))
    assert detection_probability(required_noncentrality(0.9, 0.05), 0.05) == pytest.approx(0.9, abs=1e-8)


def _q(prob, stds):
    sig = np.array([stds[k] for k in ("alpha", "q", "az")])
    g = np.concatenate([d.noise_gain(include_trim=False) for d in prob.data])
    return np.diag(1.0 / (sig**2 * g.mean()))


def test_noncentrality_is_the_mean_likelihood_ratio():
    """Mean of Q_steady - Q_unsteady over noisy unsteady records: lambda, scatter sqrt(4 lambda) (LR ~ N(l, 4l))."""
    mu, ms = make_model("unsteady", "navion"), make_model("steady", "navion")
    inp = classic_input("3211", LIM)
    d = discriminate(mu, ms, inp, noise=0.2)
    rec = response(mu, inp)
    stds = noise_stds(rec, 0.2)
    rng = np.random.default_rng(5)
    n = 50
    lr = []
    for _ in range(n):
        noisy = add_noise(rec, stds, rng)
        q = []
        for m in (ms, mu):
            prob = prepare(noisy, m)
            S = _q(prob, stds)
            q.append(noncentrality(prob, _best_match(prob, S), S))
        lr.append(q[0] - q[1])
    sd = math.sqrt(4 * d.noncentrality)
    assert abs(np.mean(lr) - d.noncentrality) < 4 * sd / math.sqrt(n)  # 4 sigma of the mean
    assert 0.6 < np.std(lr, ddof=1) / sd < 1.5  # chi(49) scatter of a std is ~10 %; model curvature adds a little


def test_noncentrality_scales_with_inverse_noise_variance():
    mu, ms = make_model("unsteady", "navion"), make_model("steady", "navion")
    inp = classic_input("doublet", LIM)
    a = discriminate(mu, ms, inp, noise=0.05).noncentrality
    b = discriminate(mu, ms, inp, noise=0.1).noncentrality
    assert b == pytest.approx(a / 4, rel=1e-6)


def test_minimum_detectable_delay_is_detected_at_the_stated_power():
    """A truth with the minimum detectable delay: the nonlinear lambda of the model without it is lambda_req."""
    base = make_model("derivatives", "navion")
    inp = classic_input("3211", LIM)
    (det,) = minimum_detectable(base, "time_delay:alpha", inp, noise=0.05, power=0.9)
    assert det.parameter == "tau_alpha"
    truth = with_effects(base, ["time_delay:alpha"]).with_values({"tau_alpha": det.minimum})
    rec = response(base, inp)
    stds = noise_stds(rec, 0.05)  # the same sensor as the prediction
    lam = discriminate(truth, base, inp, noise=stds).noncentrality
    # the predicted stderr is the fit's bound, whose variance carries the factor n_eff / (n_eff - n_out)
    # of an estimated R (fdml.estimate.white_covariance); the nonlinear lambda is for known noise
    n_eff = (10.0 - 0.1) * LIM.duration / (2 * math.pi) + 1.0  # default band 0.1:10, independent frequencies
    expected = required_noncentrality(0.9, 0.05) * n_eff / (n_eff - 3)
    assert lam == pytest.approx(expected, rel=0.05)  # local (Fisher) against nonlinear: the delay's curvature


@pytest.mark.slow
def test_design_gains_over_3211():
    d = design(make_model("unsteady", "navion"), criterion="d-optimal", duration=12.0, band="0.5:10", refine=6)
    assert set(d.baselines) == {"3211", "sweep"}
    g = d.gains()["3211"]
    assert np.exp(np.mean(np.log(list(g.values())))) > 1.0  # the design beats the 3-2-1-1 on average
    assert d.discrimination["3211"].noncentrality > 0


def test_design_refusals():
    mu = make_model("unsteady", "navion")
    with pytest.raises(FdmlError, match="fixed"):
        design(mu, criterion="a-optimal", targets=["F"], duration=12.0)
    with pytest.raises(FdmlError, match="not in the"):
        design(mu, criterion="a-optimal", targets=["nope"], duration=12.0)
    with pytest.raises(FdmlError, match="unsteady model"):
        design(make_model("steady", "navion"), criterion="discriminate", duration=12.0)
    with pytest.raises(BandError, match="Nyquist"):
        design(mu, band="0.5:200", duration=12.0)


@pytest.mark.parametrize(
    "band, message",
    [
        ("10:0.5", "hi = 0.5 rad/s is below lo = 10 rad/s"),
        ("0.5:10:0", "step = 0 rad/s must be positive"),
        ("0:10", "lo = 0 rad/s must be positive"),
        ("0.5:10:0.1:1", "must be LO:HI[:STEP] in rad/s"),
        ("0.5:200", "band edge 200 rad/s is not below the Nyquist frequency pi/dt = 157.1 rad/s"),
    ],
)
def test_the_design_parses_bands_with_the_one_band_parser(band, message):
    """Issue 22: design() and the input generators refuse a band with fdml.spectral.parse_band's messages."""
    mu = make_model("unsteady", "navion")
    for call in (lambda: design(mu, band=band, duration=12.0), lambda: classic_input("sweep", LIM, band)):
        with pytest.raises(BandError) as exc:
            call()
        assert message in str(exc.value)


def test_an_input_band_may_be_written_lo_hi():
    assert np.array_equal(classic_input("sweep", LIM, "0.5:10").de, classic_input("sweep", LIM, (0.5, 10.0)).de)


@pytest.mark.slow
def test_discrimination_design_beats_the_classic_inputs():
    """Navion, 12 s, 1 deg, noise 10 % of the 3-2-1-1 response: a larger lambda than a 3-2-1-1 and a sweep."""
    d = design(
        make_model("unsteady", "navion"), criterion="discriminate", duration=12.0, band="0.5:10", noise=0.1, refine=20
    )
    lam = {k: v.noncentrality for k, v in d.discrimination.items()}
    assert lam[d.input.name] > max(lam["3211"], lam["sweep"]), lam
    assert d.input.report()["within_limits"]


@pytest.mark.slow
def test_a_optimal_design_names_its_targets():
    d = design(make_model("unsteady", "navion"), criterion="a-optimal", targets=["Cm_de"], duration=12.0, refine=4)
    assert d.criterion == "a-optimal" and "Cm_de" in d.predicted.to_dict()


# --- what the table says: placeholders, whole input names, units (issue 21) ----------------------
PARTIAL = {
    "name": "partial",
    **{k: v for k, v in make_model("steady", "navion").aircraft.to_dict().items() if k not in ("sources", "assumed")},
}
for _k in ("CLa_t", "deps_da", "Cz_de", "y_w", "z_w", "y_t", "z_t", "F", "G", "H", "b1"):
    PARTIAL.pop(_k, None)  # the file gives CLa_w and Cm_de only


def test_placeholders_are_the_values_nobody_gave():
    from fdml.aircraft import GENERIC_CONSTANTS, Aircraft

    ac = Aircraft.from_dict(PARTIAL)
    steady = make_model("steady", ac)
    assert set(steady.placeholders()) == {"CLa_t", "deps_da", "Cz_de"}
    for k, why in steady.placeholders().items():
        assert steady.parameters[k].value == GENERIC_CONSTANTS[k] and f"{GENERIC_CONSTANTS[k]:g}" in why
    assert set(steady.with_values({"CLa_t": 3.9}).placeholders()) == {"deps_da", "Cz_de"}  # --set gives it
    assert set(with_effects(steady, "time_delay:alpha").placeholders()) == set(steady.placeholders())
    # the quasi-steady derivatives built from a placeholder are placeholders too; Cm_de is given
    assert set(make_model("derivatives", ac).placeholders()) == {"Cz_a", "Cz_q", "Cz_de", "Cm_a", "Cm_q"}
    assert set(make_model("dimensional", airspeed=50.0).placeholders()) == {"Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de"}
    assert make_model("steady", "navion").placeholders() == {}  # the preset gives every constant


def test_design_table_marks_placeholders_names_inputs_whole_and_gives_units():
    from fdml.aircraft import Aircraft

    d = design(
        make_model("steady", Aircraft.from_dict(PARTIAL)),
        duration=6.0,
        dt=0.05,
        band="0.5:8",
        refine=0,
        detect=["time_delay:alpha"],
    )
    text = d.table()
    lines = text.splitlines()
    for name in [d.input.name, *d.baselines]:
        assert f" {name}" in lines[0], (name, lines[0])  # "d-optimal multisine", not "d-optimal multisin"
    rows = {line.split()[0]: line for line in lines[2 : 2 + len(d.predicted.to_dict())]}
    for k, row in rows.items():
        assert (f"{d.predicted.values[k]:.4g}*" in row) == (k in ("CLa_t", "deps_da", "Cz_de")), row
    note = text.split("* placeholder")[1].split("\n\n")[0]
    assert all(k in note for k in ("CLa_t", "deps_da", "Cz_de")) and "CLa_w" not in note
    (det,) = d.detectable
    assert det.unit == "s" and f"{det.minimum:.4g} s" in text
    back = Design.from_dict(d.to_dict(), input=d.input)
    assert back.placeholders == d.placeholders and back.detectable[0].unit == "s"
