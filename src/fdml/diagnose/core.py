"""``diagnose``: locate the gap, attribute it to an effect, measure how far it shrinks.

See :mod:`fdml.diagnose` for the method and ``../shared/docs/DIAGNOSIS.md`` for
the design study this follows (and where it departs from it).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..errors import FdmlError, ParameterError
from ..models.base import Model
from ..record import Record
from .attribute import Candidate, attribute_step, choose, p_value
from .data import analysis_data
from .disturbance import gust_test
from .effects import Effect, default_library, registered_effects
from .likelihood import fit_model, likelihood_ratio, noise_bands
from .locate import default_bands, holm
from .report import SHRINK_CONFIRM, DiagnosisReport, label_for
from .shrink import compensation, fit_map, footprint, frozen_fit, parameter_shifts, shrink

__all__ = ["diagnose"]

logger = logging.getLogger(__name__)


def _resolve(records, base):
    from ..results import FitResult

    opts = {}
    if isinstance(base, FitResult):
        if records is None:
            records = [base.record(i) for i in range(len(base.time_records))]
        opts = {"outputs": tuple(base.outputs), "boundary": base.boundary}
        base = base.model
    if not isinstance(base, Model):
        raise ParameterError(f"base must be an fdml Model or FitResult, got {type(base).__name__}")
    if records is None:
        raise FdmlError("no records were given to diagnose")
    if isinstance(records, Record):
        records = [records]
    return list(records), base, opts


def _as_list(records) -> list:
    if records is None:
        return []
    return [records] if isinstance(records, Record) else list(records)


def _data_findings(records, model, band, strict: bool) -> list:
    """The data check on every record, issued as warnings (fdml.datacheck)."""
    from ..datacheck import check_data
    from ..findings import emit, raise_if_strict

    try:
        U = float(model.U)
    except (AttributeError, NotImplementedError, TypeError, ValueError):
        U = None
    lohi = None
    if band is not None:  # the diagnosis takes LO:HI; the check needs a grid: 100 steps over it
        lo, hi = (band.split(":")[:2] if isinstance(band, str) else band[:2])
        lohi = (float(lo), float(hi), (float(hi) - float(lo)) / 100)
    found = [f for r in records for f in check_data(r, band=lohi, airspeed=U).findings]
    raise_if_strict(found, strict)
    emit(found, stacklevel=3)
    return found


def _attach(found: list, rep: DiagnosisReport) -> DiagnosisReport:
    rep.findings = list(found)
    return rep


def _library(library) -> list:
    if library is None:
        return list(registered_effects())
    out = []
    names = []
    for item in library:
        if isinstance(item, Effect):
            out.append(item)
        else:
            names.append(str(item))
    if names:
        out.extend(default_library(names))
    return out


def _noise_effect(effects):
    return next((e for e in effects if e.kind == "noise" and e.name == "unmeasured_gust"), None)


def diagnose(records=None, base=None, *, holdout=None, band=None, bands=None, library=None, alpha: float = 0.05,
             max_effects: int = 2, oversample: int = 2, noise: str = "band", refit_top: int = 4, outputs=None,
             boundary: str = "estimated", biases="auto", trim: str = "first",
             shrink_threshold: float = SHRINK_CONFIRM, check: bool = True, strict: bool = False) -> DiagnosisReport:
    """Diagnose the gap between a base model and flight records.

    Parameters
    ----------
    records : Record or list of Record
        Records fitted jointly (the same flight condition).  May be omitted
        when ``base`` is a FitResult holding its time-domain records.
    base : Model or FitResult
        Any fdml model (its values are start values), or a fit whose model
        and options are reused (the diagnosis refits it on its own grid).
    holdout : Record or list of Record, optional
        Records of the same flight condition not used for fitting: shrink and
        remaining gaps are judged on them with every model parameter frozen.
    band : (lo, hi) or "LO:HI", optional
        Analysis band, rad/s (default 0.1-10).
    bands : sequence of float, optional
        Edges of the gap map's bands, rad/s (default: log-spaced, merged
        until each band holds enough independent frequencies).
    library : sequence of str or Effect, optional
        Candidate effects by name (``"time_delay"``) or key
        (``"time_delay@q"``), or Effect objects (default: every registered).
    alpha : float, optional
        Family-wise level of the attribution tests and of the gap map.
    max_effects : int, optional
        Greedy forward selection stops after this many effects.
    oversample : int, optional
        Grid points per independent frequency (see :mod:`fdml.diagnose.data`).
    noise : {"band", "white"}, optional
        Noise model of the likelihood: band-wise covariance (default) or one
        covariance over the whole band (fdml's own).
    refit_top : int, optional
        Candidates refitted after the score screen (plus any whose score test
        is significant on its own).
    outputs, boundary, biases, trim :
        As in :func:`fdml.fit`.
    shrink_threshold : float, optional
        Shrink needed for the label "confirmed".
    check, strict : bool, optional
        Run the data check (:func:`fdml.datacheck.check_data`) on every
        record and held-out record (default True; findings kept in
        ``report.findings``); with ``strict``, raise
        :class:`~fdml.errors.DataCheckError` on any finding before fitting.

    Returns
    -------
    DiagnosisReport
    """
    t0 = time.perf_counter()
    records, model, fopts = _resolve(records, base)
    found = _data_findings(list(records) + _as_list(holdout), model, band, strict) if check else []
    if outputs is None:
        outputs = fopts.get("outputs")
    boundary = fopts.get("boundary", boundary)
    if not (0 < alpha < 1):
        raise ParameterError(f"alpha must lie in (0, 1), got {alpha}")
    effects = _library(library)
    data = analysis_data(records, band, oversample=oversample, trim=trim, gust=model.gust)
    nb = noise_bands(data, mode=noise)
    rows = nb.assign(data.stacked_omega())
    options = {"outputs": outputs, "boundary": boundary, "biases": biases}
    channels = tuple(outputs.split(",") if isinstance(outputs, str) else (outputs or ("alpha", "q", "az")))
    channels = tuple(c.strip() for c in channels)
    edges = np.asarray(bands, float) if bands is not None else default_bands(data)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise ParameterError("bands must be increasing edges in rad/s, at least two")
    n_out = len(channels)
    n_obs = 2 * data.n_dft * n_out
    settings = {"alpha": alpha, "band": list(data.band), "bands": edges.tolist(), "oversample": oversample,
                "noise": noise, "noise_bands": nb.edges.tolist(), "refit_top": refit_top, "max_effects": max_effects,
                "records": data.names(), "independent_frequencies": data.n_dft, "base_model": model.describe(),
                "shrink_threshold": shrink_threshold, "outputs": list(channels)}
    problems = []
    try:
        base_fit = fit_model(data, model, nb, **options)
    except FdmlError as exc:
        return _attach(found, _empty("base_fit_failed", [f"the base model could not be fitted: {exc}"], settings))
    if not base_fit.converged:
        return _attach(found, _empty("base_not_converged",
                      [f"the base fit did not converge ({base_fit.message}); no effect can be attributed "
                       "against an unconverged base"], settings))
    designs = {}
    base_map = fit_map(data, base_fit, edges, alpha=alpha, channels=channels, designs=designs)
    testable = [c for c in base_map.cells if c.excitation == "ok"]
    thin = [c for c in base_map.cells if c.excitation != "ok"]
    for c in thin:
        problems.append(f"{c.channel} {c.band[0]:.3g}-{c.band[1]:.3g} rad/s: {c.excitation} "
                        f"(gain resolvable to {c.gain_se_db:.2g} dB only)" if c.gain_se_db else
                        f"{c.channel} {c.band[0]:.3g}-{c.band[1]:.3g} rad/s: {c.excitation}")
    if not testable:
        rep = _empty("insufficient_excitation",
                     problems + ["no band has enough excitation to say anything about the model; no verdict"],
                     settings)
        rep.location = base_map.to_list()
        return _attach(found, rep)

    fw = floor_weights(data, base_map, channels)

    # --- attribution: greedy forward selection ------------------------------------------
    gust_eff = _noise_effect(effects)
    det = [e for e in effects if e.kind == "deterministic"]
    cur = base_fit
    accepted: list = []
    all_tested: list = []
    skipped_all: dict = {}
    ambiguity: list = []
    K0 = None
    remaining = list(det)
    step_fits = []  # the fit each step's candidates are added to
    for step in range(max(int(max_effects), 0)):
        step_fits.append(cur)
        tested, skipped = attribute_step(data, cur, remaining, nb, rows, options, alpha=alpha,
                                         refit_top=refit_top, step=step, n_obs=n_obs, floor_weights=fw)
        if step == 0:
            K0 = len(tested) + (1 if gust_eff is not None else 0)
            # Holm over the whole first-step family, the turbulence test included
            ps = [c.p for c in tested] + ([1.0] if gust_eff is not None else [])
            for c, a in zip(tested, holm(np.array(ps))):
                c.p_holm = float(a)
            for s in skipped:
                skipped_all.setdefault(s.key, s)
        all_tested.extend(tested)
        best, amb = choose(tested, alpha, n_obs, rows, data.stacked_dft())
        if best is None:
            break
        if accepted:
            # backward check: is the earlier effect still needed next to the new one?
            prev = accepted[-1]
            try:
                only_new = fit_model(data, best.effect.augment(base_fit.model), nb, start=best.fit.params, **options)
                lr_prev = likelihood_ratio(only_new.cost, best.fit.cost, data.oversample)
                p_prev, _ = p_value(lr_prev, prev.df, prev.null)
                if p_prev >= alpha:
                    logger.info("backward check drops %s (p = %.3g) once %s is in", prev.key, p_prev, best.key)
                    accepted.remove(prev)
                    prev.reason = f"dropped by the backward check (p = {p_prev:.3g} once {best.key} is in)"
            except FdmlError:  # pragma: no cover
                pass
        accepted.append(best)
        ambiguity.append(amb)
        cur = best.fit
        remaining = [e for e in remaining if e.key != best.key]

    # --- unmeasured turbulence, after the deterministic effects ---------------------------
    gust = None
    gust_sig = False
    if gust_eff is not None:
        why = gust_eff.applicable(cur.model, inputs=data.inputs, outputs=channels)
        if why is None and len(channels) >= 2:
            try:
                gust = gust_test(data, cur, edges)
            except (FdmlError, np.linalg.LinAlgError, ValueError) as exc:
                skipped_all[gust_eff.key] = Candidate(gust_eff, gust_eff.key, identifiable=False,
                                                      reason=f"cannot be evaluated: {exc}")
        else:
            skipped_all[gust_eff.key] = Candidate(gust_eff, gust_eff.key, identifiable=False,
                                                  reason=why or "needs at least two output channels")
    if gust is not None:
        gust_p_adj = min(1.0, gust.p * max(K0 or 1, 1))
        gust_sig = gust_p_adj < alpha

    # --- shrink, footprint, labels ---------------------------------------------------------
    # Shrink is judged on flagged cells only (rule 6), with the base floors and regressors.  A
    # candidate at forward step k is compared with the model it was added to (step k's fit) on the
    # cells still flagged there, so a second effect is credited with the share of the *remaining*
    # gap it removes.
    refitted = [c for c in all_tested if c.refitted]
    step_maps = {0: base_map}
    for k in range(1, len(step_fits)):
        step_maps[k] = fit_map(data, step_fits[k], edges, alpha=alpha, channels=channels, before=base_map,
                               designs=designs)
    in_shr = {}
    for c in refitted:
        after = fit_map(data, c.fit, edges, alpha=alpha, channels=channels, before=base_map, designs=designs)
        in_shr[(c.key, c.step)] = shrink(step_maps[c.step], after)
    final = cur
    final_map_same = fit_map(data, final, edges, alpha=alpha, channels=channels, before=base_map, designs=designs)
    final_map = fit_map(data, final, edges, alpha=alpha, channels=channels)
    unexplained = [dict(c.to_dict(), where="in-sample") for c in final_map.cells if c.significant]
    shrink_final, n_flag = shrink(base_map, final_map_same)

    hold = None
    h_shr = {}
    if holdout is not None:
        hdata = analysis_data(holdout, data.band, oversample=oversample, trim=trim, gust=model.gust)
        hnb = noise_bands(hdata, mode=noise)
        h_designs = {}
        h_base = frozen_fit(hdata, base_fit.model, hnb, options)
        h_before = fit_map(hdata, h_base, edges, alpha=alpha, channels=channels, designs=h_designs)
        h_step = {0: h_before}
        for k in range(1, len(step_fits)):
            hk = frozen_fit(hdata, step_fits[k].model, hnb, options)
            h_step[k] = fit_map(hdata, hk, edges, alpha=alpha, channels=channels, before=h_before, designs=h_designs)
        for c in refitted:
            hf = frozen_fit(hdata, c.fit.model, hnb, options)
            h_after = fit_map(hdata, hf, edges, alpha=alpha, channels=channels, before=h_before, designs=h_designs)
            h_shr[(c.key, c.step)] = shrink(h_step[c.step], h_after)
        h_final = frozen_fit(hdata, final.model, hnb, options)
        h_final_same = fit_map(hdata, h_final, edges, alpha=alpha, channels=channels, before=h_before,
                               designs=h_designs)
        h_final_own = fit_map(hdata, h_final, edges, alpha=alpha, channels=channels)
        h_unexp = [dict(c.to_dict(), where="holdout") for c in h_final_own.cells if c.significant]
        unexplained += h_unexp
        hs_final, hn_flag = shrink(h_before, h_final_same)
        hold = {"records": hdata.names(), "location": h_before.to_list(), "location_after": h_final_same.to_list(),
                "shrink": hs_final, "flagged_before": hn_flag, "unexplained": h_unexp}

    acc_keys = [(a.key, a.step) for a in accepted]
    amb_first = ambiguity[0] if ambiguity else []
    # remaining gap for the labels: the final fit's own map (report.UNEXPLAINED_RULE)
    n_unexp_label = len([u for u in unexplained if u["where"] == "in-sample"])
    ranking = []
    for c in all_tested:
        sig = c.significant(alpha) and c.refitted
        in_sample, nfl = in_shr.get((c.key, c.step), (None, 0))
        h = h_shr.get((c.key, c.step))
        shr, nflag = (h if h is not None else (in_sample, nfl)) if hold else (in_sample, nfl)
        amb = False
        for a, s in zip(accepted, ambiguity):
            if a.key == c.key and a.step == c.step:
                amb = len(s) > 1
        acc = (c.key, c.step) in acc_keys
        lab = label_for(significant=sig, accepted=acc, ambiguous=amb, plausible=c.plausible,
                        shrink=shr, n_flagged=nflag, n_unexplained=n_unexp_label, threshold=shrink_threshold)
        ranking.append(_rank_entry(c, lab, shr, in_sample, h[0] if h else None, acc, n_obs, sig))
    if gust is not None:
        # a noise-kind effect is judged on its likelihood gain, not on the coherent gap (which it cannot
        # close): confirmed when no coherent gap is left unexplained, else partial
        glab = ("confirmed" if n_unexp_label == 0 else "partial") if gust_sig else None
        ranking.append({
            "effect": "unmeasured_gust", "key": gust_eff.key, "channel": gust_eff.channel, "lr": gust.lr,
            "p_value": gust.p, "p_holm": min(1.0, gust.p * max(K0 or 1, 1)), "shrink": gust.share,
            "label": glab, "params": {"sigma_w": {"value": gust.sigma_w, "stderr": gust.sigma_w_se, "unit": "m/s"}},
            "df": 1, "null": "chibar", "accepted": gust_sig, "step": len(accepted), "refitted": True,
            "shrink_in_sample": gust.share, "shrink_holdout": None, "significant": gust_sig,
            "note": "noise kind: shrink is the share of the input-incoherent residual power it explains"})

    # --- verdict -------------------------------------------------------------------------------
    verdict = accepted[0].name if accepted else ("unmeasured_gust" if gust_sig else "none")
    not_ident = [{"effect": s.effect.name, "channel": s.effect.channel, "key": s.key, "reason": s.reason}
                 for s in skipped_all.values()]
    fp, comp, shifts, selected = [], [], {}, []
    for a in accepted:
        nulls = a.effect.nulls(base_fit.model if a.step == 0 else a.fit.model)
        f = footprint(data, a.fit, nulls, base_map, channels)
        for x in f:
            x["effect"] = a.key
        fp += f
        if a.step == 0:
            comp = compensation(data, a.fit, base_fit, nulls, base_map, channels)
        entry = next(r for r in ranking if r["key"] == a.key and r["step"] == a.step)
        selected.append({**entry, "parameter_shifts": parameter_shifts(base_fit, a.fit)})
    if accepted:
        shifts = parameter_shifts(base_fit, final)
    ambiguous = [c.key for c in amb_first if accepted and c.key != accepted[0].key]
    report = DiagnosisReport(
        verdict=verdict, status="ok", problems=problems, ranking=ranking, ambiguous=ambiguous,
        not_identifiable=not_ident, location=base_map.to_list(), footprint=fp, unexplained=unexplained,
        selected=selected, location_after=final_map_same.to_list(), compensation=comp, parameter_shifts=shifts,
        holdout=hold,
        noise={"model": noise, "bands": nb.edges.tolist(), "floor_method": base_map.method,
               "gust_test": None if gust is None else {"lr": gust.lr, "p": gust.p, "sigma_w": gust.sigma_w,
                                                       "share": gust.share, "samples": gust.n_samples}},
        settings={**settings, "elapsed_s": time.perf_counter() - t0, "shrink_in_sample": shrink_final,
                  "flagged_before": n_flag, "family_size": K0},
        details={"data": data, "base_fit": base_fit, "final_fit": final, "base_map": base_map,
                 "final_map": final_map_same, "edges": edges, "accepted": accepted, "channels": channels},
    )
    from .text import paragraph

    report.text = paragraph(report)
    return _attach(found, report)


def floor_weights(data, gmap, channels) -> np.ndarray:
    """1/sqrt(noise floor) per stacked analysis row and fitted channel, from the gap map's cells."""
    om = data.stacked_omega()
    nb = gmap.edges.size - 1
    b = np.clip(np.searchsorted(gmap.edges, om, side="right") - 1, 0, nb - 1)
    out = np.ones((om.size, len(channels)))
    for j, ch in enumerate(channels):
        fl = np.array([gmap.cell(ch, i).floor for i in range(nb)], float)
        ok = np.isfinite(fl) & (fl > 0)
        if not ok.any():
            continue
        fl[~ok] = np.median(fl[ok])
        out[:, j] = 1.0 / np.sqrt(fl[b])
    return out


def _rank_entry(c: Candidate, label, shr, in_sample, holdout, accepted: bool, n_obs: int, sig: bool) -> dict:
    units = {p.name: p.unit for p in c.effect.params}
    try:
        units.update({p.name: p.unit for p in c.effect.param_list(c.fit.model)} if c.fit is not None else {})
    except Exception:  # pragma: no cover
        pass
    logn = math.log(max(n_obs, 2))
    return {
        "effect": c.name, "key": c.key, "channel": c.channel, "lr": c.lr, "p_value": c.p, "p_holm": c.p_holm,
        "log10_p": c.logp / math.log(10), "shrink": shr, "shrink_in_sample": in_sample, "shrink_holdout": holdout,
        "label": label,
        "params": {k: {"value": v, "stderr": se, "unit": units.get(k, "")} for k, (v, se) in c.params.items()},
        "df": c.df, "null": c.null, "delta_aic": 2 * c.q_eff - c.lr, "delta_bic": c.q_eff * logn - c.lr,
        "lm": c.screen.lm if c.screen is not None else None, "refitted": c.refitted, "plausible": c.plausible,
        "significant": bool(sig),
        "accepted": accepted, "step": c.step,
        "aliasing": c.screen.aliasing if c.screen is not None else None,
        "mde": c.screen.mde if c.screen is not None else None,
    }


def _empty(status: str, problems: list, settings: dict) -> DiagnosisReport:
    rep = DiagnosisReport(verdict="none", status=status, problems=problems, ranking=[], ambiguous=[],
                          not_identifiable=[], location=[], footprint=[], unexplained=[], settings=settings)
    rep.text = "No verdict: " + "; ".join(problems)
    return rep
