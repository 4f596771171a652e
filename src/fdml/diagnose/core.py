"""``diagnose``: locate the gap, attribute it to an effect, measure how far it shrinks.

See :mod:`fdml.diagnose` for the method and ``docs/diagnosis_method.md`` for
the design study this follows (and where it departs from it).
"""

from __future__ import annotations

import functools
import inspect
import logging
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..channels import OUTPUTS
from ..errors import FdmlError, ParameterError
from ..estimate import NoiseModel
from ..fit_options import parse_outputs
from ..kinematics import KinematicEvidence, flight_path_findings, kinematic_evidence, known_terms
from ..kinematics import members as _members_of
from ..models.base import Model, model_airspeed
from ..models.effects import Effect, applied_effects, default_library, registered_effects, root_model, with_effects
from ..parameters import Role
from ..record import Record
from ..verdict import ABSORBS, LEVEL
from ..warning_log import merged, recording
from .attribute import Candidate, attribute_step, choose, p_value
from .data import AnalysisData, analysis_data
from .disturbance import GustTest, gust_test
from .likelihood import DiagFit, fit_model, likelihood_ratio, noise_bands
from .locate import GapMap, default_bands, holm
from .report import SHRINK_CONFIRM, DiagnosisReport, label_for
from .shrink import (
    compensation,
    fit_map,
    footprint,
    frozen_fit,
    parameter_shifts,
    shrink,
)
from .text import paragraph

__all__ = ["diagnose", "recommended_fit"]

logger = logging.getLogger(__name__)


def _resolve(records, base, outputs=None):
    """(records, base model, its fit options): a FitResult's model, records and options, and the model
    predicting the fitted ``outputs`` (theta, q_dot beside alpha, q and a_z), as :func:`fdml.fit` has it."""
    from ..results import FitResult

    opts = {}
    if isinstance(base, FitResult):
        if records is None:
            records = [base.record(i) for i in range(len(base.time_records))]
        opts = {
            "outputs": tuple(base.outputs),
            "boundary": base.boundary,
            "input_edges": base.options.get("input_edges", "none"),
        }
        base = base.model
    if not isinstance(base, Model):
        raise ParameterError(f"base must be an fdml Model or FitResult, got {type(base).__name__}")
    if records is None:
        raise FdmlError("no records were given to diagnose")
    outputs = opts.get("outputs") if outputs is None else outputs
    if outputs:  # the rows the spectra and the predictions follow
        base = base.with_outputs(parse_outputs(outputs))
    return _as_list(records), base, {**opts, "outputs": outputs}


def _as_list(records) -> list:
    if records is None:
        return []
    return [records] if isinstance(records, Record) else list(records)


def _data_findings(records, model, band, strict: bool) -> list:
    """The data check on every record, issued as warnings (fdml.datacheck)."""
    from ..datacheck import check_data
    from ..findings import emit, raise_if_strict

    lohi = None
    if band is not None:  # the diagnosis takes LO:HI; the check needs a grid: 100 steps over it
        lo, hi = band.split(":")[:2] if isinstance(band, str) else band[:2]
        lohi = (float(lo), float(hi), (float(hi) - float(lo)) / 100)
    found = [f for r in records for f in check_data(r, band=lohi, airspeed=model_airspeed(model)).findings]
    raise_if_strict(found, strict)
    emit(found, stacklevel=3)
    return found


def _library(library) -> list:
    if library is None:
        return list(registered_effects())
    library = list(library)
    names = [str(item) for item in library if not isinstance(item, Effect)]
    return [item for item in library if isinstance(item, Effect)] + list(default_library(names) if names else ())


def _kinematics(su, model) -> tuple[KinematicEvidence | None, str]:
    """The short-period identity on the analysis spectra (fdml.kinematics), or None and why not."""
    missing = [c for c in OUTPUTS if c not in su.channels]
    if missing:
        return None, f"the kinematic identity needs alpha, q and a_z; {', '.join(missing)} not fitted"
    U = model_airspeed(model)
    if U is None:
        return None, "the kinematic identity needs the airspeed U"
    try:
        return kinematic_evidence(su.data.spectra, U, known=known_terms(model)), ""
    except (FdmlError, np.linalg.LinAlgError, ValueError) as exc:  # reported, never fatal
        return None, f"the kinematic identity could not be evaluated: {exc}"


@dataclass(frozen=True)
class _Sensors:
    """The base model as given against the base with the settled sensor effects (phase 0)."""

    raw_fit: object  # DiagFit of the model as given (None when it failed)
    raw_map: GapMap | None  # its gap map: where the model as given misses
    shrink: float | None  # in-sample shrink of the flagged gap by the settled effects
    shrink_holdout: float | None
    n_flagged: int


def _sensor_stage(su, raw_model, base_fit, base_map, holdout) -> _Sensors:
    """How far the settled sensor effects close the gap of the model as given, in-sample and held out."""
    if su.kin is None or not su.kin.settled:
        return _Sensors(base_fit, base_map, None, None, 0)
    try:
        raw_fit = fit_model(su.data, raw_model, su.nb, **su.options)
    except FdmlError:
        return _Sensors(None, None, None, None, 0)
    raw_map = su.fit_map(raw_fit)
    shr, nflag = shrink(raw_map, su.fit_map(base_fit, before=raw_map))
    hs = None
    if holdout is not None:
        _, _, hmap = _holdout_maps(su, holdout)
        h_raw = hmap(raw_fit.model)
        hs, nflag_h = shrink(h_raw, hmap(base_fit.model, h_raw))
        nflag = nflag_h if hs is not None else nflag
    return _Sensors(raw_fit, raw_map, shr, hs, nflag)


def _settled_model(model, kin: KinematicEvidence | None):
    """``model`` with the sensor effects the kinematics settled, each fixed at its kinematic value."""
    if kin is None or not kin.settled:
        return model
    m = with_effects(model, *[s.effect() for s in kin.settled])
    return m.fix({s.param: s.value for s in kin.settled})


@dataclass(frozen=True)
class _Setup:
    """What every phase of a diagnosis needs: analysis data, noise model, gap-map bands, options."""

    data: AnalysisData
    nb: NoiseModel  # the band-wise noise of every fit
    edges: np.ndarray  # gap-map band edges, rad/s
    channels: tuple
    options: dict  # outputs, boundary, biases, input_edges (as fdml.fit; edges as the base fit resolved them)
    effects: tuple
    alpha: float
    n_obs: int  # real independent observations (for BIC)
    settings: dict
    model: Model  # the base model as given (its gust option sets the hold-out's inputs)
    noise: str
    trim: str
    shrink_threshold: float
    designs: dict = field(default_factory=dict, repr=False)  # gap-map regressors, shared by every in-sample map
    kin: KinematicEvidence | None = None  # what alpha, q and a_z say about their sensors (settled first)
    kin_note: str = ""  # why there is no kinematic evidence
    flight_path: tuple = ()  # the time-domain flight-path reconstruction's findings, per record

    def fit_map(self, fit, before=None, *, own: bool = False):
        """The gap map of an in-sample fit: with ``before``, that map's noise floors held; the regressors
        (forced responses) are the base fit's, shared by every map (same regressors before and after),
        unless ``own`` (the fit's own regressors, for the remaining gap)."""
        designs = None if own else self.designs
        return fit_map(
            self.data, fit, self.edges, alpha=self.alpha, channels=self.channels, before=before, designs=designs
        )


@dataclass(frozen=True)
class _Selection:
    """Forward selection's outcome (phase 2)."""

    accepted: list  # Candidates, in the order accepted
    ambiguity: list  # per accepted candidate, its ambiguity set
    tested: list  # every tested Candidate of every step
    skipped: dict  # key -> Candidate not testable (first step), and the turbulence test if it could not run
    family: int | None  # size of the first step's family (Holm), the turbulence test included
    step_fits: list  # the fit each step's candidates were added to
    final: DiagFit  # after the last accepted effect
    gust: GustTest | None
    gust_sig: bool
    gust_effect: Effect | None


@dataclass(frozen=True)
class _Shrink:
    """Shrink in-sample and on the hold-out records (phase 3)."""

    in_sample: dict  # (key, step) -> (shrink, flagged cells)
    holdout: dict  # (key, step) -> (shrink, flagged cells) on the hold-out records
    final_map: GapMap  # final fit's map with the base floors
    unexplained: list
    shrink_final: float | None
    n_flagged: int
    hold: dict | None  # the report's hold-out section

    @property
    def n_unexplained(self) -> int:
        """Flagged cells left in the final fit's own map, in-sample (what the labels judge: report.UNEXPLAINED_RULE)."""
        return sum(u["where"] == "in-sample" for u in self.unexplained)


def _steps_compared(rep: DiagnosisReport, boundary, biases) -> tuple[str | None, dict | None]:
    """How the timing of every elevator step between samples (docs/theory.md section 7a) compares with the
    model the diagnosis ``rep`` chose without it: ``("better", None)``, ``("equal", alternative)`` or
    ``(None, None)``.

    The base model and every model along the selection are refitted with the steps' timing.  "better":
    one has a lower BIC (``2 C / K + k ln n`` on the diagnosis's grid: C its band-wise cost, K its
    oversampling, k the estimates, n the real independent observations) than the chosen model.
    "equal": none does, but some with other effects than the chosen ones explain the gap as well as it by
    :func:`fdml.score.equally` on Akaike-penalised LRs against the base fit; ``alternative`` is then the
    entry for ``recommendation["alternatives"]`` of the one with the fewest effects.  Only for records
    whose elevator steps between samples and a diagnosis that found a significant candidate (else there
    is no gap to explain).
    """
    from ..score import equally

    final = rep.details.get("final_fit")
    if final is None or not any(r.get("significant") for r in rep.ranking):
        return None, None
    data = rep.details["data"]
    if not any(d.edges.size for d in data.spectra):  # the steps the analysis spectra hold
        return None, None
    st, base_fit = rep.settings, rep.details["base_fit"]
    nb = NoiseModel(tuple(rep.noise["bands"]))
    K, logn = st["oversample"], math.log(max(2 * st["independent_frequencies"] * len(st["outputs"]), 2))

    def bic(f: DiagFit) -> float:
        return 2.0 * f.cost / K + len(f.names) * logn

    def aic_lr(f: DiagFit) -> float:  # against the base fit, Akaike-penalised
        return 2.0 * (base_fit.cost - f.cost) / K - 2.0 * (len(f.names) - len(base_fit.names))

    # the base and every model along the selection (step i's refit holds the effects accepted so far)
    path = [base_fit.model] + [a.fit.model for a in rep.details.get("accepted", ()) if a.fit]
    fits = []
    for model in path if final.model in path else [*path, final.model]:  # instead of the effects, or beside
        try:
            edged = fit_model(
                data, model, nb, outputs=st["outputs"], boundary=boundary, biases=biases, input_edges="estimated"
            )
        except FdmlError:
            continue
        if edged.converged:
            fits.append(edged)
    if not fits:
        return None, None
    if min(bic(f) for f in fits) < bic(final):
        return "better", None
    # of those that stand for other effects than the chosen ones (the steps' timing in place of some) and
    # that the data cannot tell from the chosen model, the one with the fewest effects
    chosen = {e.key for e in applied_effects(final.model)}
    tied = [
        f
        for f in fits
        if {e.key for e in applied_effects(f.model)} != chosen
        and equally(max(aic_lr(final), aic_lr(f)), min(aic_lr(final), aic_lr(f)))
    ]
    if not tied:
        return None, None
    best = min(tied, key=lambda f: (len(applied_effects(f.model)), bic(f)))
    root = [p.name for p in base_fit.model.parameters if p.free and p.role is Role.AERO]
    return "equal", {
        "effects": [e.key for e in applied_effects(best.model)],
        "input_edges": "estimated",
        "params": {},
        "derivatives": {n: {"value": best.params[n], "stderr": best.stderr.get(n, math.nan)} for n in root},
        "lr": 2.0 * (base_fit.cost - best.cost) / K,
    }


def _steps_compete(diag):
    """``diag`` (:func:`diagnose`) letting the elevator steps' timing compete with the effects (theory 7a).

    With ``input_edges=None`` (its default) the diagnosis runs without the steps' timing, and again with
    it when that lowers the BIC of the model it chose (:func:`_steps_compared`); when the data cannot
    tell the two apart, the report is marked ambiguous with the steps' timing among its alternatives.
    Its report says which.
    """
    params = inspect.signature(diag).parameters

    @functools.wraps(diag)
    def run(records=None, base=None, **kw):
        given = kw.get("input_edges")
        rep = diag(records, base, **{**kw, "input_edges": given or "none"})
        if given is not None:
            return rep
        how, alt = _steps_compared(rep, **{k: kw.get(k, params[k].default) for k in ("boundary", "biases")})
        if how == "better":
            again = diag(records, base, **{**kw, "input_edges": "estimated"})
            note = (
                "The elevator steps between samples, and their timing explains the gap (a lower BIC for the "
                "base model, or the model the diagnosis chose, with every step's timing than for the chosen "
                "model without): every step's timing is estimated (--input-edges estimated; docs/theory.md "
                "section 7a)."
            )
            rep = replace(again, settings={**again.settings, "input_edges": note})
        elif how == "equal":
            rep = _with_steps_alternative(rep, alt)
        else:
            return rep
        return replace(rep, text=paragraph(rep))

    return run


def _with_steps_alternative(rep: DiagnosisReport, alt: dict) -> DiagnosisReport:
    """``rep`` marked ambiguous: the steps' timing ``alt`` explains the gap as well as the chosen model."""
    rec = dict(rep.recommendation)
    chosen = [s["key"] for s in rep.selected]
    alts = list(rec.get("alternatives") or [])
    if not alts:
        derivs = {
            n: {"value": v["recommended"][0], "stderr": v["recommended"][1]}
            for n, v in rec.get("derivatives", {}).items()
            if v.get("recommended")
        }
        alts = [{"effects": chosen, "params": {}, "derivatives": derivs, "lr": None}]
    rec.update(ambiguous=True, alternatives=[*alts, alt])
    with_ = "+".join(alt["effects"]) or "the base model"
    note = (
        f"The elevator steps between samples: {with_} with every step's timing explains the gap as well as "
        f"{'+'.join(chosen) or 'the base model'} (these data cannot tell them apart; --input-edges estimated "
        "fits the steps' timing; docs/theory.md section 7a)."
    )
    return replace(rep, recommendation=rec, settings={**rep.settings, "input_edges_alternative": note})


@_steps_compete
def diagnose(
    records=None,
    base=None,
    *,
    holdout=None,
    band=None,
    bands=None,
    library=None,
    alpha: float = LEVEL,
    max_effects: int = 2,
    oversample: int = 2,
    noise: str = "band",
    refit_top: int = 4,
    outputs=None,
    boundary: str = "estimated",
    biases="auto",
    input_edges: str | None = None,
    trim: str = "first",
    shrink_threshold: float = SHRINK_CONFIRM,
    check: bool = True,
    strict: bool = False,
) -> DiagnosisReport:
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
    outputs : sequence of str or str, optional
        Outputs that enter the fits (default ``alpha, q, az``), as in :func:`fdml.fit`.
    boundary : {"estimated", "measured", "none"}, optional
        Boundary terms, as in :func:`fdml.fit`.
    biases : {"auto", True, False}, optional
        Output biases, as in :func:`fdml.fit`.
    input_edges : {"none", "estimated", "auto"} or None, optional
        The elevator steps' timing terms, as in :func:`fdml.fit`: the base fit settles
        ``"auto"``, and every later fit takes its choice (one input for every model compared).
        None (default): none, unless the records' elevator steps between samples and, with a
        significant gap, the base model or a model along the selection has a lower BIC with every
        step's timing than the model chosen without (where the steps were is not in the record);
        the diagnosis is then run again with every step's timing estimated (docs/theory.md
        section 7a), and its ``settings["input_edges"]`` says why.  When the two cannot be told
        apart, the recommendation is marked ambiguous with the steps' timing among its
        alternatives (``settings["input_edges_alternative"]``).
    trim : {"first", "mean", "none"}, optional
        Trim removal, as in :func:`fdml.spectral.spectra`.
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
        Its ``recommended`` is :func:`fdml.fit` of the base model plus the
        accepted effects (see :func:`recommended_fit`).
    """
    input_edges = input_edges or "none"
    t0 = time.perf_counter()
    records, model, fopts = _resolve(records, base, outputs)
    found = _data_findings(list(records) + _as_list(holdout), model, band, strict) if check else []
    outputs = fopts["outputs"]
    boundary = fopts.get("boundary", boundary)
    input_edges = fopts.get("input_edges", input_edges)
    if not (0 < alpha < 1):
        raise ParameterError(f"alpha must lie in (0, 1), got {alpha}")
    if isinstance(max_effects, bool) or not isinstance(max_effects, (int, np.integer)) or max_effects < 0:
        raise ParameterError(f"max_effects must be an integer >= 0, got {max_effects!r}")
    # the set-up every phase shares: analysis data, noise bands, gap-map edges, settings (bad options raise here)
    effects = _library(library)
    data = analysis_data(records, band, oversample=oversample, trim=trim, gust=model.gust, outputs=model.outputs)
    nb = noise_bands(data, mode=noise)
    channels = parse_outputs(outputs or None)
    edges = np.asarray(bands, float) if bands is not None else default_bands(data)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise ParameterError("bands must be increasing edges in rad/s, at least two")
    su = _Setup(
        data=data,
        nb=nb,
        edges=edges,
        channels=channels,
        options={"outputs": outputs, "boundary": boundary, "biases": biases, "input_edges": input_edges},
        effects=tuple(effects),
        alpha=alpha,
        n_obs=2 * data.n_dft * len(channels),
        settings={
            "alpha": alpha,
            "band": list(data.band),
            "bands": edges.tolist(),
            "oversample": oversample,
            "noise": noise,
            "noise_bands": list(nb.edges),
            "refit_top": refit_top,
            "max_effects": max_effects,
            "records": data.names(),
            "independent_frequencies": data.n_dft,
            "base_model": model.describe(),
            "shrink_threshold": shrink_threshold,
            "outputs": list(channels),
        },
        model=model,
        noise=noise,
        trim=trim,
        shrink_threshold=shrink_threshold,
    )
    kin, kin_note = _kinematics(su, model)
    raw_model, model = model, _settled_model(model, kin)
    su = replace(su, kin=kin, kin_note=kin_note, flight_path=tuple(flight_path_findings(records)))
    try:
        base_fit = fit_model(su.data, model, su.nb, **su.options)
    except FdmlError as exc:
        return _empty("base_fit_failed", [f"the base model could not be fitted: {exc}"], su.settings, found)
    if base_fit.result is not None:  # every later fit takes the steps' timing as the base fit settled it
        su = replace(su, options={**su.options, "input_edges": base_fit.result.options.get("input_edges", "none")})
    if not base_fit.converged:
        why = (
            f"the base fit did not converge ({base_fit.message}); no effect can be attributed against an "
            "unconverged base"
        )
        return _empty("base_not_converged", [why], su.settings, found, warned=base_fit.warnings)
    return _attribute(su, raw_model, base_fit, holdout, found, t0, max_effects=max_effects, refit_top=refit_top)


def _attribute(
    su: _Setup, raw_model, base_fit, holdout, found: list, t0: float, *, max_effects: int, refit_top: int
) -> DiagnosisReport:
    """The phases after the base fit: locate, attribute, shrink, the recommended fit and the report."""
    base_map, problems = _locate(su, base_fit)
    if not any(c.excitation == "ok" for c in base_map.cells):
        return _empty(
            "insufficient_excitation",
            problems + ["no band has enough excitation to say anything about the model; no verdict"],
            su.settings,
            found,
            location=base_map.to_list(),
            warned=base_fit.warnings,
        )
    sel = _select(su, base_fit, base_map, max_effects=max_effects, refit_top=refit_top)
    shr = _shrink_holdout(su, base_fit, base_map, sel, holdout)
    with recording(reemit=False) as log:  # kept in the report
        rec = recommended_fit(
            su.data,
            base_fit.model,
            [a.effect for a in sel.accepted],
            start=sel.final.model,
            settled=su.kin.settled if su.kin is not None else (),
            **su.options,
        )
    warned = merged(
        base_fit.warnings, sel.final.warnings, *(a.fit.warnings for a in sel.accepted), log, rec.warnings if rec else ()
    )
    sensors = _sensor_stage(su, raw_model, base_fit, base_map, holdout)
    return _assemble(su, base_fit, base_map, sel, shr, problems, found, rec, t0, warned, sensors)


# --- phase 1: locate ---------------------------------------------------------------------------------------------


def _locate(su: _Setup, base_fit):
    """The base fit's gap map, and the cells too thinly excited to test (as problems)."""
    base_map = su.fit_map(base_fit)
    problems = []
    for c in base_map.cells:
        if c.excitation == "ok":
            continue
        where = f"{c.channel} {c.band[0]:.3g}-{c.band[1]:.3g} rad/s: {c.excitation}"
        problems.append(f"{where} (gain resolvable to {c.gain_se_db:.2g} dB only)" if c.gain_se_db else where)
    return base_map, problems


# --- phase 2: attribution by greedy forward selection, then turbulence -------------------------------------------


def _select(su: _Setup, base_fit, base_map, *, max_effects: int, refit_top: int) -> _Selection:
    """Greedy forward selection of deterministic effects, then the unmeasured-turbulence test."""
    fw = floor_weights(su.data, base_map, su.channels)
    gust_eff = next((e for e in su.effects if e.kind == "noise" and e.name == "unmeasured_gust"), None)
    cur = base_fit
    accepted: list[Candidate] = []
    ambiguity: list[list[Candidate]] = []
    all_tested: list[Candidate] = []
    step_fits: list[DiagFit] = []
    skipped_all: dict = {}
    K0 = None
    # what the model already holds (known sensor positions, the kinematics' settled effects) is not tested
    held = {e.key for e in applied_effects(base_fit.model)}
    remaining = [e for e in su.effects if e.kind == "deterministic" and e.key not in held]
    for step in range(max(int(max_effects), 0)):
        step_fits.append(cur)
        tested, skipped = _step(su, cur, remaining, step, refit_top, fw)
        if step == 0:
            K0 = len(tested) + (1 if gust_eff is not None else 0)
            # Holm over the whole first-step family, the turbulence test included
            ps = [c.p for c in tested] + ([1.0] if gust_eff is not None else [])
            for c, a in zip(tested, holm(np.array(ps))):
                c.p_holm = float(a)
            for s in skipped:
                skipped_all.setdefault(s.key, s)
        all_tested.extend(tested)
        best, amb = choose(tested, su.alpha, su.n_obs)
        if best is None:
            break
        if accepted:
            _backward_check(su, base_fit, accepted, best)
        accepted.append(best)
        ambiguity.append(amb)
        cur = best.fit
        remaining = [e for e in remaining if e.key != best.key]
    gust, gust_sig = _turbulence(su, cur, gust_eff, K0, skipped_all)
    return _Selection(
        accepted=accepted,
        ambiguity=ambiguity,
        tested=all_tested,
        skipped=skipped_all,
        family=K0,
        step_fits=step_fits,
        final=cur,
        gust=gust,
        gust_sig=gust_sig,
        gust_effect=gust_eff,
    )


def _step(su: _Setup, cur, remaining: list, step: int, refit_top: int, fw) -> tuple:
    """One attribution step; the first tests the kinematics' alias set alone when there is one, and the
    whole library when none of those can be accepted."""
    first = _kinematic_first(su, remaining) if step == 0 else []
    for cands in ([first] if first else []) + [remaining]:
        tested, skipped = attribute_step(
            su.data,
            cur,
            cands,
            su.nb,
            su.nb.assign(su.data.stacked_omega()),  # the noise band of each stacked row
            su.options,
            alpha=su.alpha,
            refit_top=refit_top,
            step=step,
            n_obs=su.n_obs,
            floor_weights=fw,
            kin=su.kin,
            refit_all=cands is first,
        )
        if cands is remaining or choose(tested, su.alpha, su.n_obs)[0] is not None:
            return tested, skipped
    return tested, skipped


def _kinematic_first(su: _Setup, remaining: list) -> list:
    """The first step's candidates when the kinematics show a sensor pattern they cannot attribute:
    its alias set's members, every one refitted (sensors first: no aerodynamic effect is tested
    before the sensors are settled).  Empty otherwise."""
    if su.kin is None or not su.kin.aliases:
        return []
    keys = {m.key for m in su.kin.aliases[0]}
    return [e for e in remaining if e.key in keys]


def _backward_check(su: _Setup, base_fit, accepted: list, best) -> None:
    """Is the effect accepted last still needed next to the new one?  Drops it from ``accepted`` if not."""
    prev = accepted[-1]
    try:
        only_new = fit_model(su.data, best.effect.augment(base_fit.model), su.nb, start=best.fit.params, **su.options)
        lr_prev = likelihood_ratio(only_new.cost, best.fit.cost, su.data.oversample)
        p_prev, _ = p_value(lr_prev, prev.df, prev.null)
    except FdmlError:  # pragma: no cover
        return
    if p_prev >= su.alpha:
        logger.info("backward check drops %s (p = %.3g) once %s is in", prev.key, p_prev, best.key)
        accepted.remove(prev)
        prev.reason = f"dropped by the backward check (p = {p_prev:.3g} once {best.key} is in)"


def _turbulence(su: _Setup, cur, gust_eff, K0, skipped_all: dict):
    """Unmeasured turbulence, tested after the deterministic effects: (GustTest or None, significant)."""
    if gust_eff is None:
        return None, False
    why = gust_eff.applicable(cur.model, inputs=su.data.inputs, outputs=su.channels)
    if why is None and len(su.channels) < 2:
        why = "needs at least two output channels"
    if why is None:
        try:
            gust = gust_test(su.data, cur, su.edges)
        except (FdmlError, np.linalg.LinAlgError, ValueError) as exc:
            why = f"cannot be evaluated: {exc}"
    if why is not None:
        skipped_all[gust_eff.key] = Candidate(gust_eff, gust_eff.key, identifiable=False, reason=why)
        return None, False
    if gust is None:  # no band holds two samples
        return None, False
    return gust, min(1.0, gust.p * max(K0 or 1, 1)) < su.alpha


# --- phase 3: shrink, in-sample and on the hold-out records ------------------------------------------------------


def _shrink_holdout(su: _Setup, base_fit, base_map, sel: _Selection, holdout) -> _Shrink:
    """Shrink of every refitted candidate and of the final fit (flagged cells only, rule 6).

    A candidate at forward step k is compared with the model it was added to (step k's fit) on the
    cells still flagged there, so a second effect is credited with the share of the *remaining* gap
    it removes.
    """
    refitted = [c for c in sel.tested if c.refitted]
    step_maps = {k: su.fit_map(f, before=base_map) if k else base_map for k, f in enumerate(sel.step_fits)}
    in_shr = {(c.key, c.step): shrink(step_maps[c.step], su.fit_map(c.fit, before=base_map)) for c in refitted}
    final_map_same = su.fit_map(sel.final, before=base_map)
    final_map = su.fit_map(sel.final, own=True)
    unexplained = [dict(c.to_dict(), where="in-sample") for c in final_map.cells if c.significant]
    shrink_final, n_flag = shrink(base_map, final_map_same)
    h_shr, hold = {}, None
    if holdout is not None:
        h_shr, hold = _holdout(su, base_fit, sel, refitted, holdout)
        unexplained += hold["unexplained"]
    return _Shrink(
        in_sample=in_shr,
        holdout=h_shr,
        final_map=final_map_same,
        unexplained=unexplained,
        shrink_final=shrink_final,
        n_flagged=n_flag,
        hold=hold,
    )


def _holdout_maps(su: _Setup, holdout, designs: dict | None = None):
    """The hold-out records' analysis data and noise bands, and ``hmap(model, before=None)``: the gap map
    of ``model`` with every model parameter frozen on them (``before``'s floors held; ``designs`` shared)."""
    hdata = analysis_data(holdout, su.data.band, oversample=su.data.oversample, trim=su.trim, gust=su.model.gust)
    hnb = noise_bands(hdata, mode=su.noise)

    def hmap(model, before=None):
        hf = frozen_fit(hdata, model, hnb, su.options)
        return fit_map(hdata, hf, su.edges, alpha=su.alpha, channels=su.channels, before=before, designs=designs)

    return hdata, hnb, hmap


def _holdout(su: _Setup, base_fit, sel: _Selection, refitted: list, holdout):
    """Shrink on the hold-out records with every model parameter frozen: ({(key, step): shrink}, section)."""
    designs: dict = {}
    hdata, hnb, hmap = _holdout_maps(su, holdout, designs)
    h_before = hmap(base_fit.model)
    h_step = {k: hmap(f.model, h_before) if k else h_before for k, f in enumerate(sel.step_fits)}
    h_shr = {(c.key, c.step): shrink(h_step[c.step], hmap(c.fit.model, h_before)) for c in refitted}
    h_final = frozen_fit(hdata, sel.final.model, hnb, su.options)
    h_final_same = fit_map(
        hdata, h_final, su.edges, alpha=su.alpha, channels=su.channels, before=h_before, designs=designs
    )
    h_final_own = fit_map(hdata, h_final, su.edges, alpha=su.alpha, channels=su.channels)
    h_unexp = [dict(c.to_dict(), where="holdout") for c in h_final_own.cells if c.significant]
    hs_final, hn_flag = shrink(h_before, h_final_same)
    return h_shr, {
        "records": hdata.names(),
        "location": h_before.to_list(),
        "location_after": h_final_same.to_list(),
        "shrink": hs_final,
        "flagged_before": hn_flag,
        "unexplained": h_unexp,
        "warnings": list(h_final.warnings),  # of the frozen fit of the final model
    }


# --- the recommended model -------------------------------------------------------------------------------------


def recommended_fit(
    data,
    base_model: Model,
    effects,
    *,
    start: Model | None = None,
    settled=(),
    outputs=None,
    boundary: str = "estimated",
    biases="auto",
    input_edges: str = "none",
):
    """:func:`fdml.fit` of ``base_model`` plus ``effects`` on the diagnosis's analysis grid.

    The model is built as a user would build it (``with_effects(base_model, *effects)``), so its result
    saves and reloads like any fit; start values are the diagnosis's final estimates (``start``).
    Otherwise ``fdml fit``'s defaults: white noise, the ``white`` covariance.  None when it cannot be
    fitted (the reason is logged).

    Parameters
    ----------
    data : AnalysisData
        The records' spectra on the analysis grid.
    base_model : Model
        The base model (values: the base fit's estimates).
    effects : sequence of Effect
        The accepted effects, in order.
    start : Model, optional
        A model whose parameter values (shared names) start the fit.
    settled : sequence of fdml.kinematics.SensorEffect, optional
        Sensor effects the kinematics settled: fixed in ``base_model`` at their kinematic values,
        their standard errors carried into the covariance (:func:`fdml.propagate.with_known_uncertainty`).
    outputs : sequence of str or str, optional
        Outputs that enter the fit (default ``alpha, q, az``), as in :func:`fdml.fit`.
    boundary : {"estimated", "measured", "none"}, optional
        Boundary terms, as in :func:`fdml.fit`.
    biases : {"auto", True, False}, optional
        Output biases, as in :func:`fdml.fit`.
    input_edges : {"none", "estimated", "auto"}, optional
        The elevator steps' timing terms, as in :func:`fdml.fit`.

    Returns
    -------
    FitResult or None
        Its warnings are in its ``warnings``, the adequacy advice worded for
        the diagnosis (:func:`fdml.adequacy.reworded`); :func:`diagnose` keeps
        them in the report.
    """
    from ..adequacy import reworded
    from ..estimate import fit as fdml_fit
    from ..propagate import with_known_uncertainty

    model = with_effects(base_model, *effects) if effects else base_model
    if start is not None:
        sv = start.parameters.values.items()
        model = model.with_values({k: v for k, v in sv if k in model.parameters and math.isfinite(v)})

    opts = {"outputs": outputs, "boundary": boundary, "biases": biases, "input_edges": input_edges}
    refit = functools.partial(fdml_fit, list(data.spectra), check=False, **opts)  # the diagnosis checked the records
    try:
        with recording(reemit=False):  # kept in res.warnings
            res = reworded(refit(model), in_diagnosis=True)  # its advice does not send the user to this diagnosis
            if settled:  # the two refits' warnings repeat the fit's
                res = with_known_uncertainty(
                    res, lambda v: refit(res.model.with_values(v), adequacy=False), {s.param: s.stderr for s in settled}
                )
        return res
    except FdmlError as exc:
        logger.warning("the recommended model could not be fitted: %s", exc)
        return None


# --- phase 4: the report -----------------------------------------------------------------------------------------


def _assemble(
    su: _Setup,
    base_fit,
    base_map,
    sel: _Selection,
    shr: _Shrink,
    problems: list,
    found: list,
    recommended,
    t0: float,
    warned: tuple,
    sensors: _Sensors,
) -> DiagnosisReport:
    """Labels, verdict, footprints and compensation of the accepted effects: the frozen report.

    ``warned``: the warnings of the fits the report keeps (base, final, accepted, recommended);
    ``sensors``: the model as given against the one with the settled sensor effects.
    """
    settled = _settled_entries(su, sensors, n_unexplained=shr.n_unexplained)
    ranking = settled + _ranking(su, sel, shr, n_settled=len(settled))
    verdict = "unmeasured_gust" if sel.gust_sig else "none"
    if settled or sel.accepted:
        verdict = settled[0]["effect"] if settled else sel.accepted[0].name
    not_ident = [
        {"effect": s.effect.name, "channel": s.effect.channel, "key": s.key, "reason": s.reason}
        for s in sel.skipped.values()
    ]
    fp, comp, selected = [], [], []
    for a in sel.accepted:
        nulls = a.effect.nulls(base_fit.model if a.step == 0 else a.fit.model)
        fp += [dict(x, effect=a.key) for x in footprint(su.data, a.fit, nulls, base_map)]
        if a.step == 0:
            comp = compensation(su.data, a.fit, base_fit, nulls, base_map)
        entry = next(r for r in ranking if r["key"] == a.key and r["step"] == a.step)
        selected.append({**entry, "parameter_shifts": parameter_shifts(base_fit, a.fit)})
    selected = settled + [_as_recommended(e, recommended, su.kin) for e in selected]
    shifts = parameter_shifts(base_fit, sel.final) if sel.accepted else {}
    amb_first = sel.ambiguity[0] if sel.ambiguity else []
    ambiguous = [c.key for c in amb_first if sel.accepted and c.key != sel.accepted[0].key]
    gust = sel.gust
    report = DiagnosisReport(
        verdict=verdict,
        status="ok",
        problems=problems,
        ranking=ranking,
        ambiguous=ambiguous,
        not_identifiable=not_ident,
        location=(sensors.raw_map or base_map).to_list(),
        footprint=fp,
        unexplained=shr.unexplained,
        selected=selected,
        location_after=shr.final_map.to_list(),
        compensation=comp,
        parameter_shifts=shifts,
        holdout=shr.hold,
        noise={
            "model": su.noise,
            "bands": list(su.nb.edges),
            "floor_method": base_map.method,
            "gust_test": None
            if gust is None
            else {"lr": gust.lr, "p": gust.p, "sigma_w": gust.sigma_w, "share": gust.share, "samples": gust.n_samples},
        },
        settings={
            **su.settings,
            "elapsed_s": time.perf_counter() - t0,
            "shrink_in_sample": shr.shrink_final,
            "flagged_before": shr.n_flagged,
            "family_size": sel.family,
        },
        details={
            "data": su.data,
            "base_fit": base_fit,
            "final_fit": sel.final,
            "base_map": base_map,
            "final_map": shr.final_map,
            "edges": su.edges,
            "accepted": sel.accepted,
            "channels": su.channels,
        },
        findings=tuple(found),
        recommended=recommended,
        warnings=tuple(warned),
        kinematics={
            **(su.kin.to_dict() if su.kin is not None else {"note": su.kin_note}),
            "flight_path": list(su.flight_path),
        },
        recommendation=_recommendation(su, sel, recommended, sensors.raw_fit),
    )
    return replace(report, text=paragraph(report))


def _as_recommended(entry: dict, rec, kin) -> dict:
    """An accepted effect's entry with its sizes as the recommended fit has them (the diagnosis's own
    band-noise refit kept as ``diagnosis_fit``), and, for a sensor effect, the kinematic view beside:
    the identity's estimate of the same effect (``kinematic``), when it tested it."""
    out = dict(entry)
    if rec is not None:
        out["params"] = {
            n: dict(d, value=rec.params[n], stderr=rec.errors[n]) if n in rec.params else d
            for n, d in entry["params"].items()
        }
        out["diagnosis_fit"] = entry["params"]
    if kin is not None:
        for f in kin.tested:
            if entry["key"] in f.keys:
                m = next(x for x in _members_of(f) if x.key == entry["key"])
                out["kinematic"] = {m.param: {"value": m.value, "stderr": m.stderr, "unit": m.unit, "lr": f.lr}}
    return out


def _settled_entries(su: _Setup, sensors: _Sensors, n_unexplained: int) -> list:
    """Ranking entries of the sensor effects the kinematics settled (accepted before any other)."""
    if su.kin is None:
        return []
    shr = sensors.shrink_holdout if sensors.shrink_holdout is not None else sensors.shrink
    label = label_for(
        significant=True,
        accepted=True,
        ambiguous=False,
        plausible=True,
        shrink=shr,
        n_flagged=sensors.n_flagged,
        n_unexplained=n_unexplained,
        threshold=su.shrink_threshold,
    )
    return [
        {
            **_entry_head(m.effect(), m.key, m.finding.lr, m.finding.p, m.finding.p),
            "shrink": shr,
            "shrink_in_sample": sensors.shrink,
            "shrink_holdout": sensors.shrink_holdout,
            "n_flagged": sensors.n_flagged,  # the flagged cells the label judged
            "plausible": True,
            "label": label,
            "params": {m.param: {"value": m.value, "stderr": m.stderr, "unit": m.unit}},
            "accepted": True,
            "significant": True,
            "step": 0,
            "source": "kinematics",
            "note": f"settled by the kinematics: {m.finding.describe()}",
        }
        for m in su.kin.settled
    ]


def _derivative_table(raw, rec) -> dict:
    """Per free base parameter: the base model's estimate as given and the recommended one, with standard errors."""
    if rec is None:
        return {}
    aero = [p.name for p in root_model(rec.model).parameters if p.free and p.role is Role.AERO]
    return {
        n: {
            "recommended": [rec.params[n], rec.errors.get(n)],
            **({"base": [raw.params[n], raw.stderr.get(n)]} if raw is not None and n in raw.params else {}),
        }
        for n in aero
        if n in rec.params
    }


def _unit(c: Candidate, name: str) -> str:
    return next((p.unit for p in c.effect.params if p.name == name), "")


def _recommendation(su: _Setup, sel: _Selection, rec, raw_fit) -> dict:
    """What the recommended model is and how sure: settled sensors, ambiguity, alternatives, derivatives."""
    amb = sel.ambiguity[0] if sel.ambiguity else []
    settled = [m.key for m in su.kin.settled] if su.kin is not None else []
    alts = [
        {
            "effects": settled + [c.key],
            "params": {k: {"value": v, "stderr": e, "unit": _unit(c, k)} for k, (v, e) in c.params.items()},
            "derivatives": {k: {"value": v, "stderr": e} for k, (v, e) in c.derivatives.items()},
            "lr": c.lr,
        }
        for c in amb
    ]
    spread = {}
    if len(amb) > 1:
        for n in amb[0].derivatives:
            vals = [c.derivatives[n] for c in amb if n in c.derivatives]
            v = [x for x, _ in vals]
            se = min((e for _, e in vals if e and math.isfinite(e)), default=math.nan)
            spread[n] = {"min": min(v), "max": max(v), "in_stderr": (max(v) - min(v)) / se if se > 0 else None}
    return {
        "settled_by_kinematics": settled,
        "ambiguous": len(amb) > 1,
        "alternatives": alts if len(amb) > 1 else [],
        "spread": spread,
        "derivatives": _derivative_table(raw_fit, rec),
    }


def _ranking(su: _Setup, sel: _Selection, shr: _Shrink, n_settled: int = 0) -> list:
    """One entry per tested candidate (and the turbulence test, after the ``n_settled`` sensor effects the
    kinematics settled and the accepted ones), with its label."""
    acc_keys = [(a.key, a.step) for a in sel.accepted]
    ranking = []
    for c in sel.tested:
        sig = c.significant(su.alpha) and c.refitted
        in_sample, nfl = shr.in_sample.get((c.key, c.step), (None, 0))
        h = shr.holdout.get((c.key, c.step))
        shr_, nflag = h if (shr.hold and h is not None) else (in_sample, nfl)
        amb = any(len(s) > 1 for a, s in zip(sel.accepted, sel.ambiguity) if a.key == c.key and a.step == c.step)
        acc = (c.key, c.step) in acc_keys
        lab = label_for(
            significant=sig,
            accepted=acc,
            ambiguous=amb,
            plausible=c.plausible,
            shrink=shr_,
            n_flagged=nflag,
            n_unexplained=shr.n_unexplained,
            threshold=su.shrink_threshold,
        )
        if sig and c.demoted:
            lab = ABSORBS if c.demoted.startswith(ABSORBS) else "set aside"
        ranking.append(_rank_entry(c, lab, (shr_, in_sample, h[0] if h else None, nflag), acc, su.n_obs, sig))
    gust, K0 = sel.gust, sel.family
    if gust is not None:
        # a noise-kind effect is judged on its likelihood gain, not on the coherent gap (which it cannot
        # close): confirmed when no coherent gap is left unexplained, else partial
        glab = ("confirmed" if shr.n_unexplained == 0 else "partial") if sel.gust_sig else None
        ge = sel.gust_effect
        assert ge is not None  # a turbulence test ran, so the library holds the effect
        ranking.append(
            {
                **_entry_head(ge, ge.key, gust.lr, gust.p, min(1.0, gust.p * max(K0 or 1, 1))),
                "shrink": gust.share,
                "label": glab,
                "params": {"sigma_w": {"value": gust.sigma_w, "stderr": gust.sigma_w_se, "unit": "m/s"}},
                "df": 1,
                "null": "chibar",
                "accepted": sel.gust_sig,
                "step": len(sel.accepted) + n_settled,
                "refitted": True,
                "shrink_in_sample": gust.share,
                "shrink_holdout": None,
                "significant": sel.gust_sig,
                "note": "noise kind: shrink is the share of the input-incoherent residual power it explains",
            }
        )
    return ranking


def floor_weights(data, gmap, channels) -> np.ndarray:
    """1/sqrt(noise floor) per stacked analysis row and fitted channel, from the gap map's cells.

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    gmap : GapMap
        A gap map holding every channel's cells.
    channels : sequence of str
        The fitted channels.

    Returns
    -------
    numpy.ndarray
        Shape (N, n_channels): the weights, 1 / unit of the channel's transform
        (a cell without a floor takes the channel's median floor).
    """
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


def _entry_head(effect: Effect, key: str, lr: float, p: float, p_holm: float | None) -> dict:
    """The leading keys of a ranking entry: the effect, its key and channel, its LR and p-values."""
    return {"effect": effect.name, "key": key, "channel": effect.channel, "lr": lr, "p_value": p, "p_holm": p_holm}


def _rank_entry(c: Candidate, label, judged: tuple, accepted: bool, n_obs: int, sig: bool) -> dict:
    """A candidate's ranking entry; ``judged``: (shrink, in-sample, held-out shrink, flagged cells) of its label."""
    shr, in_sample, holdout, n_flagged = judged
    units = {p.name: p.unit for p in c.effect.params}
    try:
        units.update({p.name: p.unit for p in c.effect.param_list(c.fit.model)} if c.fit is not None else {})
    except Exception:  # pragma: no cover
        pass
    logn = math.log(max(n_obs, 2))
    return {
        **_entry_head(c.effect, c.key, c.lr, c.p, c.p_holm),
        "log10_p": c.logp / math.log(10),
        "shrink": shr,
        "shrink_in_sample": in_sample,
        "shrink_holdout": holdout,
        "n_flagged": n_flagged,  # the flagged cells the label judged
        "label": label,
        "params": {k: {"value": v, "stderr": se, "unit": units.get(k, "")} for k, (v, se) in c.params.items()},
        "df": c.df,
        "null": c.null,
        "delta_aic": 2 * c.q_eff - c.lr,
        "delta_bic": c.q_eff * logn - c.lr,
        "lm": c.screen.lm if c.screen is not None else None,
        "refitted": c.refitted,
        "plausible": c.plausible,
        "significant": bool(sig),
        "accepted": accepted,
        "step": c.step,
        "aliasing": c.screen.aliasing if c.screen is not None else None,
        "demoted": c.demoted,
        "mde": c.screen.mde if c.screen is not None else None,
    }


def _empty(
    status: str, problems: list, settings: dict, found: list, location: list | None = None, warned=()
) -> DiagnosisReport:
    return DiagnosisReport(
        verdict="none",
        status=status,
        problems=problems,
        ranking=[],
        ambiguous=[],
        not_identifiable=[],
        location=location or [],
        footprint=[],
        unexplained=[],
        settings=settings,
        text="No verdict: " + "; ".join(problems),
        findings=tuple(found),
        warnings=tuple(warned),
    )
