"""Shrink: how far the gap closes once an effect is added, and where the effect acts.

* **Shrink** of the coherent gap: ``1 - sum X_after / sum X_before`` over the
  cells the base fit's map flagged (docs/diagnosis_method.md 2.6 rule 6: judged only where
  there was a gap), with X the cell's excess in units of the *before* noise
  floor, computed with the same regressors before and after.  In-sample, and
  on a held-out record with every model parameter frozen (only its own
  boundary terms and biases fitted), which is the figure to quote.
* **Footprint**: ``|y(theta_aug, eta_hat) - y(theta_aug, eta_0)|^2 / floor`` per
  cell, the energy of the effect itself, i.e. where it acts (rule 7: not the
  refitted residual map, which derivative compensation smears).
* **Compensation**: ``|y(theta_aug, eta_0) - y(theta_base)|^2 / floor`` per
  cell, how the base parameters had bent to imitate the effect, and the
  parameter shifts ``theta_aug - theta_base`` in units of the base standard
  errors.
"""

from __future__ import annotations

import math

import numpy as np

from ..channels import OUTPUTS as CHANNELS
from ..estimate import NoiseModel
from ..estimate import fit as fdml_fit
from ..warning_log import recording
from .data import AnalysisData
from .likelihood import DiagFit, diag_fit
from .locate import GapMap, band_rows, forced_response, gap_map

__all__ = ["fit_map", "shrink", "footprint", "compensation", "parameter_shifts", "frozen_fit"]


def fit_map(
    data: AnalysisData, fit, edges, *, alpha: float, channels, before: GapMap | None = None, designs: dict | None = None
) -> GapMap:
    """Gap map of a fit; with ``before``, the noise floors of that map are held (for shrink).

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    fit : DiagFit
        The fit.
    edges : numpy.ndarray
        Band edges, rad/s.
    alpha : float
        Family-wise level of the map.
    channels : sequence of str
        Channels mapped.
    before : GapMap, optional
        A map whose noise floors are held.
    designs : dict, optional
        Cell regressors to reuse (:func:`fdml.diagnose.locate.gap_map`).

    Returns
    -------
    GapMap
        The fit's map.
    """
    e = fit.full_residual()
    forced = forced_response(data, fit.model)
    floors = None
    if before is not None:
        nb = before.edges.size - 1
        floors = {(c.channel, i % nb): c.floor for i, c in enumerate(before.cells)}
    return gap_map(data, e, forced, edges, channels=channels, alpha=alpha, floors=floors, designs=designs)


def shrink(before: GapMap, after: GapMap, cells: list | None = None) -> tuple[float | None, int]:
    """(shrink of the coherent gap over the flagged cells, number of flagged cells).

    ``cells`` (indices) defaults to the cells ``before`` flags.  None when no cell was flagged
    (the gap is too small to judge) or no excess is left in them.

    Parameters
    ----------
    before, after : GapMap
        Maps of the same cells before and after the effect is added.
    cells : list of int, optional
        Indices of the cells judged.

    Returns
    -------
    shrink : float or None
        The shrink, 0 to 1.
    n_flagged : int
        Number of cells judged.
    """
    idx = [i for i, c in enumerate(before.cells) if c.significant] if cells is None else list(cells)
    if not idx:
        return None, 0
    xb = sum(max(before.cells[i].excess, 0.0) for i in idx)
    xa = sum(max(after.cells[i].excess, 0.0) if math.isfinite(after.cells[i].excess) else 0.0 for i in idx)
    if xb <= 0:
        return None, len(idx)
    return float(min(max(1.0 - xa / xb, 0.0), 1.0)), len(idx)


def _predict_rows(fit: DiagFit, theta: np.ndarray) -> np.ndarray:
    return np.concatenate(fit.prob.predict(theta))


def _cell_energy(data: AnalysisData, delta: np.ndarray, before: GapMap) -> list:
    nb = before.edges.size - 1
    out = []
    for i, c in enumerate(before.cells):
        lo, hi = before.edges[i % nb], before.edges[i % nb + 1]
        rows, _ = band_rows(data, lo, hi, i % nb == nb - 1)
        e = float(np.sum(np.abs(delta[rows, CHANNELS.index(c.channel)]) ** 2))
        ok = c.floor is not None and math.isfinite(c.floor) and c.floor > 0
        out.append({"channel": c.channel, "band": [round(lo, 6), round(hi, 6)], "energy": e / c.floor if ok else None})
    tot = sum(x["energy"] for x in out if x["energy"] is not None)
    for x in out:
        x["share"] = None if (x["energy"] is None or tot <= 0) else x["energy"] / tot
    return out


def footprint(data: AnalysisData, fit: DiagFit, nulls: dict, before: GapMap) -> list:
    """Energy of the effect itself per cell (in noise-floor units) and its share.

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    fit : DiagFit
        The fit with the effect.
    nulls : dict
        The effect's parameters at their null (effect off), by name.
    before : GapMap
        The base map: its cells and noise floors.

    Returns
    -------
    list of dict
        Per cell: ``channel``, ``band`` (rad/s), ``energy`` (floor units) and ``share``.
    """
    delta = _predict_rows(fit, fit.theta) - _predict_null(fit, nulls)
    return _cell_energy(data, delta, before)


def _predict_null(fit: DiagFit, nulls: dict) -> np.ndarray:
    """Prediction with the effect switched off (free and fixed effect parameters at their nulls).

    Nuisance (non-free) effect parameters live in the model, not in theta.
    """
    theta0 = fit.theta.copy()
    for n, v in nulls.items():
        if n in fit.names:
            theta0[fit.names.index(n)] = v
    fixed = {n: v for n, v in nulls.items() if n not in fit.names}
    if not fixed:
        return _predict_rows(fit, theta0)
    prob = fit.prob
    saved = prob.model
    try:
        prob.model = saved.with_values(fixed)
        return _predict_rows(fit, theta0)
    finally:
        prob.model = saved


def compensation(data: AnalysisData, fit: DiagFit, base: DiagFit, nulls: dict, before: GapMap) -> list:
    """How the base parameters moved to imitate the effect: per-cell energy of y(aug, eta0) - y(base).

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    fit : DiagFit
        The fit with the effect.
    base : DiagFit
        The base fit.
    nulls : dict
        The effect's parameters at their null, by name.
    before : GapMap
        The base map: its cells and noise floors.

    Returns
    -------
    list of dict
        Per cell: ``channel``, ``band`` (rad/s), ``energy`` (floor units) and ``share``.
    """
    delta = _predict_null(fit, nulls) - _predict_rows(base, base.theta)
    return _cell_energy(data, delta, before)


def parameter_shifts(base: DiagFit, fit: DiagFit) -> dict:
    """``{name: {base, base_stderr, augmented, augmented_stderr, shift_in_stderr}}`` for shared model parameters.

    Parameters
    ----------
    base : DiagFit
        The base fit.
    fit : DiagFit
        The fit with the effect(s).

    Returns
    -------
    dict
        Per shared model parameter and derived value (``derived: True``), values
        in its unit and the shift in base standard errors.
    """
    bp, fp = base.params, fit.params
    out = {
        n: _shift(bp[n], base.stderr.get(n, math.nan), fp[n], fit.stderr.get(n, math.nan))
        for n, slot in zip(base.names, base.prob.slots)
        if not slot.role.nuisance and n in fp
    }
    # the derived set (alternate set / dimensional derivatives, docs/theory.md 6), delta-method errors
    try:
        bd = base.model.derived()
        ad = fit.model.derived()
        bse = getattr(base.result, "derived", {}) or {}
        fse = getattr(fit.result, "derived", {}) or {}
    except Exception:  # pragma: no cover - a model without a derived set
        return out
    for k in bd:
        if k not in out and k in ad:
            se = bse.get(k, (None, math.nan))[1]
            out[k] = {**_shift(bd[k], se, ad[k], fse.get(k, (None, math.nan))[1]), "derived": True}
    return out


def _shift(base: float, base_se: float, aug: float, aug_se: float) -> dict:
    """One entry of :func:`parameter_shifts`: the shift in base standard errors (NaN without one)."""
    shift = (aug - base) / base_se if (base_se and math.isfinite(base_se) and base_se > 0) else math.nan
    return dict(base=base, base_stderr=base_se, augmented=aug, augmented_stderr=aug_se, shift_in_stderr=shift)


def frozen_fit(data: AnalysisData, model, bands: NoiseModel, options: dict) -> DiagFit:
    """The model with every model parameter frozen; only each record's nuisance terms are fitted (hold-out).

    Parameters
    ----------
    data : AnalysisData
        The held-out records' spectra.
    model : Model
        The model, at the estimates.
    bands : NoiseModel
        The noise bands of the cost.
    options : dict
        Fit options (``outputs``, ``boundary``, ``biases``).

    Returns
    -------
    DiagFit
        The frozen fit.
    """
    frozen = model.with_parameters(model.parameters.only_free([]))
    with recording(reemit=False) as log:  # kept in the DiagFit
        # the records were checked once (core._data_findings); a frozen model needs no adequacy check
        res = fdml_fit(list(data.spectra), frozen, cov_type="naive", check=False, adequacy=False, **options)
    return diag_fit(res, data, bands, {}, log, **options)
