"""Maximum-likelihood estimator (THEORY.md Eqs. 20-26): recovery, statistics, conventions, errors."""

import json
import math
import warnings

import numpy as np
import pytest
from conftest import noisy_record, three_two_one_one

from fdml import fit, fourier, load_result
from fdml.compare import compare_steady_unsteady
from fdml.errors import (
    BandError,
    DataWarning,
    FdmlError,
    IdentifiabilityWarning,
    ParameterError,
    RecordError,
)
from fdml.estimate import _cov_R, _grad_hess, prepare
from fdml.models import make_model
from fdml.record import Record
from fdml.spectral import FrequencyData

DIM = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")


def truth(m):
    return np.array([m.parameters[n].value for n in DIM])


def pick(res, names=DIM):
    return np.array([res[n] for n in names]), np.array([res.errors[n] for n in names])


def synthetic_spectra(model, rng, noise=0.01, dt=0.01, duration=12.0, name="fd"):
    """Frequency-domain data z = G u + complex noise (THEORY.md 9(d) set-up)."""
    t = np.arange(0, duration + dt / 2, dt)
    de = three_two_one_one(t)
    om = fourier.omega_band(0.1, 10.0, 0.1)
    U = fourier.finite_fourier_transform(de, dt, om)
    z = model.evaluate(om).G[:, :, 0] * U[:, None]
    scale = noise * np.sqrt(np.mean(np.abs(z) ** 2, axis=0))
    z = z + scale * (rng.normal(size=z.shape) + 1j * rng.normal(size=z.shape)) / np.sqrt(2)
    ones = fourier.finite_fourier_transform(np.ones_like(t), dt, om)
    return FrequencyData(
        name,
        om,
        z,
        U[:, None],
        ("de",),
        np.zeros(2),
        np.zeros(2),
        t[-1],
        dt,
        t.size,
        ones,
        trim_mode="none",
        trim_samples=0,
        band=(0.1, 10.0, 0.1),
    )


def test_recovers_dimensional_parameters(dimensional_case):
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de, y, np.random.default_rng(7))
    start = m.with_values({n: 1.3 * m.parameters[n].value for n in DIM})
    res = fit(rec, start)
    assert res.converged
    est, se = pick(res)
    assert np.all(np.abs(est - truth(m)) < 3 * se)  # within 3 standard errors
    assert np.all(np.isfinite(se) & (se > 0))


@pytest.mark.slow
def test_monte_carlo_scatter_matches_reported_stderr(dimensional_case):
    # 50 seeded records; the std of a std estimate from 50 samples is about 10 %,
    # so a correct covariance puts the ratio within 25 % of one with high probability.
    m, t, de, y = dimensional_case
    est, se = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        for i in range(50):
            res = fit(noisy_record(t, de, y, np.random.default_rng(500 + i)), m)
            e, s = pick(res)
            est.append(e)
            se.append(s)
    est, se = np.array(est), np.array(se)
    ratio = est.std(axis=0, ddof=1) / se.mean(axis=0)
    assert np.all((ratio > 0.75) & (ratio < 1.25)), ratio
    # noise adds no bias: the mean equals the noise-free estimate to 3 standard errors of the mean
    # (the noise-free estimate itself differs from truth by O(dt^2), lsim's first-order hold
    # against the transform's cubic interpolation of the sampled input)
    clean, _ = pick(fit(Record(t, {"de": de, "alpha": y[:, 0], "q": y[:, 1], "az": y[:, 2]}), m))
    assert np.all(np.abs(est.mean(axis=0) - clean) < 3 * est.std(axis=0) / math.sqrt(50))


def test_naive_bound_is_optimistic_on_a_fine_grid(dimensional_case):
    # THEORY.md 7: at 0.1 rad/s on a 10 s record (2 pi/T = 0.63) neighbouring residuals are
    # correlated, and the naive inverse information understates the variance.
    m, t, de, y = dimensional_case
    res = fit(noisy_record(t, de, y, np.random.default_rng(3)), m)
    naive = np.sqrt(np.diag(res.cov_naive))[: len(DIM)]
    assert np.all(res.stderr[: len(DIM)] > 1.5 * naive)


def test_residual_covariance_convention():
    # Eq. 24: R_jk = (1/N) sum v_ij conj(v_ik) (THEORY.md 7); the transposed form would give conj
    v = np.array([[1 + 2j, 3 - 1j, 0.5j]])
    R = _cov_R(v)
    assert R[0, 1] == (1 + 2j) * np.conj(3 - 1j)  # off-diagonal: untouched by the 1e-12 floor
    rng = np.random.default_rng(0)
    L = np.array([[1.0, 0, 0], [0.5 + 0.7j, 1.0, 0], [0.2, -0.3j, 1.0]])
    X = (rng.normal(size=(200000, 3)) + 1j * rng.normal(size=(200000, 3))) / np.sqrt(2)
    V = X @ L.T  # rows v = L x, so E{v v^*} = L L^H, with a complex cross-spectrum
    assert np.allclose(_cov_R(V), L @ L.conj().T, atol=0.01)  # sampling error ~ 1/sqrt(2e5) ~ 2e-3
    assert not np.allclose(_cov_R(V), (L @ L.conj().T).T, atol=0.1)


def test_gradient_of_concentrated_likelihood(dimensional_case):
    # g from _grad_hess equals the numerical derivative of ln det R(theta), which pins both
    # the conjugation of R and the weighting v^* R^-1 v.
    m, t, de, y = dimensional_case
    prob = prepare(noisy_record(t, de, y, np.random.default_rng(1)), m)
    th = prob.initial() * 1.02
    V = prob.residuals(th)
    R = _cov_R(V)
    A = prob.sensitivities(th)
    g, H1, Hc = _grad_hess(A, V, R, full=True)

    def J(x):
        return np.linalg.slogdet(_cov_R(prob.residuals(x)))[1]

    for k in range(len(DIM)):
        h = 1e-6 * abs(th[k])
        e = np.zeros_like(th)
        e[k] = h
        num = (J(th + e) - J(th - e)) / (2 * h)
        # sensitivities are Eq. 26 forward differences settled to 1e-4 relative
        assert g[k] == pytest.approx(num, rel=2e-3, abs=1e-6 * np.abs(g).max())


def test_lm_converges_faster_than_paper_alternation_to_the_same_optimum(dimensional_case):
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de, y, np.random.default_rng(11))
    start = m.with_values({n: 1.3 * m.parameters[n].value for n in DIM})
    lm = fit(rec, start)
    gn = fit(rec, start, method="gauss-newton")
    paper = fit(rec, start, method="gauss-newton", stop="paper")
    assert lm.converged and gn.converged and paper.converged
    assert lm.iterations <= gn.iterations
    assert "paper's rule" in paper.message and paper.iterations < gn.iterations
    e_lm, se = pick(lm)
    e_gn, _ = pick(gn)
    assert np.all(np.abs(e_lm - e_gn) < 0.01 * se)  # same optimum to a hundredth of a std error


def test_theory_9d_recovers_unsteady_theta_from_noisy_spectra():
    # THEORY.md 9(d): 1 % complex noise, 0.1 rad/s grid, 0.1-10 rad/s: theta within ~2 %
    m = make_model("unsteady", "sundowner")
    data = synthetic_spectra(m, np.random.default_rng(4))
    start = m.with_values({n: 0.8 * m.parameters[n].value for n in m.parameters.free_names})
    # noise independent per frequency: the naive bound is the right one here
    res = fit(data, start, boundary="none", biases=False, cov_type="naive")
    assert res.converged
    for n in m.parameters.free_names:
        true = m.parameters[n].value
        assert abs(res[n] - true) < 3 * res.errors[n], n
        assert abs(res[n] / true - 1) < 0.03, n


def test_steady_fit_of_unsteady_navion_reproduces_theory_section_10():
    # THEORY.md 10: noise-free steady fit of unsteady Navion data: -4.91 -5.50 -0.48 -0.80 -14.58 -1.33
    # (independent scratch code, unknown input); agreement to a few % is what the set-up allows.
    m = make_model("unsteady", "navion")
    data = synthetic_spectra(m, np.random.default_rng(0), noise=0.0)
    cmp = compare_steady_unsteady(data, "navion", boundary="none", biases=False)
    ref = {"Cz_a": -4.91, "Cz_q": -5.50, "Cz_de": -0.48, "Cm_a": -0.80, "Cm_q": -14.58, "Cm_de": -1.33}
    for k, v in ref.items():
        assert cmp.steady_set[k][0] == pytest.approx(v, rel=0.03), k
    # the paper's finding: steady Cm_q more negative, |Cm_a| smaller (WK Table 1)
    assert cmp.shift("Cm_q") < -1.0 and cmp.steady_set["Cm_a"][0] > cmp.unsteady_set["Cm_a"][0]
    assert "shift/sigma" in cmp.table()


def test_outputs_subset_and_multi_record(dimensional_case):
    m, t, de, y = dimensional_case
    r1 = noisy_record(t, de, y, np.random.default_rng(21), name="a")
    r2 = noisy_record(t, de, y, np.random.default_rng(22), name="b")
    one = fit(r1, m, outputs="alpha,q")
    assert one.outputs == ("alpha", "q") and one.R.shape == (2, 2)
    both = fit([r1, r2], m)
    assert "x0_alpha[a]" in both.names and "bias_q[b]" in both.names
    e, se = pick(both)
    assert np.all(np.abs(e - truth(m)) < 3 * se)
    _, se1 = pick(fit(r1, m))
    # twice the data: errors shrink by about sqrt(2)
    assert np.all((se / se1 > 0.55) & (se / se1 < 0.9))


def test_boundary_terms_handle_a_truncated_record(dimensional_case):
    m, t, de, y = dimensional_case
    keep = t <= 2.6  # cut while the response to the 3-2-1-1 is still large
    rec = noisy_record(t[keep], de[keep], y[keep], np.random.default_rng(5))
    with pytest.warns(DataWarning, match="ends far from trim"):
        fit(rec, m, boundary="none")
    res = fit(rec, m, boundary="estimated")
    e, se = pick(res)
    assert np.all(np.abs(e - truth(m)) < 3 * se)


def test_bounds_and_fixed_parameters(dimensional_case):
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de, y, np.random.default_rng(8))
    res = fit(rec, m, bounds={"M_q": (None, -3.0)}, fix={"Z_q": 0.0})
    assert res["M_q"] == pytest.approx(-3.0) and "M_q" in res.at_bound
    assert "Z_q" not in res.names and res.fixed["Z_q"] == 0.0
    assert "at bound" in res.summary()


def test_unidentifiable_parameter_is_named_not_nan(dimensional_case):
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de, y, np.random.default_rng(9)).with_signals(alpha_w=np.zeros_like(t))
    mg = make_model("dimensional", "navion", gust=True)
    with pytest.warns(IdentifiabilityWarning, match="tau_alpha_w"):
        res = fit(rec, mg, free=["tau_alpha_w"])
    i = res.names.index("tau_alpha_w")
    assert math.isinf(res.stderr[i]) and np.all(np.isfinite(res.values))
    assert "not identifiable" in res.summary()


def test_callback_stops_cleanly(dimensional_case):
    m, t, de, y = dimensional_case
    seen = []
    res = fit(
        noisy_record(t, de, y, np.random.default_rng(2)),
        m.with_values(M_a=-20.0),
        callback=lambda info: seen.append(info.iteration) or info.iteration >= 2,
    )
    assert seen == [1, 2] and res.stopped and not res.converged and "callback" in res.message


def test_result_json_roundtrip_is_lossless(dimensional_case, tmp_path):
    m, t, de, y = dimensional_case
    res = fit(noisy_record(t, de, y, np.random.default_rng(2)), m)
    path = tmp_path / "r.json"
    res.to_json(path)
    back = load_result(path)
    assert back.names == res.names
    assert np.array_equal(back.values, res.values) and np.array_equal(back.stderr, res.stderr)
    assert np.array_equal(back.R, res.R) and back.derived == res.derived
    assert np.array_equal(back.spectra[0].z, res.spectra[0].z)
    assert np.allclose(back.fitted_spectra(), res.fitted_spectra(), rtol=1e-14)
    d = json.loads(path.read_text())
    assert d["format"] == "fdml.FitResult" and d["version"] == 2


def test_fitted_spectra_close_to_measured(dimensional_case):
    m, t, de, y = dimensional_case
    res = fit(noisy_record(t, de, y, np.random.default_rng(2), fraction=0.01), m)
    z = res.spectra[0].z
    resid = np.abs(z - res.fitted_spectra())
    assert np.all(resid.mean(axis=0) < 0.1 * np.abs(z).mean(axis=0))  # 1 % noise


def test_bad_inputs_give_named_errors(dimensional_case):
    m, t, de, y = dimensional_case
    good = {"de": de, "alpha": y[:, 0], "q": y[:, 1], "az": y[:, 2]}
    bad = dict(good, q=np.where(t > 3, np.nan, y[:, 1]))
    with pytest.raises(RecordError, match="q has .* NaN"):
        Record(t, bad)
    t2 = t.copy()
    t2[100] += 0.005
    with pytest.raises(RecordError, match="uneven sampling"):
        Record(t2, good)
    with pytest.raises(RecordError, match="not strictly increasing"):
        Record(t[::-1], good)
    with pytest.raises(RecordError, match="missing signal.*az"):
        Record(t, {k: v for k, v in good.items() if k != "az"})
    with pytest.raises(RecordError, match="looks like deg"):
        Record(t, dict(good, alpha=np.degrees(y[:, 0]) + 3.0))
    rec = Record(t, good)
    with pytest.raises(BandError, match="Nyquist"):
        fit(rec, m, band=(0.1, 200.0, 0.1))
    with pytest.raises(BandError, match="too few samples"):
        fit(Record(t[:40], {k: v[:40] for k, v in good.items()}), m, band=(0.1, 5.0, 0.1))
    with pytest.raises(ParameterError, match="unknown parameter 'Cm_alpha'"):
        fit(rec, m, fix={"Cm_alpha": 1.0})
    with pytest.raises(RecordError, match="no alpha_w"):
        fit(rec, make_model("dimensional", "navion", gust=True))
    with pytest.raises(FdmlError, match="unknown output"):
        fit(rec, m, outputs="alpha,nz")
    with pytest.raises(BandError, match=r"LO:HI\[:STEP\]"):
        fit(rec, m, band="0.1-10")


def test_result_keeps_the_time_record(dimensional_case, tmp_path):
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de, y, np.random.default_rng(2))
    res = fit(rec, m)
    back = load_result(tmp_path / "r.json") if res.to_json(tmp_path / "r.json") else None
    for r in (res, back):
        got = r.record(0)
        assert np.array_equal(got.t, rec.t) and np.array_equal(got["q"], rec["q"])
        assert r.spectra[0].trim_mode == "first"


def test_elevator_offset_is_caught_by_input_or_state_biases(dimensional_case):
    # The record's elevator carries a constant 0.002 rad (0.11 deg) offset from the true trim,
    # and the record is taken as perturbations (trim="none"), with measured boundary terms.
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de + 0.002, y, np.random.default_rng(12))
    kw = dict(trim="none", boundary="measured", biases=False)
    plain = fit(rec, m, **kw)
    ib = fit(rec, m, input_bias=True, **kw)
    assert ib.cost < 0.5 * plain.cost  # the offset explains a large part of the residual
    e1, se1 = pick(ib)
    assert np.all(np.abs(e1 - truth(m)) < 3 * se1)
    assert abs(ib["bias_de"] + 0.002) < 3 * ib.errors["bias_de"]  # the model needs de - 0.002
    sb = fit(rec, m, state_biases=True, **kw)
    e2, se2 = pick(sb)
    assert np.all(np.abs(e2 - truth(m)) < 3 * se2)
    # the state-equation biases are the elevator offset pushed through B = (Z_de, M_de)
    p = m.parameters.values
    assert abs(sb["bias_q_dot"] + 0.002 * p["M_de"]) < 3 * sb.errors["bias_q_dot"]
    assert sb.nuisance["state_biases"] and "state-equation biases" in str(sb.summary())


def test_input_bias_with_estimated_boundary_and_output_biases_is_flagged(dimensional_case):
    # A constant input offset is exactly a shifted trim: its response is a boundary term plus an
    # output bias (partial fractions of G(s)/s), so with both estimated it cannot be identified.
    m, t, de, y = dimensional_case
    with pytest.warns(IdentifiabilityWarning, match="bias_de"):
        res = fit(noisy_record(t, de, y, np.random.default_rng(3)), m, input_bias=True)
    assert math.isinf(res.errors["bias_de"])


@pytest.mark.slow
def test_colored_bounds_follow_coloured_noise(dimensional_case):
    # band-pass noise where the short period lives (0.3-0.8 Hz): the white-noise form
    # understates the scatter, the coloured form (smoothed residual spectrum) much less so
    from scipy import signal

    m, t, de, y = dimensional_case
    b, a = signal.butter(2, [0.3, 0.8], btype="band", fs=50)
    est, sw, sc = [], [], []
    for i in range(40):
        rng = np.random.default_rng(900 + i)
        e = signal.lfilter(b, a, rng.normal(size=(y.shape[0] + 200, 3)), axis=0)[200:]
        yn = y + e / e.std(axis=0) * 0.05 * y.std(axis=0)
        rec = Record(t, {"de": de, "alpha": yn[:, 0], "q": yn[:, 1], "az": yn[:, 2]})
        w = fit(rec, m)
        c = fit(rec, m, cov_type="colored")
        est.append(pick(w)[0])
        sw.append(pick(w)[1])
        sc.append(pick(c)[1])
    scatter = np.array(est).std(axis=0, ddof=1)
    rw, rc = scatter / np.mean(sw, axis=0), scatter / np.mean(sc, axis=0)
    # Z_a and M_a: white understates by about 1.5; coloured within the 25 % + sampling (~11 % for 40)
    assert rw[0] > 1.3 and rw[3] > 1.3
    assert np.all(np.abs(rc - 1) < 0.35), rc


def test_consistency_of_repeated_manoeuvres(dimensional_case):
    from fdml.consistency import consistency

    m, t, de, y = dimensional_case
    fits = [fit(noisy_record(t, de, y, np.random.default_rng(40 + i), name=f"m{i}"), m) for i in range(4)]
    c = consistency(fits)
    assert c.names == DIM and c.dof == 3
    assert c.agree()  # same truth, honest bounds
    # a different aircraft state in one manoeuvre (M_a 10 % off) is flagged on M_a
    from conftest import lsim_dimensional

    m2 = m.with_values(M_a=1.1 * m.parameters["M_a"].value)
    odd = fit(noisy_record(t, de, lsim_dimensional(m2, t, de), np.random.default_rng(50), name="odd"), m)
    c2 = consistency(fits + [odd])
    assert not c2.agree() and c2.p_value[DIM.index("M_a")] < 1e-6
    assert "DISAGREE" in c2.summary()


@pytest.mark.parametrize("kind", ["dimensional", "derivatives", "steady", "unsteady"])
def test_analytic_and_eq26_sensitivities_agree_to_six_figures(kind):
    from fdml.record import add_noise
    from fdml.simulate import simulate_maneuver

    truth = make_model("unsteady", "navion")
    rec = add_noise(
        simulate_maneuver(truth, "3211", duration=10.0, dt=0.02), 0.02, np.random.default_rng(5), relative=True
    )
    m = make_model(kind, "navion")
    a = fit(rec, m, sensitivity="analytic", tol=1e-6)
    f = fit(rec, m, sensitivity="fd", tol=1e-6)
    assert a.names == f.names
    # estimates: Eq. 26 columns settled to 1e-4 move the fixed point by ~1e-4 of the (noise-sized)
    # gradient terms, i.e. a few 1e-5 standard errors, far below 1e-6 of the values
    assert np.all(np.abs(a.values - f.values) <= 1e-6 * np.abs(a.values) + 1e-4 * a.stderr)
    # bounds: the final columns are central differences settled to ~1e-10
    assert np.allclose(a.stderr, f.stderr, rtol=1e-6, atol=0)


@pytest.mark.slow
def test_monte_carlo_unsteady_model_from_the_time_domain_simulator():
    # the unsteady model, F term included, simulated in the time domain (independent of the
    # frequency-domain model), 50 noise draws: scatter within 25 % of the mean standard error
    from fdml.record import add_noise
    from fdml.simulate import simulate_maneuver

    m = make_model("unsteady", "navion")
    clean = simulate_maneuver(m, "3211", duration=12.0, dt=0.02)
    theta = m.parameters.free_names
    est, se = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifiabilityWarning)
        for i in range(50):
            res = fit(add_noise(clean, 0.03, np.random.default_rng(7000 + i), relative=True), m)
            est.append([res[n] for n in theta])
            se.append([res.errors[n] for n in theta])
    est, se = np.array(est), np.array(se)
    ratio = est.std(axis=0, ddof=1) / se.mean(axis=0)
    assert np.all((ratio > 0.75) & (ratio < 1.25)), dict(zip(theta, ratio))
    truth = np.array([m.parameters[n].value for n in theta])
    # the simulator matches the model to ~1e-4, far inside the noise: the mean recovers the truth
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * est.std(axis=0) / math.sqrt(50))


def test_fit_refuses_an_input_without_power_in_the_band():
    """A constant elevator: refused before fitting, naming the record and the band (issue 9), not
    fitted into Cm_de = -2.9e137; the measure is fdml.quality's, so fdml check says the same."""
    from fdml.errors import RecordError
    from fdml.quality import check_quality
    from fdml.simulate import simulate_maneuver

    m = make_model("dimensional", "navion")
    rec = simulate_maneuver(m, "3211", duration=10.0, noise=0.02, seed=2)
    flat = Record(rec.t, {**rec.signals, "de": np.full(rec.n, 0.01)}, name="flat elevator")
    with pytest.raises(RecordError, match=r"'flat elevator'.*no power in the band 0\.2-8 rad/s"):
        fit(flat, m, band=(0.2, 8.0, 0.2))
    assert not check_quality(flat, (0.2, 8.0, 0.2)).sufficient
    # an input whose power lies far above the band: more than 40 dB down throughout it
    fast = Record(rec.t, {**rec.signals, "de": 0.01 * np.sin(60.0 * rec.t)}, name="fast")
    with pytest.raises(RecordError, match="'fast'.*no power in the band"):
        fit(fast, m, band=(0.2, 2.0, 0.2))


def _direct_sums_everywhere(monkeypatch):
    """Every record's white noise through the adjoint transform (the direct sums), as beyond gram_max."""
    import dataclasses

    from fdml import estimate

    monkeypatch.setattr(estimate, "SETTINGS", dataclasses.replace(estimate.SETTINGS, gram_max=0))


@pytest.mark.parametrize(
    "case",
    [
        dict(boundary="estimated"),
        dict(boundary="measured"),  # the noise of the measured x(0), x(T): rows 0, n - 1 and the trim
        dict(boundary="measured", trim="mean", outputs="q,az"),
        dict(boundary="none", cov_type="colored"),
    ],
)
def test_white_covariance_in_closed_form_equals_the_direct_sums(dimensional_case, monkeypatch, case):
    # two records of different lengths on an uneven grid: the closed-form Gram matrices (and, for measured
    # boundary values, their correction on a few samples) against the adjoint transform over every sample.
    # Both are exact; they differ by rounding in sums of ~n m terms (~1e-13 of the largest entry)
    m, t, de, y = dimensional_case
    rng = np.random.default_rng(11)
    recs = [noisy_record(t, de, y, rng, name="a"), noisy_record(t[:401], de[:401], y[:401], rng, name="b")]
    om = np.sort(np.r_[np.linspace(0.3, 9.0, 45), 1.234, 5.55])
    res = fit(recs, m, omega=om, adequacy=False, check=False, **case)
    assert res.options["noise_covariance"] == {"a": "closed form", "b": "closed form"}
    _direct_sums_everywhere(monkeypatch)
    ref = fit(recs, m, omega=om, adequacy=False, check=False, **case)
    assert set(ref.options["noise_covariance"].values()) == {"direct sum: adjoint transform (more than 0 frequencies)"}
    assert np.array_equal(res.values, ref.values)  # the iteration does not see the route
    assert np.abs(res.cov - ref.cov).max() <= 1e-12 * np.abs(ref.cov).max()
    assert np.allclose(res.stderr, ref.stderr, rtol=1e-11, atol=0)
    if case["boundary"] == "estimated":  # the naive bound carries no noise: no route to name
        naive = fit(recs, m, omega=om, adequacy=False, check=False, cov_type="naive")
        assert "noise_covariance" not in naive.options


def test_trust_region_shift_puts_the_step_on_the_regions_edge():
    """_shift_for solves Moré and Sorensen's secular equation: against its closed forms."""
    from fdml.estimate import _shift_for

    # one dimension: |c| / (w + mu) = radius gives mu = |c| / radius - w exactly
    assert _shift_for(np.array([3.0]), np.array([0.5]), 0.0, 2.0) == pytest.approx(3.0 / 2.0 - 0.5, rel=1e-6)
    # the unconstrained (least-shift) step inside the region: no further shift
    assert _shift_for(np.array([0.1, 0.2]), np.array([1.0, 2.0]), 0.0, 10.0) == 0.0
    # an indefinite case: the step lands on the edge (Newton's iteration stops within 1e-6 relative)
    rng = np.random.default_rng(4)
    c, w = rng.normal(size=6), np.array([-0.3, 0.01, 0.5, 1.0, 2.0, 3.0])
    least = 2 * 0.3 + 1e-8 * 3.0
    mu = _shift_for(c, w, least, 0.7)
    assert mu >= least
    assert np.linalg.norm(c / (w + mu)) == pytest.approx(0.7, rel=1e-6)


def test_short_ill_conditioned_records_converge():
    """4 s records (10 frequencies, 12 parameters, correlations near 1): the trust region follows the
    long, slightly indefinite valleys.  The shifted Newton step that restarted at the smallest shift each
    pass hit the 200-pass cap on 10 of these 12 draws; the trust region on 2 (it crawls there too: the
    model is nearly unidentifiable from 10 frequencies).  Three quarters leave room for one more."""
    model = make_model("steady", "navion")
    from fdml.simulate import simulate_maneuver

    converged = 0
    for seed in range(1, 13):
        rec = simulate_maneuver(model, "3211", duration=4.0, dt=0.02, noise=0.02, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            converged += fit(rec, model, band="0.5:5:0.5", check=False, adequacy=False).converged
    assert converged >= 9


def test_an_uphill_newton_prediction_is_not_the_floating_point_floor():
    """With an indefinite concentrated Hessian H the Newton step's quadratic model predicts a rise of
    ln det R, not a decrease below the rounding; the floor test reads the Gauss-Newton step halved
    instead (g H1^-1 g / 2^11, positive), so a pass that found no decrease is not taken for the floor."""
    from fdml.estimate import _least_resolved

    g = np.array([1.0, -2.0])
    H1 = np.diag([2.0, 1.0])
    H = np.diag([2.0, -1.0])
    step_n = -np.linalg.solve(H, g)  # the Newton step: 0.5 * step.H.step + g.step = -g H^-1 g / 2 > 0 here: a rise
    assert -(g @ step_n + 0.5 * step_n @ H @ step_n) < 0
    least = _least_resolved(g, H1, H, np.ones(2, bool), step_n, True)
    assert least == pytest.approx((0.5 + 4.0) * 0.5**11)


def test_a_strongly_indefinite_first_pass_finds_its_way_when_gauss_newton_cannot():
    """Sundowner, q and theta fitted with a q delay (40 ms in the truth).  The first pass's concentrated
    Hessian is strongly indefinite, so the Gauss-Newton step goes first, and at every length it raised
    the cost.  That used to end the fit at its start as 'converged at the floating-point floor', with the
    delay at its null, five standard errors from the truth; the shifted steps now take it there in one
    pass.  (The derivatives are only partly identifiable from q and theta, which the fit says.)"""
    from fdml.maneuvers import three_two_one_one, time_vector
    from fdml.models import with_effects
    from fdml.record import add_noise
    from fdml.simulate import simulate

    base = make_model("dimensional", "sundowner", outputs=("alpha", "q", "az", "theta", "qdot"))
    t = time_vector(12.0, 0.02)
    truth = with_effects(base, "time_delay:q").with_values({"tau_q": 0.04})
    rec = simulate(truth, t, {"de": three_two_one_one(t, amplitude=0.02, start=1.0, unit=0.5, rise=0.1)})
    rec = add_noise(rec, 0.01, np.random.default_rng(1), relative=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # identifiability and convergence warnings: the valley is long
        res = fit(rec, with_effects(base, "time_delay:q"), band=(0.3, 10, 0.1), outputs="q,theta", max_iter=3)
    assert "floor" not in res.message
    assert abs(res.params["tau_q"] - 0.04) < 5 * res.errors["tau_q"]
