"""The short-period identity (fdml.kinematics) on records where it holds exactly by construction.

The references are independent of fdml's models: alpha and q are sums of sines with random
amplitudes and phases, a_z is written from docs/theory.md Eq. 5, ``a_z = (U/g)(alpha_dot - q)``,
differentiated by hand, and the sensor errors are applied to the analytic signals (a lag as an
exact shift of the sines, a vane offset as ``alpha - d q/U``, a scale as a factor).  No dynamics
are involved: the identity holds whatever the aerodynamics, and so do these tests.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fdml.constants import G0
from fdml.kinematics import (
    LEVEL,
    SensorTerms,
    kinematic_evidence,
    resolution,
    sensor_terms,
)
from fdml.models.effects import get_effect
from fdml.record import Record
from fdml.spectral import spectra

U = 60.0  # m/s
DT = 0.02
T = 16.0
OMEGAS = np.array([0.6, 1.1, 1.9, 2.7, 3.6, 4.8, 6.1, 7.7, 9.4])  # rad/s


def _record(seed, *, lags=(0.0, 0.0, 0.0), offset=0.0, scales=(1.0, 1.0, 1.0), noise=0.01, dt=DT):
    """alpha, q, a_z obeying Eq. 5 at one station, then measured with the given sensor errors.

    ``offset``: the vane ``offset`` metres ahead of the accelerometer, alpha_vane = alpha - d q/U.
    Noise: a fraction of each channel's RMS, white.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T + 1e-9, dt)
    a_amp = rng.uniform(0.002, 0.01, OMEGAS.size) / (1 + OMEGAS / 4)
    q_amp = rng.uniform(0.004, 0.02, OMEGAS.size) / (1 + OMEGAS / 6)
    pa, pq = rng.uniform(0, 2 * np.pi, (2, OMEGAS.size))

    def alpha(tt):
        return np.sum(a_amp * np.sin(OMEGAS * tt[:, None] + pa), axis=1)

    def alpha_dot(tt):
        return np.sum(a_amp * OMEGAS * np.cos(OMEGAS * tt[:, None] + pa), axis=1)

    def q(tt):
        return np.sum(q_amp * np.sin(OMEGAS * tt[:, None] + pq), axis=1)

    def az(tt):
        return U / G0 * (alpha_dot(tt) - q(tt))  # Eq. 5

    la, lq, lz = lags
    sig = {
        "alpha": scales[0] * (alpha(t - la) - offset * q(t - la) / U),
        "q": scales[1] * q(t - lq),
        "az": scales[2] * az(t - lz),
        "de": 0.01 * np.sin(2.0 * t),
    }
    for k in ("alpha", "q", "az"):
        sig[k] = sig[k] + noise * np.std(sig[k]) * rng.standard_normal(t.size)
    return Record(t, sig, name=f"identity-{seed}", check_units=False)


def _evidence(rec, **kw):
    return kinematic_evidence([spectra(rec, band=(0.3, 10.0, 0.05), trim="first")], U, **kw)


# --- the mapping from library effects to sensor terms --------------------------------------------------------------


def test_sensor_terms_of_the_library():
    assert sensor_terms(get_effect("time_delay@alpha,az"), {"tau_alpha_az": 0.1}).lags == (0.1, 0.0, 0.1)
    assert sensor_terms(get_effect("time_delay@q"), {"tau_q": 0.04}).lags == (0.0, 0.04, 0.0)
    # a vane x ahead and an accelerometer x behind are one and the same to the three outputs
    vane = sensor_terms(get_effect("sensor_offset@alpha"), {"x_alpha": 2.0})
    accel = sensor_terms(get_effect("sensor_offset@az"), {"x_az": -2.0})
    assert vane == accel == SensorTerms(offset=2.0)
    assert sensor_terms(get_effect("sensor_scale@q"), {"k_q": 0.1}).scales == (1.0, 1.1, 1.0)
    # common to every output: invisible to the identity
    assert sensor_terms(get_effect("time_delay@de"), {"tau_de": 0.05}).empty
    assert sensor_terms(get_effect("actuator_lag@de"), {"T_act": 0.05}).empty
    assert sensor_terms(get_effect("lift_lag@alpha"), {"y_w": 0.2}) is None


def test_resolution_is_a_quarter_sample():
    assert resolution("s", 0.02, 50.0) == pytest.approx(0.005)
    assert resolution("m", 0.02, 50.0) == pytest.approx(0.25)  # x/U = a quarter sample
    assert resolution("-", 0.02, 50.0) == 0.005
    assert resolution("rad", 0.02, 50.0) is None


# --- what the identity finds -------------------------------------------------------------------------------------


def test_clean_records_settle_nothing():
    """Ten patterns tested at LEVEL = 1e-3 each: about 1 % of clean records show one.  Of 20, three or
    more would happen with probability below 1e-3 if that held (binomial)."""
    fired = 0
    for seed in range(20):
        ev = _evidence(_record(seed))
        fired += bool(ev.settled or ev.aliases)
    assert fired <= 2


@pytest.mark.slow
def test_an_alpha_lag_is_settled_and_its_standard_error_is_honest():
    """30 ms on alpha: settled as time_delay@alpha; over 30 records the scatter of the estimates
    matches the reported standard error (ratio within 0.6-1.6: the 95 % range of a standard
    deviation estimated from 30 draws is 0.75-1.25, widened for the curvature-based error)."""
    est, ses = [], []
    for seed in range(30):
        ev = _evidence(_record(100 + seed, lags=(0.03, 0.0, 0.0)))
        assert [m.key for m in ev.settled] == ["time_delay@alpha"], ev.lines()
        est.append(ev.settled[0].value)
        ses.append(ev.settled[0].stderr)
    est, ses = np.array(est), np.array(ses)
    assert abs(est.mean() - 0.03) < 3 * est.std(ddof=1) / math.sqrt(est.size)
    assert 0.6 < est.std(ddof=1) / ses.mean() < 1.6


def test_a_sensor_group_lagging_together_is_one_effect():
    ev = _evidence(_record(7, lags=(0.08, 0.0, 0.08)))
    assert [m.key for m in ev.settled] == ["time_delay@alpha,az"]
    m = ev.settled[0]
    assert abs(m.value - 0.08) < 3 * m.stderr


def test_a_q_lag_is_q_lagging_not_a_negative_delay():
    ev = _evidence(_record(8, lags=(0.0, 0.05, 0.0)))
    assert [m.key for m in ev.settled] == ["time_delay@q"] and ev.settled[0].value > 0


def test_a_vane_offset_is_an_alias_of_an_accelerometer_offset():
    """3 m: both readings are plausible, so the identity cannot choose, and says so."""
    ev = _evidence(_record(9, offset=3.0))
    assert not ev.settled and len(ev.aliases) == 1
    members = {m.key: m for m in ev.aliases[0]}
    assert set(members) >= {"sensor_offset@alpha", "sensor_offset@az"}
    vane, accel = members["sensor_offset@alpha"], members["sensor_offset@az"]
    assert abs(vane.value - 3.0) < 3 * vane.stderr and accel.value == -vane.value


def test_a_nose_boom_vane_is_settled_by_the_plausible_ranges():
    """13 m ahead: the accelerometer 13 m behind the c.g. lies outside its plausible range."""
    ev = _evidence(_record(10, offset=13.0))
    assert [m.key for m in ev.settled] == ["sensor_offset@alpha"]
    assert [m.key for m in ev.implausible] == ["sensor_offset@az"]
    assert abs(ev.settled[0].value - 13.0) < 3 * ev.settled[0].stderr


def test_known_positions_are_applied_first():
    rec = _record(11, offset=13.0)
    ev = _evidence(rec, known=SensorTerms(offset=13.0))
    assert not ev.settled and not ev.aliases


def test_a_lag_below_the_resolution_is_set_aside():
    """2 ms at 50 Hz (a tenth of the sample interval) on a nearly noise-free record: significant, but
    below a quarter sample, so not settled."""
    ev = _evidence(_record(12, lags=(0.002, 0.0, 0.0), noise=1e-4))
    assert not ev.settled
    assert any(m.key == "time_delay@alpha" for m in ev.unresolved)


def test_check_contradicts_the_wrong_way_and_not_an_alias():
    ev = _evidence(_record(13, offset=3.0))
    assert not ev.settled  # the 3 m offset is an unresolved alias (test above)
    # the vane offset and its accelerometer alias: the same terms, the same check, no contradiction
    vane = ev.check(sensor_terms(get_effect("sensor_offset@alpha"), {"x_alpha": 3.0}))
    accel = ev.check(sensor_terms(get_effect("sensor_offset@az"), {"x_az": -3.0}))
    assert vane == accel and vane[1] > LEVEL
    # an offset the wrong way round moves alpha away from the identity: contradicted
    lr, p = ev.check(sensor_terms(get_effect("sensor_offset@alpha"), {"x_alpha": -3.0}))
    assert p < LEVEL and lr > 0
    assert ev.check(None) == (0.0, 1.0)
    # once a 13 m vane is settled, an accelerometer offset of -13 m on top doubles it: contradicted
    ev13 = _evidence(_record(13, offset=13.0))
    assert ev13.check(sensor_terms(get_effect("sensor_offset@az"), {"x_az": -13.0}))[1] < LEVEL


def test_a_scale_error_is_settled_and_the_ratios_reported():
    rec = _record(14, scales=(0.95, 1.0, 1.0))
    ev = _evidence(rec)
    assert [m.key for m in ev.settled] == ["sensor_scale@alpha"]
    k = ev.settled[0]
    assert abs(k.value - (-0.05)) < 3 * k.stderr
    ka, se = ev.scales["kappa_alpha"]  # after the settled scale: K_q / K_alpha back to 1
    assert abs(ka - 1.0) < 3 * se
    # with the scale known, the ratio the identity reports is the raw one (kappa_alpha = K_q / K_alpha)
    raw = _evidence(rec, known=SensorTerms()).scales  # noqa: F841 (same evidence: settled again)
    known = kinematic_evidence(
        [spectra(rec, band=(0.3, 10.0, 0.05), trim="first")], U, known=SensorTerms(scales=(0.95, 1.0, 1.0))
    )
    assert not known.settled


def test_a_wrong_airspeed_is_an_a_z_scale_and_is_named_as_one():
    """Eq. 5 holds with the true U; given U_g = U / 1.08, the identity needs a_z scaled by
    g/U against g/U_g: k_az = U/U_g - 1 = 0.08 (closed form), and the text names the airspeed."""
    rec = _record(21)
    U_given = U / 1.08
    ev = kinematic_evidence([spectra(rec, band=(0.3, 10.0, 0.05), trim="first")], U_given)
    assert [m.key for m in ev.settled] == ["sensor_scale@az"]
    k = ev.settled[0]
    assert abs(k.value - 0.08) < 3 * k.stderr
    line = next(s for s in ev.lines() if "airspeed" in s)
    assert f"{U_given * (1 + k.value):.4g} m/s" in line and abs(U_given * (1 + k.value) - U) < 3 * U_given * k.stderr


# --- each pattern's profile against a brute-force search --------------------------------------------------------------


def _dense(idn, pat, lo, hi, n):
    """The least cost of ``pat`` on an n-point grid of [lo, hi]: brute force, independent of the profile."""
    grid = np.linspace(lo, hi, n)
    costs = idn.costs(pat.batch(SensorTerms(), grid))
    i = int(np.argmin(costs))
    return grid[i], costs[i], grid[1] - grid[0]


def test_every_profile_finds_the_brute_force_minimum():
    """An offset and a scale are found in closed form (the cost is quadratic in the offset and in 1/(1 + k)),
    a lag by coarse and refined grids: each size and cost against 4,001 points over the bounds.  The grid's
    own minimum lies within half its spacing of the true one, so a profile is at least as low as the grid's
    point, to rounding, and its size within a spacing of it (the cost's curvature sets no tighter bound)."""
    from fdml.kinematics import _identity, _profile, patterns

    rec = _record(3, lags=(0.03, 0.0, 0.0), offset=1.2, scales=(1.0, 1.0, 0.96))
    idn = _identity([spectra(rec, band=(0.3, 10.0, 0.05), trim="first")], U, SensorTerms())
    for pat in patterns():
        lo, hi = pat.bounds
        x, cost, se = _profile(idn, SensorTerms(), pat)
        xd, cd, h = _dense(idn, pat, lo, hi, 4001)
        assert cost <= cd + 1e-9 * abs(cd), pat.keys
        assert abs(x - xd) <= h + 1e-3 * se, pat.keys
        assert 0.0 < se < math.inf


def test_a_pattern_not_significant_on_its_own_is_neither_settled_nor_an_alias():
    """A clean record (the validation's null seed 1000241: Navion 3-2-1-1, 3 % white noise) whose best
    pattern, a 1.3 ms lag of q and a_z, passes the level but lies below the quarter-sample resolution.
    The a_z scale explains the identity equally (its LR within 15.4 of the best) with p = 0.009 alone.
    It is the alias set's only resolved member, and it used to be settled for that reason: a false alarm."""
    from fdml.diagnose.truth import simulate_truth
    from fdml.diagnose.validation import BAND, GUST_STD
    from fdml.kinematics import _alias_set, known_terms, members
    from fdml.models import make_model

    base = make_model("steady", "navion")
    rec = simulate_truth(base, None, {}, maneuver="3211", seed=1000241, noise=0.03, gust_std=GUST_STD)
    U = base.aircraft.U
    ev = kinematic_evidence([spectra(rec, band=BAND)], U, known=known_terms(base))
    alias = [m for f in _alias_set(list(ev.tested)) for m in members(f, rec.dt, U)]
    best = ev.tested[0]
    assert best.p < LEVEL and not any(m.resolved for m in members(best, rec.dt, U))  # the case is the one described
    assert [m.key for m in alias if m.resolved] == ["sensor_scale@az"] and alias[0].finding.p < LEVEL
    assert not ev.settled and not ev.aliases
    assert [m.key for m in ev.unresolved] == ["time_delay@q,az"]  # the set-aside lag, not the patterns of chance


def test_null_likelihood_ratios_have_their_nominal_distribution():
    """Over 120 clean records (two noise levels, two sample rates), every pattern's LR against its null
    law: chi2(1) for an offset or a scale (mean 1), the chi-bar-square 0.5 chi2_0 + 0.5 chi2_1 for a lag
    from its bound (mean 0.5).  The mean of 120 draws has a standard error of 0.13 (chi2(1): sd sqrt 2)
    and 0.10 (chi-bar-square: sd sqrt 1.25); the bands below are about four of them.  All 1,200 p-values
    pooled: the share under 0.05 is 0.05 +- 0.025 (four binomial standard errors of 0.0063, the
    patterns of one record taken as independent).  Before the record ends were known values (a lag's end terms were free
    coefficients) the lags' mean was 1.7; before the variance model was fitted by maximum likelihood, the
    scales' was 2."""
    lags, others, ps = [], [], []
    for seed in range(120):
        rec = _record(20_000 + seed, noise=(0.01, 0.04)[seed % 2], dt=(0.02, 0.01)[(seed // 2) % 2])
        for f in _evidence(rec).tested:
            (lags if f.unit == "s" else others).append(f.lr)
            ps.append(f.p)
    assert 0.1 < np.mean(lags) < 0.9, np.mean(lags)  # 0.5 +- 4 x 0.1
    assert 0.5 < np.mean(others) < 1.5, np.mean(others)
    assert abs(np.mean(np.array(ps) < 0.05) - 0.05) < 0.025, np.mean(np.array(ps) < 0.05)
