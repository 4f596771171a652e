"""Figures of fits, with matplotlib (imported only when a plot is made).

=============================  =====================================================
:func:`plot_spectra`           measured against model output spectra, magnitude and
                               phase per output (WK Figs. 3-5), with the Cramer-Rao
                               band of the fitted spectrum
:func:`plot_time_histories`    measured time histories against the model simulated
                               in the time domain from the estimate
:func:`plot_residual_spectra`  ``|residual|`` per output against frequency, with the
                               noise floor implied by R
:func:`plot_correlation`       the parameter correlation matrix as a heat map
=============================  =====================================================

Every function takes ``ax=`` / ``axes=`` (or makes its own figure), returns
``(figure, axes)`` and never calls ``show()``.  Frequency axes are in rad/s
or, with ``freq_unit="Hz"``, in Hz.  Two computations behind the figures are
public: :func:`spectra_uncertainty` (the band) and :func:`simulate_fit` (the
time-domain model response of a fit).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from .channels import OUTPUTS, boundary_channels
from .fit_options import known_outputs

__all__ = [
    "plot_spectra",
    "plot_time_histories",
    "plot_residual_spectra",
    "plot_correlation",
    "spectra_uncertainty",
    "simulate_fit",
    "phase_on_one_branch",
    "figure_legend",
    "settle_layout",
]

#: Each output's symbol and its transform's unit.
_LABELS = {
    "alpha": r"$\tilde\alpha$ (rad s)",
    "q": r"$\tilde q$ (rad)",
    "az": r"$\tilde a_z$ (g s)",
    "theta": r"$\tilde\theta$ (rad s)",
    "qdot": r"$\tilde{\dot q}$ (rad/s)",
}
_NAMES = {"alpha": r"$\alpha$", "q": r"$q$", "az": r"$a_z$", "theta": r"$\theta$", "qdot": r"$\dot q$"}
_DEG = 180.0 / math.pi


def _freq(omega: np.ndarray, unit: str):
    if unit == "rad/s":
        return omega, "frequency (rad/s)"
    if unit == "Hz":
        return omega / (2 * np.pi), "frequency (Hz)"
    raise ValueError(f"freq_unit must be 'rad/s' or 'Hz', got {unit!r}")


def _axes_grid(axes, ax, shape: tuple[int, int], figsize):
    """(figure, axes array of ``shape``, created) from user axes or a new (constrained-layout) figure."""
    if axes is not None and ax is not None:
        raise ValueError("give axes= or ax=, not both")
    given = axes if axes is not None else ax
    if given is None:
        import matplotlib.pyplot as plt

        fig, arr = plt.subplots(*shape, figsize=figsize, sharex=True, squeeze=False, layout="constrained")
        return fig, arr, True
    arr = np.asarray(given, dtype=object)
    n = shape[0] * shape[1]
    if arr.size != n:
        raise ValueError(f"this figure needs {n} axes {shape}, got {arr.size}")
    arr = arr.reshape(shape)
    return arr.flat[0].figure, arr, False


def _plain_log_ticks(axis) -> None:
    """Label a log axis with plain numbers (0.02, 0.1) instead of mathtext (2 x 10^-2).

    Mathtext tick labels cost most of the drawing time of a spectra figure.
    """
    from matplotlib import ticker

    class _Plain(ticker.LogFormatter):
        def _num_to_string(self, x, vmin, vmax):
            return f"{x:.3g}"

    axis.set_major_formatter(_Plain())
    axis.set_minor_formatter(_Plain(labelOnlyBase=False, minor_thresholds=(2, 0.5)))


def phase_on_one_branch(reference, *others) -> list[np.ndarray]:
    """Phases, deg, of a reference response and of others, all on one branch.

    The reference (a model's response, smooth along frequency) is unwrapped
    along frequency from its principal value at the first frequency; each
    other response (data, or another model of the same data) is placed point
    by point on the branch nearest the reference, ``ref + angle(other/ref)``.
    A response within 180 deg of the reference is then drawn beside it, so a
    good fit looks like one: two separate unwraps part by 360 deg wherever
    noise or a near-zero magnitude makes them take different branches.

    Parameters
    ----------
    reference : array_like, complex, shape (m,)
        The response the branch follows, in frequency order.
    *others : array_like, complex, shape (m,)
        Responses at the same frequencies.

    Returns
    -------
    list of ndarray
        The reference's phase, then each other's, deg.
    """
    ref = np.asarray(reference, complex)
    base = np.unwrap(np.angle(ref))
    return [np.degrees(base)] + [np.degrees(base + np.angle(np.asarray(o, complex) * np.conj(ref))) for o in others]


def figure_legend(fig, axes, *, side: str = "lower", **kw):
    """One legend for the whole figure, above or below its axes, with the entries of ``axes`` (duplicates once).

    Under constrained layout (every figure fdml makes) the legend gets its own
    room outside the axes, so it covers no data.  In a figure without it, the
    legend goes to the first axes at its emptiest place instead.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    axes : iterable of Axes
        Where the entries come from.
    side : {"lower", "upper"}, optional
        Below the axes (default) or above them (under the figure's title).
    **kw
        Passed to :meth:`~matplotlib.figure.Figure.legend` (``ncol``, ``fontsize``).

    Returns
    -------
    matplotlib.legend.Legend or None
        The legend (None when there is nothing to show).
    """
    axes = list(axes)
    entries: dict = {}  # label -> its first handle
    for a in axes:
        for h, lab in zip(*a.get_legend_handles_labels()):
            entries.setdefault(lab, h)
    if not entries:
        return None
    handles, labels = list(entries.values()), list(entries)
    opts = {"fontsize": "small", "ncol": min(len(labels), 5), **kw}
    engine = fig.get_layout_engine()
    if engine is not None and type(engine).__name__ == "ConstrainedLayoutEngine":
        return fig.legend(handles, labels, loc=f"outside {side} center", **opts)
    return axes[0].legend(handles, labels, loc="best", **{k: v for k, v in opts.items() if k != "ncol"})


def settle_layout(fig) -> None:
    """Tight layout measured twice, for a figure with fixed-aspect axes (a heat map) and a colour bar.

    The first pass changes the axes' size, which moves the fixed-aspect axes
    and its labels; the second sees where they went.  One pass leaves a long
    row label outside the figure.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        A figure without a layout engine.
    """
    for _ in range(2):
        fig.draw_without_rendering()
        fig.tight_layout()


def _row(rows, out: str) -> int:
    """The row of output ``out`` in a fit's ``rows`` (a ValueError naming it if the fit has none)."""
    if out not in rows:
        raise ValueError(f"the fit has no {out} spectra (it predicts {', '.join(rows)}); fit with outputs including it")
    return rows.index(out)


# --- the Cramer-Rao band of the fitted spectra ---------------------------------------------------


def _perturbed(result, i: int, value: float):
    vals = np.array(result.values, float)
    vals[i] = value
    name = result.names[i]
    model = result.model
    if name in model.parameters:
        model = model.with_values({name: value})
    return dataclasses.replace(result, values=vals, model=model)


def spectra_uncertainty(result, record: int = 0, *, rel_step: float = 1e-6):
    """Fitted output spectra and their standard deviation from the parameter covariance.

    ``Var y_k(w) = a_k(w) Cov a_k(w)^H`` with ``a_k(w) = d y_k(w) / d theta``
    the sensitivities of the prediction to every estimated quantity (model
    parameters and nuisance terms: boundary values, biases) at the estimate,
    by central differences of :meth:`FitResult.fitted_spectra` (exact for the
    nuisance terms, which enter linearly).  This is the variance of the
    complex prediction, ``E|y - E y|^2``: the radius of its uncertainty disc,
    which bounds the spread of both the magnitude and (divided by ``|y|``) the
    phase.

    Parameters
    ----------
    result : FitResult
        The fit.
    record : int, optional
        Record of a multi-record fit.
    rel_step : float, optional
        Difference step relative to ``max(|theta_i|, 1e-3)``.

    Returns
    -------
    y : ndarray, complex, shape (m, n_y)
        Fitted spectra of the model's outputs (as :meth:`FitResult.fitted_spectra`).
    sigma : ndarray, shape (m, n_y)
        ``sqrt(Var y)``.  Parameters without a finite standard error (not
        identifiable) are left out of the sum.
    """
    y0 = result.fitted_spectra(record)
    cov = np.array(result.cov, float)
    ok = np.isfinite(np.diag(cov))
    cov = np.where(np.isfinite(cov) & np.outer(ok, ok), cov, 0.0)  # unidentified estimates left out
    rec_name = result.spectra[record].name
    params = result.model.parameters
    A = np.zeros(y0.shape + (len(result.names),), complex)
    for i, (name, slot) in enumerate(zip(result.names, result.slots)):
        if not ok[i] or slot.record not in (None, rec_name):
            continue  # unidentified, or a nuisance term of another record
        v = float(result.values[i])
        h = rel_step * max(abs(v), 1e-3)
        lo, hi = (params[name].lower, params[name].upper) if name in params else (-math.inf, math.inf)
        up, dn = min(v + h, hi), max(v - h, lo)
        if up == dn:
            continue
        A[:, :, i] = (
            _perturbed(result, i, up).fitted_spectra(record) - _perturbed(result, i, dn).fitted_spectra(record)
        ) / (up - dn)
    var = np.einsum("mkp,pq,mkq->mk", A, cov, A.conj()).real
    return y0, np.sqrt(np.maximum(var, 0.0))


# --- spectra -------------------------------------------------------------------------------------


def plot_spectra(
    results,
    labels: Sequence[str] | None = None,
    *,
    record: int = 0,
    outputs: Sequence[str] | None = None,
    freq_unit: str = "rad/s",
    mag_unit: str = "abs",
    crb: bool = True,
    sigma: float = 2.0,
    axes=None,
    ax=None,
    title: str | None = None,
):
    """Measured against fitted output spectra, magnitude and phase (the layout of WK Figs. 3-5).

    Magnitudes are those of the output spectra (finite Fourier transforms of
    the trimmed records); phases are taken relative to the elevator
    spectrum, i.e. the phase of the transfer function, so the manoeuvre's
    timing drops out, and they are drawn on one branch: the first fit's
    phase unwrapped along frequency, the data and the other fits point by
    point on the branch nearest it (:func:`phase_on_one_branch`), so a good
    fit looks like one.  The shaded band is ``+-sigma`` standard deviations of
    the fitted spectrum from the parameter covariance (the Cramer-Rao bound
    for ``cov_type="white"``; see :func:`spectra_uncertainty`): on the
    magnitude ``|y| +- sigma sd(y)`` (clipped at ``1e-3 |y|`` on a log axis), on
    the phase ``+- sigma sd(y)/|y|`` rad.

    Parameters
    ----------
    results : FitResult or sequence of FitResult
        Fits of the same record; the measured spectra are taken from the first.
    labels : sequence of str, optional
        Legend entries for the fits (default: model kinds).
    record : int, optional
        Which record of a multi-record fit.
    outputs : sequence of str, optional
        Outputs to show (default: those of the first fit).
    freq_unit : {"rad/s", "Hz"}, optional
        Unit of the frequency axis.
    mag_unit : {"abs", "dB"}, optional
        Magnitude on a log axis, or in dB (20 log10).
    crb : bool, optional
        Shade the uncertainty band of each fit (default True).
    sigma : float, optional
        Band half-width in standard deviations (default 2).
    axes, ax : array of Axes, shape (2, n_outputs), optional
        Magnitude row and phase row; made if not given (either name).
    title : str, optional
        Figure title.

    Returns
    -------
    fig : matplotlib.figure.Figure
        The figure drawn on.
    axes : ndarray of Axes, shape (2, n_outputs)
        Magnitude row and phase row.
    """
    if mag_unit not in ("abs", "dB"):
        raise ValueError(f"mag_unit must be 'abs' or 'dB', got {mag_unit!r}")
    if not isinstance(results, (list, tuple)):
        results = [results]
    labels = list(labels) if labels is not None else [r.kind for r in results]
    outputs = known_outputs(outputs or results[0].outputs)
    spec = results[0].spectra[record]
    f, flabel = _freq(spec.omega, freq_unit)
    fig, axes, created = _axes_grid(axes, ax, (2, len(outputs)), (4.2 * len(outputs), 6))
    # phase relative to the elevator spectrum: removes the manoeuvre's timing
    # (exp(-j w t_0)) without dividing magnitudes by the input's spectral zeros
    ref = np.exp(-1j * np.angle(spec.u[:, 0]))
    bands = [spectra_uncertainty(r, record) if crb else (r.fitted_spectra(record), None) for r in results]

    def mag(x):
        return 20 * np.log10(np.maximum(x, 1e-300)) if mag_unit == "dB" else x

    rows = results[0].model.outputs
    for j, out in enumerate(outputs):
        k = _row(rows, out)
        z = spec.z[:, k]
        ax_m, ax_p = axes[0, j], axes[1, j]
        if mag_unit == "abs":
            ax_m.set_yscale("log")
            _plain_log_ticks(ax_m.yaxis)
        ax_m.plot(f, mag(np.abs(z)), "k.", ms=4, label="measured")
        # one branch for all: the first fit unwrapped along frequency, the data and the other fits beside it
        fits = [y_all[:, k] * ref for y_all, _ in bands]
        first, data_ph, *other_ph = phase_on_one_branch(fits[0], z * ref, *fits[1:])
        ax_p.plot(f, data_ph, "k.", ms=4)
        for (y_all, sd_all), lab, ph in zip(bands, labels, [first, *other_ph]):
            y = y_all[:, k]
            (line,) = ax_m.plot(f, mag(np.abs(y)), "-", lw=1.5, label=lab)
            ax_p.plot(f, ph, "-", lw=1.5, color=line.get_color())
            if sd_all is not None:
                a, sd = np.abs(y), sigma * sd_all[:, k]
                lo = np.maximum(a - sd, 1e-3 * a)
                shade = {"color": line.get_color(), "alpha": 0.25, "lw": 0}
                ax_m.fill_between(f, mag(lo), mag(a + sd), label=f"{lab} {sigma:g}-sigma band", **shade)
                dph = np.degrees(np.minimum(sd / np.maximum(a, 1e-300), np.pi))
                ax_p.fill_between(f, ph - dph, ph + dph, **shade)
        # scale the magnitude axis to the data and fits, not to the band: where the band is
        # wider than the spectrum (lowest frequencies, bias and boundary terms) it is clipped
        curves = np.abs(np.concatenate([z] + [y_all[:, k] for y_all, _ in bands]))
        top = float(np.max(curves))
        bottom = float(np.min(curves[curves > 0])) if np.any(curves > 0) else top
        if mag_unit == "abs" and top > 0:
            ax_m.set_ylim(bottom / 2.0, top * 2.0)
        elif top > 0:
            ax_m.set_ylim(mag(bottom) - 6.0, mag(top) + 6.0)
        ax_m.set_title(out)
        ax_m.set_ylabel("|" + _LABELS[out] + "|" + (" (dB)" if mag_unit == "dB" else ""))
        ax_p.set_ylabel("phase re elevator (deg)")
        ax_p.set_xlabel(flabel)
        ax_m.grid(True, which="both", alpha=0.3)
        ax_p.grid(True, alpha=0.3)
    figure_legend(fig, axes[0, :1])
    if title:
        fig.suptitle(title)
    return fig, axes


# --- time histories ------------------------------------------------------------------------------


def simulate_fit(result, record: int = 0, *, trim_window: float | None = None):
    """The model's time histories at the estimate for one record of a fit.

    What the frequency-domain model of the record (``z = G u + H d + b 1``,
    plus the optional state-equation and elevator biases) says in the time
    domain:

    * the forced response to the record's own trimmed inputs (elevator, and
      the gust angle for a gust model), simulated from rest with
      :func:`fdml.simulate.simulate` at the estimated parameters (input
      delays and, for the unsteady model, the downwash memory term included),
      with the estimated elevator bias added to the elevator;
    * the free response from the initial state ``x(0)`` (estimated boundary
      values ``x0_alpha, x0_q``, or the measured ones for
      ``boundary="measured"``; none for ``"none"``), with every lag state of
      the unsteady model starting at zero as in the frequency-domain model,
      and the response to the estimated state-equation biases (constant
      forcing from t = 0);
    * the estimated output biases and the trim removed before the transform
      (first sample, or the mean of the first ``trim_window`` seconds, the
      window the fit used: ``result.options["trim_window"]``).

    Not reproduced: the end values ``xT`` (a property of the finite
    transform, not of the motion; compare them with the simulated end
    state), measurement noise, and anything outside the fitted band that the
    frequency-domain fit never saw (slow drift, the phugoid, structural
    modes): the time-domain residual shows them.  For the unsteady model with
    F != 0 the small free response from ``x(0)`` leaves out the F term (it
    has no finite-state form); ``meta["initial_state"]`` says so.

    Parameters
    ----------
    result : FitResult
        A fit made from time-domain records (it keeps them).
    record : int, optional
        Which record of a multi-record fit (default the first).
    trim_window : float, optional
        Leading window of ``trim="mean"``, s; default the fit's (0.5 s for a
        result saved before fits kept their options).

    Returns
    -------
    Record
        Signals ``alpha`` (rad), ``q`` (rad/s), ``az`` (g) of the model and the
        fit's other outputs (``theta`` rad, ``qdot`` rad/s^2), with
        the measured inputs; ``meta`` holds ``trim`` (values added back),
        ``biases``, ``x0`` and ``initial_state`` ("exact", "none" or
        "approximate: ...").
    """
    from .errors import ParameterError
    from .models.base import output_rows
    from .record import Record
    from .simulate import realize, simulate

    raw = result.record(record)
    mode = result.spectra[record].trim_mode
    if trim_window is None:
        trim_window = result.options.get("trim_window")  # the fit's (None: not a mean trim)
    window = {} if trim_window is None else {"window": float(trim_window)}
    trimmed = raw.remove_trim(mode, **window) if mode != "none" else raw
    trim = {k: float(raw[k][0] - trimmed[k][0]) for k in raw.signals}
    model = result.model
    nu = result.nuisance_values(record)  # the values the frequency-domain measurement model uses
    b = nu.biases
    ib = 0.0 if nu.input_bias is None else nu.input_bias
    sb = np.zeros(2) if nu.state_biases is None else nu.state_biases
    rows = model.outputs
    x0 = np.zeros(len(boundary_channels(rows))) if nu.x0 is None else nu.x0
    inputs = {"de": trimmed["de"] + ib}
    if model.gust:
        inputs["alpha_w"] = trimmed["alpha_w"]
    zero_bias = {f"bias_{o}": 0.0 for o in rows}
    t = raw.t[0] + raw.dt * np.arange(raw.n)  # the simulator needs an exact grid; records are uniform to 1e-3 dt
    forced = simulate(model, t, inputs, zero_bias)
    y = np.column_stack([forced[o] for o in rows])
    state = "none"
    if np.any(x0 != 0) or np.any(sb != 0):
        try:
            real = realize(model, zero_bias)
            state = "exact"
        except ParameterError:
            real = realize(model, {**zero_bias, "F": 0.0})
            state = "approximate: the F term is left out of the free response"
        rates = output_rows(rows, model.U, model.parameters.values)[1]  # rows of the states' rates
        y = y + _free_response(real, t - t[0], x0, sb, rates)
    y = y + b[None, :] + np.array([trim.get(o, 0.0) for o in rows])[None, :]
    signals = {"de": raw["de"], **{o: y[:, i] for i, o in enumerate(rows)}}
    if raw.has("alpha_w"):
        signals["alpha_w"] = raw["alpha_w"]
    meta = {
        "trim": trim,
        "biases": dict(zip(rows, b.tolist())),
        "x0": x0.tolist(),
        "state_biases": sb.tolist(),
        "elevator_bias": ib,
        "initial_state": state,
        "model": model.kind,
        "source": raw.name,
    }
    return Record(raw.t, signals, name=f"{raw.name} (model)", meta=meta, check_units=False)


def _free_response(real, tau: np.ndarray, x0: np.ndarray, sb: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """Outputs from x(0) = x0 (lags at zero) under constant state-equation forcing sb, exact on ``tau``.

    ``x0`` holds the boundary channels (alpha, q[, theta]); the forcing enters
    the first two states of every fdml realisation (the alpha and q equations),
    and an output of the states' rates (``rates``, (n_y, 2): a_z, q_dot) feels it directly.
    """
    from scipy import linalg

    ns = real.A.shape[0]
    at = [real.outputs.index(c) for c in boundary_channels(real.outputs)]
    xi0 = np.linalg.lstsq(real.C[at], x0, rcond=None)[0]  # alpha, q[, theta] = x0; every other state zero
    M = np.zeros((ns + 1, ns + 1))  # the state and the constant 1, whose column carries the forcing
    M[:ns, :ns] = real.A
    M[:2, ns] = sb
    dt = tau[1] - tau[0]
    Phi = linalg.expm(M * dt)
    z = np.empty((tau.size, ns + 1))
    z[0] = np.append(xi0, 1.0)
    for i in range(1, tau.size):
        z[i] = Phi @ z[i - 1]
    return z[:, :ns] @ real.C.T + rates @ sb


def plot_time_histories(
    result,
    record: int = 0,
    *,
    outputs: Sequence[str] | None = None,
    inputs: bool = True,
    angle_unit: str = "deg",
    trim_window: float | None = None,
    axes=None,
    ax=None,
    title: str | None = None,
):
    """Measured time histories against the model simulated in the time domain from the estimate.

    The cross-check of a frequency-domain fit: the model response comes from
    :func:`simulate_fit` (forced response to the measured inputs, free
    response from the estimated initial state, output biases and trim added
    back; see there for what is and is not reproduced).  Each output
    panel's title gives the RMS of measured minus model; one legend sits
    below the panels.

    Parameters
    ----------
    result : FitResult
        A fit made from time-domain records.
    record : int, optional
        Which record of a multi-record fit (default the first).
    outputs : sequence of str, optional
        Outputs to show (default alpha, q, az).
    inputs : bool, optional
        Add a top panel with the elevator (and gust angle) (default True).
    angle_unit : {"deg", "rad"}, optional
        Units of alpha, q, the elevator and the gust angle (a_z is in g).
    trim_window : float, optional
        Leading window of ``trim="mean"``, s; default the fit's (:func:`simulate_fit`).
    axes, ax : array of Axes, optional
        One per panel (inputs first), in a column; made if not given.
    title : str, optional
        Figure title.

    Returns
    -------
    fig : matplotlib.figure.Figure
        The figure drawn on.
    axes : ndarray of Axes, shape (n_panels,)
        The panels, inputs first.
    """
    if angle_unit not in ("deg", "rad"):
        raise ValueError(f"angle_unit must be 'deg' or 'rad', got {angle_unit!r}")
    outputs = known_outputs(outputs or OUTPUTS)
    for out in outputs:
        _row(result.model.outputs, out)
    meas = result.record(record)
    model = simulate_fit(result, record, trim_window=trim_window)
    n = len(outputs) + int(inputs)
    fig, arr, created = _axes_grid(axes, ax, (n, 1), (8, 2.0 * n + 0.6))
    arr = arr[:, 0]
    scale = _DEG if angle_unit == "deg" else 1.0
    rate = f"{angle_unit}/s"
    unit = {"q": rate, "qdot": f"{rate}^2", "az": "g", **dict.fromkeys(("alpha", "theta", "de", "alpha_w"), angle_unit)}
    sc = {k: 1.0 if k == "az" else scale for k in unit}
    t = meas.t
    if inputs:
        a = arr[0]
        a.plot(t, sc["de"] * meas["de"], "k-", lw=1.0, label=r"$\delta_e$")
        if meas.has("alpha_w") and result.model.gust:
            a.plot(t, sc["alpha_w"] * meas["alpha_w"], "-", color="0.5", lw=1.0, label=r"$\alpha_w$")
        a.set_ylabel(f"input ({unit['de']})")
        a.grid(True, alpha=0.3)
    for a, out in zip(arr[int(inputs) :], outputs):
        ym, yf = sc[out] * meas[out], sc[out] * model[out]
        rms = float(np.sqrt(np.mean((ym - yf) ** 2)))
        a.plot(t, yf, "-", lw=2.2, color="C1", alpha=0.85, label="model")
        a.plot(t, ym, "k-", lw=0.7, label="measured", zorder=3)
        a.set_ylabel(f"{_NAMES[out]} ({unit[out]})")
        a.set_title(f"rms error {rms:.3g} {unit[out]}", loc="right", fontsize="small")
        a.grid(True, alpha=0.3)
    arr[-1].set_xlabel("time (s)")
    figure_legend(fig, arr, ncol=4)
    if title:
        fig.suptitle(title)
    return fig, arr


# --- residual spectra ----------------------------------------------------------------------------


def plot_residual_spectra(
    result,
    record: int = 0,
    *,
    outputs: Sequence[str] | None = None,
    freq_unit: str = "rad/s",
    axes=None,
    ax=None,
    title: str | None = None,
):
    """Residual spectra ``|measured - fitted|`` per output, with the noise floor implied by R.

    For complex Gaussian residuals with covariance R (Eq. 24), ``E|v_k|^2 =
    R_kk``: the solid line is that RMS level ``sqrt(R_kk)``, the dashed line
    the level exceeded with probability 5 % (``sqrt(-ln 0.05 R_kk)``, the
    Rayleigh quantile).  Residuals that cluster above it over a range of
    frequencies point at model error there, not noise.  Outputs that were not
    fitted have no R entry and are drawn without a floor.

    Parameters
    ----------
    result : FitResult
        The fit.
    record : int, optional
        Which record of a multi-record fit (default the first).
    outputs : sequence of str, optional
        Default: the fitted outputs.
    freq_unit : {"rad/s", "Hz"}, optional
        Unit of the frequency axis.
    axes, ax : array of Axes, shape (n_outputs,), optional
        One panel per output; made if not given (either name).
    title : str, optional
        Figure title.

    Returns
    -------
    fig : matplotlib.figure.Figure
        The figure drawn on.
    axes : ndarray of Axes, shape (n_outputs,)
        One panel per output.
    """
    outputs = known_outputs(outputs or result.outputs)
    spec = result.spectra[record]
    f, flabel = _freq(spec.omega, freq_unit)
    v = spec.z - result.fitted_spectra(record)
    fig, arr, created = _axes_grid(axes, ax, (1, len(outputs)), (4.2 * len(outputs), 3.4))
    arr = arr[0]
    R = np.asarray(result.R)
    for a, out in zip(arr, outputs):
        k = _row(result.model.outputs, out)
        a.semilogy(f, np.abs(v[:, k]), ".", ms=4, color="C3", label="|residual|")
        _plain_log_ticks(a.yaxis)
        if out in result.outputs:
            i = result.outputs.index(out)
            r = math.sqrt(max(float(np.real(R[i, i])), 0.0))
            a.axhline(r, color="k", lw=1.2, label=r"$\sqrt{R_{kk}}$ (rms)")
            a.axhline(r * math.sqrt(-math.log(0.05)), color="k", ls="--", lw=1.0, label="95 % level")
        a.set_title(out)
        a.set_ylabel("|" + _LABELS[out] + "|")
        a.set_xlabel(flabel)
        a.grid(True, which="both", alpha=0.3)
    figure_legend(fig, arr[:1])
    if title:
        fig.suptitle(title)
    return fig, arr


# --- correlation ---------------------------------------------------------------------------------


def plot_correlation(
    result,
    *,
    names: Sequence[str] | None = None,
    nuisance: bool = True,
    annotate: bool = True,
    cmap: str = "RdBu_r",
    colorbar: bool = True,
    ax=None,
    title: str | None = None,
):
    """The correlation matrix of the estimates as an annotated heat map.

    Parameters
    ----------
    result : FitResult
        The fit.
    names : sequence of str, optional
        Parameters to show, in order (default all estimated ones).
    nuisance : bool, optional
        With the default ``names``, include nuisance terms (biases, boundary
        values); False shows the model parameters only.
    annotate : bool, optional
        Write each correlation in its cell (two decimals).
    cmap : str, optional
        Diverging colour map, fixed to [-1, 1].
    colorbar : bool, optional
        Draw a colour bar.
    ax : Axes, optional
        Where to draw; default a new figure.
    title : str, optional
        Axes title.

    Returns
    -------
    fig : matplotlib.figure.Figure
        The figure drawn on.
    ax : Axes
        The heat map's axes.
    """
    all_names = list(result.names)
    if names is None:
        names = list(all_names if nuisance else result.model_names)
    else:
        bad = [n for n in names if n not in all_names]
        if bad:
            raise ValueError(f"not estimated in this fit: {', '.join(bad)}")
    idx = [all_names.index(n) for n in names]
    C = np.asarray(result.corr, float)[np.ix_(idx, idx)]
    n = len(names)
    size = max(3.5, 0.45 * n + 1.8)
    fig, arr, created = _axes_grid(None, ax, (1, 1), (size + (1.0 if colorbar else 0.0), size))
    if created:
        fig.set_layout_engine(None)  # a fixed-aspect heat map with a colour bar: settle_layout below
    a = arr[0, 0]
    import matplotlib

    cm = matplotlib.colormaps[cmap].with_extremes(bad="0.85")  # NaN (unidentified): grey
    im = a.imshow(np.ma.masked_invalid(C), cmap=cm, vmin=-1.0, vmax=1.0, interpolation="nearest")
    a.set_xticks(range(n), names, rotation=60, ha="right", fontsize="small")
    a.set_yticks(range(n), names, fontsize="small")
    if annotate:
        fs = "x-small" if n > 10 else "small"
        for (i, j), c in np.ndenumerate(C):
            txt = f"{c + 0.0:.2f}".replace("-0.00", "0.00") if np.isfinite(c) else ""
            color = "white" if np.isfinite(c) and abs(c) > 0.6 else "black"
            a.text(j, i, txt, ha="center", va="center", fontsize=fs, color=color)
    if colorbar:
        fig.colorbar(im, ax=a, fraction=0.046, pad=0.04, label="correlation")
    a.set_title(title or "correlation of the estimates")
    if created:
        settle_layout(fig)
    return fig, a
