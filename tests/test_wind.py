"""Vertical wind and gust angle from inertial and air data (BS Eq. 13), synthetic and real."""

import math

import numpy as np
import pytest
from scipy.signal import savgol_coeffs

from fdml.errors import RecordError
from fdml.io import data_path, load_record
from fdml.record import Record
from fdml.wind import DEFAULT_SMOOTH, SG_CUTOFF, gust_angle

VK = 60.0  # inertial speed, m/s
W_AMP = (1.5, 0.5)  # vertical wind amplitudes at 1.3 and 4 rad/s, m/s


def _flight(u_w=0.0, dt=0.02, T=20.0):
    """Inertial path, a known vertical wind, and the air data an aircraft would measure."""
    t = np.arange(0, T + 1e-9, dt)
    theta = 0.05 + 0.02 * np.sin(0.8 * t)
    gamma_k = 0.01 * np.sin(0.5 * t)
    xdot, hdot = VK * np.cos(gamma_k), VK * np.sin(gamma_k)
    # h: the integral of VK sin(0.01 sin(0.5 t)) by a trapezoid rule 200 times finer than the record
    tf = np.linspace(0, T, 200 * t.size + 1)
    g = VK * np.sin(0.01 * np.sin(0.5 * tf))
    cum = np.concatenate([[0.0], np.cumsum((g[:-1] + g[1:]) / 2 * np.diff(tf))])
    h = 1000.0 + np.interp(t, tf, cum)
    w_w = W_AMP[0] * np.sin(1.3 * t) + W_AMP[1] * np.sin(4.0 * t)
    ua, wa = xdot - u_w, hdot - w_w  # V_a = V_k - V_w (BS Eq. 13)
    V = np.hypot(ua, wa)
    gamma_a = np.arctan2(wa, ua)
    alpha = theta - gamma_a
    truth = gamma_k - gamma_a  # alpha_w = alpha - alpha_k = alpha - (theta - gamma_k)
    sig = {
        "de": 0.01 * np.sin(2 * t),
        "alpha": alpha,
        "q": np.gradient(theta, dt),
        "az": -1 + 0 * t,
        "theta": theta,
        "V": V,
        "hdot": hdot,
        "h": h,
    }
    return Record(t, sig, name="gusty"), truth, w_w, gamma_k


def test_exact_with_inertial_vertical_speed():
    rec, truth, w_w, _ = _flight()
    g = gust_angle(rec)
    assert g.source == "hdot" and g.channels == ("alpha", "V", "theta", "hdot")
    np.testing.assert_allclose(g.alpha_w, truth, atol=1e-12)
    np.testing.assert_allclose(g.w_wind, w_w, atol=1e-10)
    # an up-gust raises the angle of attack: alpha_w ~ w_w / V
    assert np.corrcoef(g.alpha_w, w_w / VK)[0, 1] > 0.999
    r = g.record
    np.testing.assert_array_equal(r["alpha_w"], g.alpha_w)
    assert r.meta["gust"]["source"] == "hdot"


def test_horizontal_wind():
    rec, truth, _, gamma_k = _flight(u_w=5.0)
    np.testing.assert_allclose(gust_angle(rec, horizontal_wind=5.0).alpha_w, truth, atol=1e-12)
    # ignoring it errs by about gamma u_w / V (documented bound)
    err = np.max(np.abs(gust_angle(rec).alpha_w - truth))
    bound = np.max(np.abs(gamma_k)) * 5.0 / VK
    assert 0 < err < 1.5 * bound


def test_from_altitude_within_the_differentiator_error():
    rec, truth, _, _ = _flight()
    rec = Record(rec.t, {k: v for k, v in rec.signals.items() if k != "hdot"}, name="baro")
    g = gust_angle(rec)
    assert g.source == "altitude" and "h" in g.channels
    n_win = round(DEFAULT_SMOOTH / rec.dt) | 1
    assert g.cutoff_hz == pytest.approx(SG_CUTOFF / (n_win * rec.dt))
    # hdot = VK sin(0.01 sin 0.5t) ~ 0.6 sin(0.5 t): the quadratic Savitzky-Golay derivative's
    # relative error at 0.5 rad/s, from its coefficients, bounds the error of alpha_w = gamma_k - gamma_a
    c = savgol_coeffs(n_win, 2, deriv=1, delta=rec.dt)[::-1]
    k = np.arange(n_win) - n_win // 2
    w = 0.5
    H = np.sum(c * np.exp(1j * w * k * rec.dt))
    rel = abs(H / (1j * w) - 1)
    inner = slice(n_win, -n_win)  # the ends use one-sided fits
    err = np.max(np.abs(g.alpha_w - truth)[inner])
    assert err < 2 * rel * 0.6 / VK + 1e-9


def test_noise_floor_is_what_it_says():
    rec, truth, _, _ = _flight()
    rng = np.random.default_rng(21)
    h = rec["h"] + 0.05 * rng.standard_normal(rec.n)
    rec = Record(rec.t, {**{k: v for k, v in rec.signals.items() if k != "hdot"}, "h": h})
    g = gust_angle(rec)
    actual = float(np.std((g.alpha_w - truth)[20:-20]))
    predicted = g.hdot_noise / float(np.mean(rec["V"]))
    # the noise level is estimated from the data (third differences): within 30 %
    assert actual == pytest.approx(predicted, rel=0.3)
    assert any("noise floor" in n for n in g.notes)


def test_missing_channels_are_named():
    rec, _, _, _ = _flight()
    no_theta = Record(rec.t, {k: v for k, v in rec.signals.items() if k != "theta"})
    with pytest.raises(RecordError, match="lacks theta"):
        gust_angle(no_theta)
    with pytest.raises(RecordError, match="lacks hdot"):
        gust_angle(Record(rec.t, {k: v for k, v in rec.signals.items() if k != "hdot"}), source="hdot")
    with pytest.raises(RecordError, match="unknown gust source"):
        gust_angle(rec, source="radar")


# --- the real records ----------------------------------------------------------------------------
def test_hfb320_has_no_vertical_speed_or_altitude():
    rec = load_record(data_path("hfb320/hfb320_1_10.asc"))
    with pytest.raises(RecordError, match=r"lacks h \(or hdot\)"):
        gust_angle(rec)


@pytest.mark.parametrize("rel", ["twin_otter/totter_lon_020213f1_018.mat", "attas/fAttasElv1.mat"])
def test_real_records_only_offer_a_barometric_altitude(rel):
    rec = load_record(data_path(rel))
    assert not rec.has("hdot")
    g = gust_angle(rec)
    assert g.source == "altitude" and np.all(np.isfinite(g.alpha_w))
    assert any("barometric altitude is not inertial" in n for n in g.notes)


def test_baro_altitude_rate_against_the_kinematic_climb_rate():
    """Twin Otter: the pressure-altitude rate follows V sin(theta - alpha) (ratio ~1); ATTAS: it is
    about three times larger, so its altitude carries static-pressure errors that swamp any gust."""
    from scipy.signal import savgol_filter

    ratios = {}
    for rel in ("twin_otter/totter_lon_020213f1_018.mat", "attas/fAttasElv1.mat"):
        r = load_record(data_path(rel))
        hd = savgol_filter(r["h"], int(1.0 / r.dt) | 1, 2, deriv=1, delta=r.dt)
        kin = r["V"] * np.sin(r["theta"] - r["alpha"])
        ratios[rel.split("/")[0]] = float(np.std(hd) / np.std(kin))
    assert 0.8 < ratios["twin_otter"] < 1.25
    assert ratios["attas"] > 2.5
    assert math.isfinite(ratios["attas"])
