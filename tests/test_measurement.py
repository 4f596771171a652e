"""One forward measurement model (fdml.models.measurement) and every user of it, pinned together.

Users: Problem.predict and the nuisance columns of Problem.sensitivities (the
fit), FitResult.fitted_spectra (also after a JSON round trip), the residual
covariance the fit reports, and plotting.simulate_fit (its time-domain view).
Two-record fits with state-equation biases, an elevator bias, measured and
estimated boundary terms, on records made with scipy's lsim (tests/conftest.py).
"""

import warnings

import numpy as np
import pytest
from conftest import lsim_dimensional, noisy_record, three_two_one_one

from fdml import fit
from fdml.estimate import SETTINGS, prepare
from fdml.fourier import finite_fourier_transform
from fdml.models import ModelResponse, make_model
from fdml.models.measurement import (
    NUISANCE_NAMES,
    boundary_vector,
    end_shift,
    nuisance_columns,
    predict,
)
from fdml.plotting import simulate_fit
from fdml.results import load_result

EPS = np.finfo(float).eps
OUTS = ("alpha", "q", "az")
#: (boundary, state_biases, input_bias).  For this model the elevator offset is
#: exactly a state-equation bias along B, so the third fit is not identifiable in
#: those two; the measurement model must still agree everywhere.
CONFIGS = [("estimated", True, False), ("measured", False, True), ("measured", True, True)]
BAND = (0.3, 10.0, 0.1)


def _records(dt):
    """Two records of the Navion dimensional model, started 2 s into the motion (x(0) != 0)."""
    m = make_model("dimensional", "navion")
    t = np.arange(0.0, 14.0 + dt / 2, dt)
    keep = t >= 2.0 - 1e-9
    out = []
    for i, (start, unit) in enumerate(((1.5, 0.3), (1.0, 0.5))):
        de = three_two_one_one(t, 0.02, start=start, unit=unit)
        y = lsim_dimensional(m, t, de + 0.003)  # elevator offset the record does not show
        y = y + np.array([0.02, -0.001, 0.05])  # sensor offsets
        rec = noisy_record(
            t[keep] - t[keep][0], de[keep] - 0.01, y[keep], np.random.default_rng(7 + i), fraction=0.02, name="ab"[i]
        )
        out.append(rec)
    return m, out


def _fit(dt, config):
    m, recs = _records(dt)
    kw = {"boundary": config[0], "state_biases": config[1], "input_bias": config[2], "band": BAND}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # identifiability warnings of the degenerate third config
        res = fit(recs, m, **kw)
        prob = prepare(recs, m, **kw)
    return res, prob


@pytest.fixture(scope="module", params=CONFIGS, ids=["-".join(map(str, c)) for c in CONFIGS])
def case(request):
    return _fit(0.02, request.param)


# --- the module on its own -------------------------------------------------------------------


def test_predict_is_linear_in_the_nuisance_values_with_columns_as_coefficients():
    rng = np.random.default_rng(0)
    m = 40

    def cplx(*shape):
        return rng.normal(size=shape) + 1j * rng.normal(size=shape)

    resp = ModelResponse(np.linspace(0.5, 8, m), cplx(m, 3, 1), cplx(m, 3, 2), cplx(m, 3, 2))
    omega, T, u, ones = resp.omega, 7.3, cplx(m, 1), cplx(m)
    shift = end_shift(omega, T)
    eta = rng.normal(size=len(NUISANCE_NAMES))
    full = predict(resp, u, ones, boundary_vector(eta[3:5], eta[5:7], shift), eta[:3], eta[7:9], eta[9] * ones)
    bare = predict(resp, u, ones)
    # y - G u = C eta exactly (every term linear): only rounding, a few eps of |y|
    np.testing.assert_allclose(
        full - bare, nuisance_columns(resp, shift, ones) @ eta, rtol=0, atol=50 * EPS * np.abs(full).max()
    )
    # the boundary vector, written out: d = x(0) - x(T) exp(-j w T) (THEORY.md section 7)
    d = boundary_vector(eta[3:5], eta[5:7], shift)
    np.testing.assert_allclose(
        d[:, 1], eta[4] - eta[6] * (np.cos(omega * T) - 1j * np.sin(omega * T)), rtol=0, atol=10 * EPS
    )


def test_predict_of_derivatives_broadcasts_over_a_leading_axis():
    rng = np.random.default_rng(1)
    m, k = 30, 4
    G, H, P = (rng.normal(size=(k, m, 3, n)) + 1j * rng.normal(size=(k, m, 3, n)) for n in (1, 2, 2))
    u, ones, d = rng.normal(size=(m, 1)) + 0j, rng.normal(size=m) + 0j, rng.normal(size=(m, 2)) + 0j
    many = predict(ModelResponse(None, G, H, P), u, ones, d, None, np.array([0.3, -0.2]), 0.1 * ones)
    for i in range(k):
        one = predict(ModelResponse(None, G[i], H[i], P[i]), u, ones, d, None, np.array([0.3, -0.2]), 0.1 * ones)
        np.testing.assert_array_equal(many[i], one)


# --- every user agrees ----------------------------------------------------------------------


def test_fitted_spectra_equal_problem_predict_at_the_estimate(case, tmp_path):
    res, prob = case
    assert prob.names == res.names
    ys = prob.predict(res.values)
    back = load_result(res.to_json(tmp_path / "fit.json"))
    for r in range(2):
        # the same function on the same floats (JSON keeps every float bit): equal but for at most
        # a rounding difference in the order of operations, a few eps of the largest value
        tol = 8 * EPS * np.abs(ys[r]).max()
        np.testing.assert_allclose(res.fitted_spectra(r), ys[r], rtol=0, atol=tol)
        np.testing.assert_allclose(back.fitted_spectra(r), ys[r], rtol=0, atol=tol)


def test_reported_residual_covariance_is_that_of_the_fitted_spectra(case):
    res, prob = case
    out = [OUTS.index(o) for o in res.outputs]
    V = np.concatenate([(s.z - res.fitted_spectra(r))[:, out] for r, s in enumerate(res.spectra)])
    np.testing.assert_allclose(prob.residuals(res.values), V, rtol=0, atol=8 * EPS * np.abs(V).max())
    R = V.T @ V.conj() / V.shape[0]  # Eq. 24
    scale = np.real(np.diag(R)).max()
    R = R + SETTINGS.r_floor * scale * np.eye(len(out))  # the fit's documented floor on the diagonal
    # one sum over ~200 rows: rounding well below 1e-13 of the largest variance
    np.testing.assert_allclose(res.R, R, rtol=0, atol=1e-13 * scale)
    assert res.cost == pytest.approx(np.linalg.det(R).real, rel=1e-9)  # J = det R (Eq. 25)


def test_nuisance_columns_equal_finite_differences_of_predict(case):
    res, prob = case
    th = res.values
    A = prob.sensitivities(th)
    nuis = [i for i, s in enumerate(prob.slots) if s.role.nuisance]
    assert len(nuis) == len(prob.slots) - 6
    for i in nuis:
        h = max(abs(th[i]), 1.0)
        fd = (prob._eval_moved(th, i, h) - prob._eval_moved(th, i, -h)) / (2 * h)
        # y is linear in a nuisance value: no truncation error, rounding eps |y| / h (|y| ~ h |column|)
        np.testing.assert_allclose(A[:, :, i], fd, rtol=0, atol=1e-12 * np.abs(A[:, :, i]).max(), err_msg=prob.names[i])


def _time_domain_error(res):
    """max |transform of simulate_fit - fitted spectra| / peak, per output, over both records."""
    worst = np.zeros(3)
    for r in range(2):
        sim = simulate_fit(res, r)
        s, nu = res.spectra[r], res.nuisance_values(r)
        trim = sim.meta["trim"]
        Y = np.column_stack([finite_fourier_transform(sim[o] - trim[o], sim.dt, s.omega) for o in OUTS])
        y = res.fitted_spectra(r)
        # simulate_fit ends where the model goes, not at the fitted x(T) (a property of the
        # transform, not of the motion): move y's x(T) there, d = x(0) - x(T) exp(-j w T)
        xT = np.array([sim["alpha"][-1] - trim["alpha"], sim["q"][-1] - trim["q"]]) - nu.biases[:2]
        H = res.model.evaluate(s.omega).H
        y = y - (H @ (xT - nu.xT)) * np.exp(-1j * s.omega * s.T)[:, None]
        worst = np.maximum(worst, np.abs(Y - y).max(axis=0) / np.abs(y).max(axis=0))
    return worst


def test_simulate_fit_transformed_matches_fitted_spectra(case):
    res, _ = case
    assert res.nuisance_values(0).state_biases is not None or res.nuisance_values(0).input_bias is not None
    err = _time_domain_error(res)
    # The simulator holds the sampled elevator linearly between samples (first-order hold), the
    # transform integrates the cubic interpolant of the same samples (order dt^4): they differ at
    # frequency w by 1 - sinc^2(w dt / 2) ~ (w dt)^2 / 12 of the input there, at most
    # (w_max dt)^2 / 12 = 3.3e-3 of the peak output spectrum at 10 rad/s and dt = 0.02 s.
    assert np.all(err < (BAND[1] * 0.02) ** 2 / 12), err


def test_time_domain_mismatch_is_second_order_in_the_sampling_interval():
    # a formula difference between the two views would not shrink with dt; the hold difference
    # above falls as dt^2: a factor of 4 when dt halves (3 to 5 allowed for the noise realisation)
    coarse = _time_domain_error(_fit(0.02, CONFIGS[2])[0])
    fine = _time_domain_error(_fit(0.01, CONFIGS[2])[0])
    assert np.all((coarse / fine > 3.0) & (coarse / fine < 5.0)), coarse / fine
