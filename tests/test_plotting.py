"""Plots: return types, axes, ax= honoured, no show(), Hz scaling, the CRB band, a fair time-domain overlay."""

import dataclasses
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

import fdml  # noqa: E402
from fdml.plotting import (  # noqa: E402
    plot_correlation,
    plot_residual_spectra,
    plot_spectra,
    plot_time_histories,
    simulate_fit,
    spectra_uncertainty,
)
from fdml.record import Record, add_noise  # noqa: E402
from fdml.simulate import simulate_maneuver  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")


@pytest.fixture(autouse=True)
def no_show(monkeypatch):
    def fail(*a, **k):
        raise AssertionError("plotting code must never call show()")

    monkeypatch.setattr(plt, "show", fail)
    monkeypatch.setattr(Figure, "show", fail)
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def res():
    truth = fdml.make_model("derivatives", "navion")
    r = simulate_maneuver(truth, "3211", duration=10.0, dt=0.02)
    r = add_noise(r, 0.02, np.random.default_rng(5), relative=True)
    return fdml.fit(r, truth, band=(0.2, 8, 0.2))


def _band(coll, x):
    """(lower, upper) of a fill_between collection at the abscissae x."""
    v = np.vstack([p.vertices for p in coll.get_paths()])
    lo = np.array([v[np.isclose(v[:, 0], xi), 1].min() for xi in x])
    hi = np.array([v[np.isclose(v[:, 0], xi), 1].max() for xi in x])
    return lo, hi


# --- spectra ----------------------------------------------------------------------------------


def test_plot_spectra_figure_and_axes(res):
    fig, axes = plot_spectra(res)
    assert isinstance(fig, Figure) and axes.shape == (2, 3)
    assert [a.get_title() for a in axes[0]] == ["alpha", "q", "az"]
    m = res.spectra[0].omega.size
    k = 1
    meas, fitted = axes[0, k].lines[:2]
    np.testing.assert_allclose(meas.get_ydata(), np.abs(res.spectra[0].z[:, k]))
    np.testing.assert_allclose(fitted.get_ydata(), np.abs(res.fitted_spectra()[:, k]))
    assert len(meas.get_xdata()) == m


def test_plot_spectra_honours_axes_and_hz(res):
    fig0, axs = plt.subplots(2, 2)
    fig, axes = plot_spectra(res, outputs=["alpha", "az"], freq_unit="Hz", axes=axs)
    assert fig is fig0 and axes[1, 1] is axs[1, 1]
    w = res.spectra[0].omega
    for a in axes.flat:
        np.testing.assert_allclose(a.lines[0].get_xdata(), w / (2 * np.pi), rtol=1e-15)
    assert axes[1, 0].get_xlabel() == "frequency (Hz)"
    fig1, axs1 = plt.subplots(2, 2)
    fig, axes = plot_spectra(res, outputs=["alpha", "az"], ax=axs1)  # ax= is an alias
    assert fig is fig1
    with pytest.raises(ValueError, match="needs 6 axes"):
        plot_spectra(res, axes=axs1[0])
    with pytest.raises(ValueError, match="freq_unit"):
        plot_spectra(res, freq_unit="kHz")


def test_crb_band_brackets_the_fit_and_scales_with_the_standard_errors(res):
    fig, axes = plot_spectra(res, sigma=2.0)
    f = res.spectra[0].omega
    y, sd = spectra_uncertainty(res)
    np.testing.assert_allclose(y, res.fitted_spectra())
    assert np.all(sd > 0)
    widths = []
    for k in range(3):
        a = np.abs(y[:, k])
        lo, hi = _band(axes[0, k].collections[0], f)
        assert np.all(lo <= a) and np.all(a <= hi) and np.all(hi > a)
        np.testing.assert_allclose(hi - a, 2.0 * sd[:, k], rtol=1e-9)
        widths.append(hi - a)
        plo, phi = _band(axes[1, k].collections[0], f)  # phase band brackets the phase curve
        ph = axes[1, k].lines[1].get_ydata()
        assert np.all(plo <= ph + 1e-9) and np.all(ph <= phi + 1e-9)
    # four times the covariance: twice the standard errors (derived from it), twice the band
    res4 = dataclasses.replace(res, cov=4.0 * res.cov)
    np.testing.assert_array_equal(res4.stderr, 2.0 * res.stderr)
    _, sd4 = spectra_uncertainty(res4)
    np.testing.assert_allclose(sd4, 2.0 * sd, rtol=1e-9)
    fig4, axes4 = plot_spectra(res4, sigma=2.0)
    for k in range(3):
        lo, hi = _band(axes4[0, k].collections[0], f)
        np.testing.assert_allclose(hi - np.abs(y[:, k]), 2.0 * widths[k], rtol=1e-9)


def test_band_of_one_output_bias_is_exact(res):
    """Only bias_alpha uncertain: sd(alpha~) = sigma_b |ones~(w)|, nothing on q and az."""
    i = res.names.index("bias_alpha")
    cov = np.zeros_like(res.cov)
    cov[i, i] = 1e-6
    _, sd = spectra_uncertainty(dataclasses.replace(res, cov=cov))
    np.testing.assert_allclose(sd[:, 0], 1e-3 * np.abs(res.spectra[0].ones), rtol=1e-6)
    assert np.all(sd[:, 1:] == 0)


def test_plot_spectra_several_fits_and_db(res):
    other = dataclasses.replace(res, values=res.values * 1.0)
    fig, axes = plot_spectra([res, other], ["a", "b"], mag_unit="dB", crb=False)
    assert len(axes[0, 0].lines) == 3 and not axes[0, 0].collections
    assert "dB" in axes[0, 0].get_ylabel()
    np.testing.assert_allclose(axes[0, 0].lines[0].get_ydata(), 20 * np.log10(np.abs(res.spectra[0].z[:, 0])))


# --- time histories -------------------------------------------------------------------------


def test_plot_time_histories(res):
    fig, axes = plot_time_histories(res)
    assert isinstance(fig, Figure) and axes.shape == (4,)
    assert axes[-1].get_xlabel() == "time (s)"
    rec = res.record(0)
    model_line, meas_line = axes[1].lines[:2]
    np.testing.assert_allclose(meas_line.get_ydata(), np.degrees(rec["alpha"]))
    err = model_line.get_ydata() - meas_line.get_ydata()
    assert np.sqrt(np.mean(err**2)) < 0.05 * np.ptp(meas_line.get_ydata())  # the noise level, 2 %
    fig0, axs = plt.subplots(2, 1)
    fig, axes = plot_time_histories(res, outputs=["q"], axes=axs, angle_unit="rad")
    assert fig is fig0 and axes[1] is axs[1]
    np.testing.assert_allclose(axes[1].lines[1].get_ydata(), rec["q"])
    fig, axes = plot_time_histories(res, inputs=False)
    assert axes.shape == (3,)


@pytest.mark.parametrize(
    "kind, opts, trim, window",
    [
        ("dimensional", {}, "first", None),  # trim added back, x0 = 0
        ("derivatives", {"adot": True}, "none", (1.5, 11.5)),  # starts mid-manoeuvre: x0 != 0, E != I
        ("steady", {}, "mean", None),
    ],
)
def test_time_domain_overlay_is_fair(kind, opts, trim, window):
    """Noise-free record of the model itself: the overlay reproduces it (trim, biases, x(0))."""
    truth = fdml.make_model(kind, "navion", **opts)
    if opts.get("adot"):
        truth = truth.with_values(Cz_adot=-1.0, Cm_adot=-4.0)
    r = simulate_maneuver(truth, "3211", duration=12.0, dt=0.02)
    if window:
        r = r.window(*window)
    offsets = {"de": 0.01, "alpha": 0.05, "q": 0.002, "az": 1.0}  # a trim the fit removes
    r = Record(r.t, {k: v + offsets[k] for k, v in r.signals.items()}, name="trimmed", check_units=False)
    if trim == "none":  # the record is already perturbations about an equilibrium
        r = Record(r.t, {k: v - offsets[k] for k, v in r.signals.items()}, name="pert", check_units=False)
    fit = fdml.fit(r, fdml.make_model(kind, "navion", **opts), band=(0.2, 10, 0.1), trim=trim)
    m = simulate_fit(fit)
    if window:
        assert max(abs(x) for x in m.meta["x0"]) > 0.01
    for o in ("alpha", "q", "az"):
        span = np.ptp(r[o])
        assert np.max(np.abs(m[o] - r[o])) < 2e-3 * span, o


def test_time_histories_need_time_records(res):
    with pytest.raises(fdml.FdmlError, match="no time-domain records"):
        plot_time_histories(res.without_records())


# --- residual spectra ------------------------------------------------------------------------


def test_plot_residual_spectra(res):
    fig, axes = plot_residual_spectra(res, freq_unit="Hz")
    assert isinstance(fig, Figure) and axes.shape == (3,)
    w = res.spectra[0].omega
    v = res.spectra[0].z - res.fitted_spectra()
    for k, a in enumerate(axes):
        np.testing.assert_allclose(a.lines[0].get_xdata(), w / (2 * np.pi))
        np.testing.assert_allclose(a.lines[0].get_ydata(), np.abs(v[:, k]))
        floor = a.lines[1].get_ydata()[0]
        assert floor == pytest.approx(math.sqrt(res.R[k, k].real))
        # the floor is the RMS of the residuals (Eq. 24 with one record)
        assert floor == pytest.approx(np.sqrt(np.mean(np.abs(v[:, k]) ** 2)), rel=1e-6)
    fig0, ax0 = plt.subplots(1, 2)
    fig, axes = plot_residual_spectra(res, outputs=["q", "az"], ax=ax0)
    assert fig is fig0 and axes[0] is ax0[0] and axes[0].get_title() == "q"


# --- correlation ---------------------------------------------------------------------------------


def test_plot_correlation(res):
    fig, ax = plot_correlation(res)
    n = len(res.names)
    img = ax.images[0].get_array()
    np.testing.assert_allclose(np.ma.filled(img, np.nan), res.corr)
    assert len(ax.texts) == n * n
    assert [t.get_text() for t in ax.get_xticklabels()] == list(res.names)
    fig0, ax0 = plt.subplots()
    fig, ax = plot_correlation(res, nuisance=False, ax=ax0, colorbar=False, annotate=False)
    assert fig is fig0 and ax is ax0
    assert [t.get_text() for t in ax.get_yticklabels()] == ["Cz_a", "Cz_q", "Cz_de", "Cm_a", "Cm_q", "Cm_de"]
    with pytest.raises(ValueError, match="not estimated"):
        plot_correlation(res, names=["Cz_a", "nope"])


@pytest.mark.slow
def test_overlay_of_a_joint_fit_with_an_elevator_bias():
    """Two records fitted together, each with its own nuisance terms; an elevator trim error."""
    from fdml.simulate import simulate

    truth = fdml.make_model("derivatives", "navion")
    recs = []
    for name, man in (("a", "3211"), ("b", "doublet")):
        r = simulate_maneuver(truth, man, duration=10.0, dt=0.02)
        sim = simulate(truth, r.t, {"de": r["de"] + 0.002})  # the true elevator is 0.002 rad off
        recs.append(
            Record(
                r.t,
                {"de": r["de"] + 0.01, "alpha": sim["alpha"] + 0.05, "q": sim["q"], "az": sim["az"] + 1.0},
                name=name,
                check_units=False,
            )
        )
    fit = fdml.fit(recs, truth, band=(0.2, 8, 0.2), input_bias=True)
    assert "bias_de[b]" in fit.names
    for i, r in enumerate(recs):
        m = simulate_fit(fit, i)
        assert m.meta["elevator_bias"] == pytest.approx(0.002, rel=0.05)
        for o in ("alpha", "q", "az"):
            assert np.max(np.abs(m[o] - r[o])) < 2e-3 * np.ptp(r[o]), (i, o)
        y, sd = spectra_uncertainty(fit, i)
        np.testing.assert_allclose(y, fit.fitted_spectra(i))
        assert np.all(np.isfinite(sd))
