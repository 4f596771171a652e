"""Figures as a user sees them (issue 21): nothing clipped, no label over a neighbour, no legend over data
(tests/figure_checks.py), phase on one branch for data and fits, and the figures say what they show."""

import dataclasses
import math
from unittest import mock

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from figure_checks import assert_layout  # noqa: E402

import fdml  # noqa: E402
import fdml.outputs  # noqa: E402
from fdml.models import with_effects
from fdml.plotting import plot_spectra  # noqa: E402
from fdml.record import add_noise  # noqa: E402
from fdml.report import write_report  # noqa: E402
from fdml.simulate import simulate_maneuver  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")
BAND = (0.2, 8.0, 0.2)


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def record():
    truth = fdml.make_model("unsteady", "navion")
    rec = simulate_maneuver(truth, "3211", duration=10.0, dt=0.02)
    return add_noise(rec, 0.02, np.random.default_rng(5), relative=True)


@pytest.fixture(scope="module")
def fit_with_effect(record):
    """A fit whose correlation matrix has long row labels (tau_alpha, bias_alpha, x0_alpha)."""
    model = with_effects(fdml.make_model("derivatives", "navion"), "time_delay:alpha")
    return fdml.fit(record, model, band=BAND)


def _report_figures(res, tmp_path) -> dict:
    """The figures write_report saves, by file stem (captured as they are saved, at the report's 110 dpi)."""
    figs = {}
    save = fdml.outputs.StagedOutputs.savefig

    def keep(self, fig, path, **kw):
        figs[path.stem] = fig
        return save(self, fig, path, **kw)

    with mock.patch.object(fdml.outputs.StagedOutputs, "savefig", keep):
        write_report(res, tmp_path / "report", dpi=110)
    return figs


def _phases(ax):
    """(data, fits) of a phase panel: the points first, then each fit's line."""
    lines = ax.get_lines()
    return np.asarray(lines[0].get_ydata()), [np.asarray(line.get_ydata()) for line in lines[1:]]


# --- layout ---------------------------------------------------------------------------------------


@pytest.mark.slow
def test_report_figures_show_every_text_and_keep_legends_off_the_data(fit_with_effect, tmp_path):
    figs = _report_figures(fit_with_effect, tmp_path)
    assert set(figs) == {"spectra", "time_histories", "residual_spectra", "correlation"}
    for name, fig in figs.items():
        assert_layout(fig), name


def test_compare_figure(record):
    from fdml.compare import compare_steady_unsteady

    cmp = compare_steady_unsteady(record, "navion", band=BAND)
    fig = cmp.plot()
    assert_layout(fig)
    # steady and unsteady fits and the data share a branch in every phase panel
    for ax in fig.axes[3:6]:
        data, fits = _phases(ax)
        assert np.max(np.abs(fits[0] - fits[1])) < 180 and np.max(np.abs(data - fits[0])) < 180


@pytest.mark.slow
def test_diagnose_figure_fits_its_text_and_explains_the_gap_map(tmp_path):
    from fdml.diagnose import diagnose
    from fdml.diagnose.truth import simulate_truth

    base = fdml.make_model("steady", "navion")
    rec = simulate_truth(base, "time_delay@q", {"tau_q": 0.04}, maneuver="3211", noise=0.04, seed=1)
    rep = diagnose(rec, base, band=(0.3, 12.0), max_effects=1)
    fig = rep.plot()
    assert_layout(fig)
    text = " ".join(t.get_text().replace("\n", " ") for ax in fig.axes for t in ax.texts)
    # the cells' numbers are explained, negative ones included
    assert "excess coherent energy" in text and "noise floor" in text and "negative values" in text
    assert "* significant" in text


@pytest.mark.slow
def test_design_figure_has_a_title_lambda_and_p_compare():
    from fdml.design import design, plot_design

    d = design(fdml.make_model("unsteady", "navion"), duration=6.0, dt=0.05, band="0.5:8", refine=0)
    fig = plot_design(d)
    assert_layout(fig)
    title = fig.get_suptitle()
    assert d.criterion in title and d.input.name in title and "0.5-8 rad/s" in title
    entries = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    for name, disc in d.discrimination.items():
        assert f"{name}: lambda {disc.noncentrality:.3g}, P(compare) {disc.vuong:.2f}" in entries, entries


# --- phase on one branch -----------------------------------------------------------------------------


def test_spectra_phase_puts_the_data_on_the_fit_branch(record):
    """Data within 6 deg of the fit plot within 6 deg of it, also where the fit's phase starts at the +-180 cut."""
    res = fdml.fit(record, fdml.make_model("derivatives", "navion"), band=BAND)
    spec = res.spectra[0]
    y = res.fitted_spectra()
    ref = np.exp(-1j * np.angle(spec.u[:, 0]))
    first = np.degrees(np.angle(y[0] * ref[0]))  # alpha and q start near -180 deg (a nose-down response)
    assert np.min(180 - np.abs(first[:2])) < 6
    delta = np.radians(6.0) * np.random.default_rng(0).uniform(-1, 1, y.shape)
    delta[0, :2] = np.sign(first[:2]) * np.radians(6.0)  # the first point pushed across the cut from the fit
    moved = dataclasses.replace(res, spectra=(dataclasses.replace(spec, z=y * np.exp(1j * delta)),))
    fig, axes = plot_spectra(moved, crb=False)
    for ax in axes[1]:
        data, (fit,) = _phases(ax)
        assert np.max(np.abs(data - fit)) <= 6.0 + 1e-9
        assert np.max(np.abs(np.diff(fit))) < 180  # the fit itself unwrapped along frequency


def test_real_record_fit_looks_like_one():
    """Twin Otter 017, the default band: data and fit on one branch (the alpha fit wrapped to -330 deg)."""
    from fdml.io import data_path, load_record

    rec = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
    res = fdml.fit(rec, fdml.make_model("dimensional", airspeed=rec.meta["U"]))
    fig, axes = plot_spectra(res)
    for ax in axes[1]:
        data, (fit,) = _phases(ax)
        diff = np.abs(data - fit)
        # off the fit only at the input's spectral nulls (noise over a vanishing elevator spectrum)
        assert np.max(diff) <= 180 and np.median(diff) < 10, ax.get_ylabel()
    assert_layout(fig)


def test_phase_on_one_branch_closed_form():
    """A pure delay, exp(-j w tau), unwraps to -w tau; a copy 10 deg off sits 10 deg off, not 350."""
    from fdml.plotting import phase_on_one_branch

    w = np.linspace(0.1, 10, 200)
    tau = 0.9  # rad/s * s: 9 rad at the top, several turns of the principal value
    ref = np.exp(-1j * w * tau)
    base, other = phase_on_one_branch(ref, ref * np.exp(1j * math.radians(10.0)))
    np.testing.assert_allclose(base, np.degrees(-w * tau), atol=1e-9)
    np.testing.assert_allclose(other - base, 10.0, atol=1e-9)
