"""fdml.diagnose statistics: multiple-testing corrections, null distributions, calibration by simulation."""

import math

import numpy as np
import pytest
from scipy import stats

import fdml
from fdml.diagnose.attribute import davies_bound, p_value
from fdml.diagnose.data import analysis_data
from fdml.diagnose.disturbance import gust_test
from fdml.diagnose.likelihood import fit_model, likelihood_ratio, noise_bands
from fdml.diagnose.locate import bh, default_bands, forced_response, gap_map, holm
from fdml.diagnose.truth import simulate_truth
from fdml.models.effects import get_effect
from fdml.score import LR_EQUAL, equally

BAND = (0.3, 12.0)


def test_holm_and_bh_by_hand():
    p = np.array([0.01, 0.04, 0.03, 0.005, np.nan])
    # Holm: sorted 0.005, 0.01, 0.03, 0.04 -> x4, x3, x2, x1, running max
    assert np.allclose(holm(p)[:4], [0.03, 0.06, 0.06, 0.02])
    assert np.isnan(holm(p)[4])
    # BH: 0.005*4/1=0.02, 0.01*4/2=0.02, 0.03*4/3=0.04, 0.04*4/4=0.04
    assert np.allclose(bh(p)[:4], [0.02, 0.04, 0.04, 0.02])


def test_chibar_square_halves_the_chi2_tail():
    # one parameter on the boundary of its range (a delay >= 0): 0.5 chi2_0 + 0.5 chi2_1
    p, lp = p_value(3.84, 1, "chibar")
    assert p == pytest.approx(0.5 * stats.chi2.sf(3.84, 1), rel=1e-12)
    assert lp == pytest.approx(math.log(p), rel=1e-12)
    assert p_value(0.0, 1, "chibar")[0] == 1.0
    assert p_value(3.84, 1, "chi2")[0] == pytest.approx(stats.chi2.sf(3.84, 1))


def test_davies_bound_sits_between_chi2_and_bonferroni():
    u, q = 20.0, 2
    single = stats.chi2.sf(u, q)
    assert davies_bound(u, q, 0.0) == pytest.approx(single, rel=1e-9)  # a flat profile: no search penalty
    b = davies_bound(u, q, V=5.0)
    assert single < b < 30 * single
    assert davies_bound(u + 5, q, 5.0) < b  # decreasing in u
    p, _ = p_value(u, q, "davies", V=500.0, n_grid=30)  # a rough profile: Bonferroni over the grid caps it
    assert p == pytest.approx(30 * single, rel=1e-9)


def test_equally_is_the_lr_difference_within_its_own_sampling_spread():
    assert equally(100.0, 100.0 - 15.0) and not equally(100.0, 100.0 - 16.0)
    assert LR_EQUAL == pytest.approx((2 * 1.959964) ** 2)


@pytest.mark.slow
def test_the_lr_difference_scatters_within_its_stated_spread():
    """The rule's premise, by Monte Carlo: against a common base, the LR of the true effect minus the
    LR of a near alias scatters with a standard deviation of at most 2 sqrt(mean difference) (the
    noise's share with the predictions held; the refits absorb part of it, so it is an upper bound).
    20 records of a 20 ms alpha lag at 6 % noise, against the same lag put on alpha and a_z together."""
    base = fdml.make_model("dimensional", "navion")
    d = []
    for seed in range(20):
        rec = simulate_truth(base, "time_delay@alpha", {"tau_alpha": 0.02}, noise=0.06, seed=900 + seed, duration=12)
        data = analysis_data(rec, BAND)
        nb = noise_bands(data)
        f0 = fit_model(data, base, nb)
        fa = fit_model(data, get_effect("time_delay@alpha").augment(f0.model), nb, start={"tau_alpha": 0.02})
        fb = fit_model(data, get_effect("time_delay@alpha,az").augment(f0.model), nb, start={"tau_alpha_az": 0.02})
        d.append(2.0 * (fb.cost - fa.cost) / data.oversample)  # LR_a - LR_b (each LR = 2 (C0 - C1) / K)
    d = np.array(d)
    assert d.mean() > 0  # the truth explains more
    # the sample standard deviation of 20 draws lies within 0.68-1.32 of the true one with 95 %
    # probability: the bound must hold with that margin
    assert d.std(ddof=1) < 1.32 * 2 * np.sqrt(d.mean())


@pytest.fixture(scope="module")
def null_runs():
    """24 no-effect records (3-2-1-1, 5 % white noise): base fits, one nested refit each, gap maps."""
    base = fdml.make_model("steady", "navion")
    eff = get_effect("sensor_scale@q")
    out = []
    for seed in range(24):
        rec = simulate_truth(base, None, {}, maneuver="3211", noise=0.05, seed=10_000 + seed)
        data = analysis_data(rec, BAND)
        nb = noise_bands(data)
        f0 = fit_model(data, base, nb)
        f1 = fit_model(data, eff.augment(f0.model), nb)
        gm = gap_map(data, f0.full_residual(), forced_response(data, f0.model), default_bands(data))
        out.append((data, f0, f1, gm))
    return out


@pytest.mark.slow
def test_likelihood_ratio_null_distribution_counts_independent_frequencies(null_runs):
    # Interior one-parameter candidate on no-effect records: LR ~ chi2(1), mean 1, var 2.  Over 24
    # runs the mean has standard error sqrt(2/24) = 0.29; accept 1 +- 0.6 (about 2 s.e.).
    lr = np.array([likelihood_ratio(f0.cost, f1.cost, d.oversample) for d, f0, f1, _ in null_runs])
    assert 0.4 < lr.mean() < 1.6
    # Counting the 2x oversampled grid as independent doubles it (THEORY.md 7): the correction matters
    raw = np.array([2 * (f0.cost - f1.cost) for _, f0, f1, _ in null_runs])
    assert raw.mean() > 1.5 * lr.mean()


def test_gap_map_does_not_light_up_on_noise(null_runs):
    # Cell p-values under no model error: at most the nominal 5 % below 0.05 (+ 2 binomial s.e. for
    # 144 cells = 0.036); the F test ignores the fit's leverage, so it is conservative.
    p = np.array([c.p for *_, gm in null_runs for c in gm.cells if c.p is not None])
    assert p.size >= 100
    assert np.mean(p < 0.05) <= 0.05 + 2 * math.sqrt(0.05 * 0.95 / p.size)
    flagged = sum(1 for *_, gm in null_runs if gm.flagged())
    # family-wise (Holm) 5 % per record: P(>= 4 of 24 records) = 0.03 under the nominal rate
    assert flagged <= 3


def test_noise_floor_is_per_band_not_flat():
    # DIAGNOSIS.md 2.6 rule 1.  Coloured sensor noise (16x the white level at low frequency): the gap
    # map's floor must follow it band by band (relative to the white case, the lowest band's floor
    # rises more than the highest band's), and the likelihood must use several noise bands.
    base = fdml.make_model("steady", "navion")
    ratio = []
    for kind in ("white", "coloured"):
        rec = simulate_truth(base, None, {}, maneuver="multisine", duration=40.0, noise=0.05, noise_kind=kind, seed=42)
        data = analysis_data(rec, BAND)
        nb = noise_bands(data)
        assert nb.n >= 2
        f0 = fit_model(data, base, nb)
        gm = gap_map(data, f0.full_residual(), forced_response(data, f0.model), np.array([0.3, 1.0, 4.0, 12.0]))
        q = [gm.cell("q", b).floor for b in range(3)]
        ratio.append(q[0] / q[2])
    assert ratio[1] > 3 * ratio[0]


@pytest.mark.slow
def test_turbulence_test_is_calibrated_on_coloured_sensor_noise():
    # DIAGNOSIS.md 2.6 rules 1-2: independent coloured sensor noise must not look like turbulence
    # (a flat residual-based noise model gave 87 % false turbulence calls in the prototype).  20 records:
    # P(>= 4 false alarms at p < 0.05) = 0.016 under the nominal rate.
    base = fdml.make_model("steady", "navion")
    hits = 0
    for seed in range(20):
        rec = simulate_truth(base, None, {}, maneuver="doublet", noise=0.05, noise_kind="coloured", seed=20_000 + seed)
        data = analysis_data(rec, BAND)
        f0 = fit_model(data, base, noise_bands(data))
        hits += gust_test(data, f0, default_bands(data)).p < 0.05
    assert hits <= 3


def test_turbulence_test_finds_unmeasured_gust_and_its_size():
    base = fdml.make_model("steady", "navion")
    rec = simulate_truth(base, "unmeasured_gust", {"sigma_w": 0.5}, maneuver="3211", noise=0.03, seed=8)
    data = analysis_data(rec, BAND)
    f0 = fit_model(data, base, noise_bands(data))
    g = gust_test(data, f0, default_bands(data))
    assert g.p < 1e-6
    # sigma_w against the gust RMS realised in the 20-s window (Dryden's correlation time L/U ~ 10 s
    # makes that differ from the nominal 0.5): within 4 standard errors plus 10 % for the Dryden
    # shape's length scale, which the test assumes
    real = rec.meta["gust_rms_in_record"]
    assert abs(g.sigma_w - real) < 4 * g.sigma_w_se + 0.1 * real
