"""The estimator's noise model (fdml.estimate.NoiseModel): white, one R over the band, or one R_b per band."""

import numpy as np
import pytest

import fdml
from fdml.diagnose.data import analysis_data
from fdml.diagnose.likelihood import noise_bands
from fdml.diagnose.truth import simulate_truth
from fdml.errors import FdmlError
from fdml.estimate import NoiseModel, fit, prepare
from fdml.models.effects import get_effect

BAND = (0.3, 12.0)


@pytest.fixture(scope="module")
def case():
    """A 20 s record with a 30 ms pitch-rate delay and coloured sensor noise, four noise bands."""
    base = fdml.make_model("steady", "navion")
    rec = simulate_truth(
        base, "time_delay@q", {"tau_q": 0.03}, duration=20.0, noise=0.05, noise_kind="coloured", seed=4
    )
    data = analysis_data([rec], BAND)
    nb = noise_bands(data, min_independent=8)
    assert nb.n == 4
    return data, nb, get_effect("time_delay@q").augment(base)


def _band_cost(prob, theta, nb):
    """sum_b N_b ln det R_b with R_b = (1/N_b) sum v v^H, written out here (Eq. 24 per band)."""
    V = prob.residuals(theta)
    rows = nb.assign(np.concatenate([d.omega for d in prob.data]))
    c = 0.0
    for b in range(nb.n):
        Vb = V[rows == b]
        c += Vb.shape[0] * np.linalg.slogdet(Vb.T @ Vb.conj() / Vb.shape[0])[1]
    return c


def test_white_is_one_band_and_the_default(case):
    data, _, model = case
    items = list(data.spectra)
    r0 = fit(items, model, adequacy=False, check=False)
    lo, hi = BAND
    r1 = fit(items, model, noise=NoiseModel((lo / 2, hi * 2)), adequacy=False, check=False)
    # one band over everything is the white noise model: the same iterations, bit for bit
    assert np.array_equal(r0.values, r1.values) and np.array_equal(r0.stderr, r1.stderr)


def test_band_noise_fit_minimises_the_band_cost(case):
    from scipy import optimize

    data, nb, model = case
    items = list(data.spectra)
    res = fit(items, model, cov_type="colored", noise=NoiseModel(tuple(nb.edges)), adequacy=False, check=False)
    prob = prepare(items, res.model)
    theta = np.array([res.params[n] for n in prob.names])
    # the reported cost is exp((1/N) sum_b N_b ln det R_b)
    assert prob.N * np.log(res.cost) == pytest.approx(_band_cost(prob, theta, nb), abs=1e-6)
    # an independent optimiser (scipy BFGS on the band cost written out above, in units of the standard
    # errors) from fdml's white-noise fit: the band-wise noise moves the estimate, and both land on the
    # same optimum.  fdml stops within 1e-3 standard errors (its rule), BFGS at gtol 1e-6 on a cost whose
    # curvature is ~1 per unit (a standard error): within a few 1e-3 standard errors, asserted at 0.02.
    white = fit(items, model, cov_type="colored", adequacy=False, check=False)
    t0 = np.array([white.params[n] for n in prob.names])
    se = res.stderr
    opt = optimize.minimize(
        lambda x: _band_cost(prob, t0 + x * se, nb), np.zeros(t0.size), method="BFGS", options={"gtol": 1e-6}
    )
    t_ref = t0 + opt.x * se
    assert np.max(np.abs(t0 - t_ref) / se) > 0.05  # the noise model matters in this case
    assert np.max(np.abs(theta - t_ref) / se) < 0.02
    assert _band_cost(prob, theta, nb) <= opt.fun + 1e-6


def test_noise_model_refuses_bad_edges():
    with pytest.raises(FdmlError, match="increasing"):
        NoiseModel((1.0, 1.0))
    with pytest.raises(FdmlError, match="increasing"):
        NoiseModel((3.0,))
    with pytest.raises(FdmlError, match="NoiseModel"):
        fit([], fdml.make_model("steady", "navion"), noise="band")


def test_diagnosis_fit_reports_errors_at_its_own_estimate(case):
    # issue 8: the diagnosis used to report the white-noise fit's standard errors and derived values next
    # to the estimates of a later polish; now one fit gives all three, so they belong to the same estimate
    from fdml.diagnose.likelihood import fit_model

    data, nb, model = case
    f = fit_model(data, model, nb)
    assert np.array_equal(f.result.values, f.theta)
    assert f.stderr == dict(zip(f.result.names, f.result.stderr.tolist()))
    derived = f.model.derived()
    assert all(f.result.derived[k][0] == pytest.approx(v, rel=1e-12) for k, v in derived.items())
    # and that estimate is the band-noise one: its cost is the band cost written out here
    assert f.cost == pytest.approx(_band_cost(f.prob, f.theta, nb), abs=1e-6)
