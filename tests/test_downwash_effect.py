"""The downwash lag in its textbook form (issue 8): the downwash reaches the tail l_t/U late.

References are independent of the code under test:

* the frequency response of the steady Wells-Keskar model with the downwash delayed,
  E = eps_ss [(1 - g) + g exp(-s tau)], written here from THEORY.md Eqs. 6-7, 9 and 13-15 with the
  aircraft's numbers (not through fdml's model or effect code);
* the validation truth, a delay-differential equation marched in the time domain
  (``fdml.diagnose.truth``), against that closed form (finite Fourier transform of a smooth doublet
  response, as tests/test_model_effects.py does for every effect);
* fdml's simulation of the model with the effect (a Pade realisation) against the truth's march.
"""

import numpy as np
import pytest

from fdml.constants import G0
from fdml.diagnose.truth import _downwash_delay, simulate_truth
from fdml.fourier import finite_fourier_transform
from fdml.maneuvers import doublet, time_vector
from fdml.models import make_model, with_effects
from fdml.simulate import simulate

OMEGA = np.linspace(0.2, 10.0, 50)


@pytest.fixture(scope="module")
def navion():
    return make_model("steady", "navion")


def closed_form(model, omega, tau, g=1.0):
    """(n, 3) alpha, q, a_z per elevator of the steady model with eps = eps_ss [(1 - g) + g e^{-s tau}] alpha.

    THEORY.md: C_Lt = a_t (alpha - eps + l q/U) (Eq. 9, quasi-steady), C_z = -a_w alpha - (St/Sw) C_Lt
    + Cz_de de (Eq. 6), C_m = -(l St/(c Sw)) C_Lt + Cm_de de (Eq. 7), Eqs. 3-5 for the states and a_z.
    """
    ac, p = model.aircraft, model.parameters.values
    s = 1j * np.asarray(omega)
    sr, l, U, c = ac.S_t / ac.S_w, p["l_t"], ac.U, ac.c_w
    eps = p["deps_da"] * ((1.0 - g) + g * np.exp(-s * tau))
    clt_a, clt_q = p["CLa_t"] * (1.0 - eps), p["CLa_t"] * l / U  # C_Lt per alpha, per q
    cz_a, cz_q = -p["CLa_w"] - sr * clt_a, -sr * clt_q
    cm_a, cm_q = -(l * sr / c) * clt_a, -(l * sr / c) * clt_q
    out = np.empty((s.size, 3), complex)
    for i, si in enumerate(s):
        M = np.array([[si - ac.k_z * cz_a[i], -1.0 - ac.k_z * cz_q], [-ac.k_m * cm_a[i], si - ac.k_m * cm_q]])
        a, q = np.linalg.solve(M, [ac.k_z * p["Cz_de"], ac.k_m * p["Cm_de"]])
        out[i] = a, q, (U / G0) * (si * a - q)  # Eq. 5
    return out


def test_effect_response_is_the_delayed_downwash(navion):
    tau = navion.aircraft.l_t / navion.U  # the textbook l_t/U, 0.086 s
    for g in (1.0, 0.4):
        m = with_effects(navion, "downwash_lag:tail").with_values(g_dw=g, tau_dw=tau)
        G = m.frequency_response(OMEGA)[:, 0, :].T
        ref = closed_form(navion, OMEGA, tau, g)
        assert np.max(np.abs(G - ref)) < 1e-12 * np.max(np.abs(ref))  # same algebra, rounding only
    # the effect is sizeable (the check above could fail) and vanishes at its null g = 0
    assert np.max(np.abs(closed_form(navion, OMEGA, tau) - closed_form(navion, OMEGA, tau, 0.0))) > 0.1 * np.max(
        np.abs(closed_form(navion, OMEGA, 0.0))
    )
    m0 = with_effects(navion, "downwash_lag:tail").with_values(g_dw=0.0, tau_dw=tau)
    np.testing.assert_array_equal(m0.frequency_response(OMEGA), navion.frequency_response(OMEGA))


def _transfer(y, u, dt):
    Y = finite_fourier_transform(np.column_stack([y["alpha"], y["q"], y["az"]]), dt, OMEGA)
    return Y / finite_fourier_transform(u, dt, OMEGA)[:, None]


def test_time_domain_truth_matches_the_closed_form(navion):
    tau = navion.aircraft.l_t / navion.U
    dt = 0.01
    t = time_vector(40.0, dt)
    u = doublet(t, 0.01, start=1.0, width=0.5, rise=0.5)
    ref = closed_form(navion, OMEGA, tau)
    err = np.max(np.abs(_transfer(_downwash_delay(navion, t, {"de": u}, tau), u, dt) - ref), axis=0)
    # tolerance of tests/test_model_effects.py: the first-order hold's sinc^2(w dt/2) factor,
    # (w dt/2)^2/4 = 6e-4 at 10 rad/s, times 2 for the interpolated delayed alpha (measured 1.6e-4 to 6e-4)
    tol = 2 * (OMEGA[-1] * dt / 2) ** 2 / 4
    assert np.max(err / np.max(np.abs(ref), axis=0)) < tol
    size = np.max(np.abs(ref - closed_form(navion, OMEGA, 0.0)), axis=0) / np.max(np.abs(ref), axis=0)
    assert np.min(size) > 20 * tol  # the delay changes every output far beyond the tolerance


def test_simulate_with_the_effect_matches_the_truth(navion):
    """fdml.simulate (an [8/8] Pade realisation of the delay) against the truth's delay-differential march."""
    tau = navion.aircraft.l_t / navion.U
    t = time_vector(20.0, 0.02)
    from fdml.maneuvers import make_input

    de = make_input("3211", t, np.radians(1.0), unit=0.4, rise=0.04)
    m = with_effects(navion, "downwash_lag:tail").with_values(g_dw=1.0, tau_dw=tau)
    rec = simulate(m, t, {"de": de})
    truth = _downwash_delay(navion, t, {"de": de}, tau)
    plain = simulate(navion, t, {"de": de})
    for ch in ("alpha", "q", "az"):
        peak = np.max(np.abs(rec[ch]))
        # two second-order schemes (exact-hold Pade states at dt; the march at dt/8 with the delayed alpha
        # interpolated linearly): measured 2e-5 of the peak; 1e-3 leaves room and is still 30 times
        # below the effect itself (next line)
        assert np.max(np.abs(rec[ch] - truth[ch])) < 1e-3 * peak, ch
        assert np.max(np.abs(plain[ch] - truth[ch])) > 3e-2 * peak, ch


def test_effect_needs_a_tail_model_and_is_listed():
    from fdml.errors import ParameterError
    from fdml.models.effects import catalogue

    with pytest.raises(ParameterError, match="downwash_lag@tail"):
        with_effects(make_model("dimensional", "navion"), "downwash_lag:tail")
    entry = next(e for e in catalogue() if e["key"] == "downwash_lag@tail")
    assert set(entry["models"]) == {"steady", "unsteady"}
    with pytest.raises(ParameterError, match="give downwash_lag:CHANNEL"):
        with_effects(make_model("steady", "navion"), "downwash_lag")  # q (G) or tail (delay): ambiguous


@pytest.mark.slow
@pytest.mark.parametrize("maneuver, seed", [("3211", 2000022), ("multisine", 2000034)])
def test_diagnosis_names_a_textbook_downwash_lag(navion, maneuver, seed):
    """A transport-delay downwash (tau = l_t/U) simulated in the time domain at high SNR (0.3 % noise)
    is named as the downwash lag on the tail, not an elevator delay or actuator lag (issue 8).

    Seeds from the report range of the high-SNR runs in the issue-8 note (6 of 6 named there)."""
    import warnings

    from fdml.diagnose import diagnose
    from fdml.diagnose.validation import BAND, HOLDOUT_OF

    tau = navion.aircraft.l_t / navion.U
    kw = dict(noise=0.003, noise_kind="white")
    rec = simulate_truth(navion, "downwash_lag@tail", {"tau_dw": tau}, maneuver=maneuver, seed=seed, **kw)
    hold = simulate_truth(
        navion, "downwash_lag@tail", {"tau_dw": tau}, maneuver=HOLDOUT_OF[maneuver], seed=seed + 7_919_000, **kw
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = diagnose(rec, navion, holdout=hold, band=BAND)
    assert rep.selected and rep.selected[0]["key"] == "downwash_lag@tail", rep.summary()
    # a late share of the downwash, with a delay inside the searched grid (0.04-0.42 s).  The size is not
    # pinned: the refit from the score test's start stops at a small share with a longer delay (g 0.02,
    # tau 0.22 s on the first seed) rather than g = 1, tau = l_t/U (the first-order part of the delay is
    # absorbed by the derivatives, so the likelihood is flat along that ridge; see the issue-8 note)
    par = rep.selected[0]["params"]
    assert par["g_dw"]["value"] > 0.0 and 0.04 <= par["tau_dw"]["value"] <= 0.42, par


@pytest.mark.parametrize("order", [1, 2, 4, 6])
def test_pade_delay_is_scipys_canonical_form_and_all_pass(order):
    """pade_delay builds its realisation on numpy (no scipy.signal on the fit path, issue 20).

    References: scipy.signal.tf2ss on the same [n/n] coefficients (Pade: c_k = (2n-k)! n! /
    ((2n)! k! (n-k)!)), and the closed-form property that the approximant is all-pass, |H| = 1
    exactly, with phase -omega tau to O((omega tau)^(2n+1)).
    """
    import math

    from scipy import signal

    from fdml.models.effect_library import pade_delay

    tau = 0.25
    A, B, C, D = pade_delay(tau, order)
    k = np.arange(order + 1)
    c = np.array(
        [
            math.factorial(2 * order - j)
            * math.factorial(order)
            / math.factorial(2 * order)
            / (math.factorial(j) * math.factorial(order - j))
            for j in k
        ]
    )
    Ar, Br, Cr, Dr = signal.tf2ss((c * (-1.0) ** k)[::-1], c[::-1])
    # the same realisation up to the 1/tau scaling: rounding of a few products only
    np.testing.assert_allclose(A * tau, Ar, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(B * tau, Br, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(C, Cr, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(D, Dr, rtol=1e-12, atol=1e-12)
    w = np.array([0.1, 1.0, 4.0])
    H = np.array([(C @ np.linalg.solve(1j * x * np.eye(order) - A, B) + D)[0, 0] for x in w])
    np.testing.assert_allclose(np.abs(H), 1.0, rtol=1e-12)
    np.testing.assert_allclose(np.angle(H[0]), -w[0] * tau, rtol=1e-3)
