"""Fit results: a frozen record of an estimate, its uncertainty and how it was reached.

:class:`FitResult` holds the estimates, standard errors, covariance and
correlation, the residual covariance R, the cost history, the convergence
verdict, the band, the derived (alternate) parameter set with delta-method
standard errors (docs/theory.md section 6), and the spectra that were fitted.  It
prints as a table (:meth:`FitResult.summary`) and round-trips through
versioned JSON without loss (:meth:`FitResult.to_json`, :func:`load_result`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from .errors import FdmlError
from .findings import Finding
from .fit_options import FitOptions
from .jsoncodec import Codec, Fields, Spec, floats, integer, json_text, nested_list, numbers, read_json, texts
from .models.measurement import (
    BOUNDARY_NAMES,
    INPUT_BIAS_NAME,
    STATE_BIAS_NAMES,
    Nuisance,
    edge_basis,
    edge_names,
    nuisance_names,
)
from .parameters import Role, Slot
from .record import Record
from .spectral import FrequencyData
from .warning_log import RecordedWarning, as_recorded

if TYPE_CHECKING:
    from .adequacy import Adequacy
    from .models.base import Model

__all__ = ["FitResult", "IterationInfo", "correlation", "frozen", "load_result", "RESULT_FORMAT"]

#: JSON format identifier and version of saved results.
RESULT_FORMAT = ("fdml.FitResult", 2)


class _Rebuilt:
    """Pickled as its fields, thawed, and built again on unpickling (which freezes them again)."""

    def __reduce__(self):
        return (_rebuild, (type(self), {f.name: _thawed(getattr(self, f.name)) for f in fields(self)}))


@dataclass(frozen=True)
class IterationInfo(_Rebuilt):
    """What a progress callback receives after each iteration.

    Parameters
    ----------
    iteration : int
        The iteration just finished (1 for the first).
    cost : float
        J = det R (Eq. 25) after the iteration.
    params : dict
        Current estimates by name.
    step_in_stderr : float
        Largest Gauss-Newton step of the iteration, in standard errors.
    """

    iteration: int
    cost: float
    params: Mapping[str, float]
    step_in_stderr: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "params", frozen(self.params))


#: Immutable leaf types :func:`frozen` returns as they are, without the ABC checks below.
_LEAVES = frozenset({str, int, float, bool, complex, np.float64, np.int64, np.bool_})


def frozen(value):
    """``value`` made immutable all the way down: read-only arrays, mapping proxies, tuples for lists.

    An array that is already read-only is kept (no copy); a writable one is
    copied first, so the caller's array stays writable.

    Parameters
    ----------
    value : object
        Any value; arrays, mappings, lists and tuples are frozen, nested.

    Returns
    -------
    object
        The frozen value (read-only array, mapping proxy, tuple or ``value`` itself).
    """
    if value is None or type(value) in _LEAVES:  # most fields and entries: nothing to freeze
        return value
    if isinstance(value, np.ndarray):
        if value.flags.writeable:
            value = value.copy()
            value.setflags(write=False)
        return value
    if isinstance(value, Mapping):
        return MappingProxyType({k: frozen(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)) and not hasattr(value, "_fields"):
        return tuple(frozen(v) for v in value)
    return value


def _thawed(value):
    """Mapping proxies back to dicts (they cannot be pickled), also in spectra and their records; the rest as is."""
    if isinstance(value, MappingProxyType):
        return {k: _thawed(v) for k, v in value.items()}
    if isinstance(value, tuple) and not hasattr(value, "_fields"):
        return tuple(_thawed(v) for v in value)
    if isinstance(value, FrequencyData):
        rec = value.record
        if rec is not None:
            rec = replace(rec, signals=dict(rec.signals), meta=_thawed(rec.meta))
        return replace(value, meta=_thawed(value.meta), record=rec)
    return value


def _rebuild(cls, kwargs: dict):
    """Unpickle a frozen result: construct it again (which freezes it again)."""
    return cls(**kwargs)


class ByName:
    """``params`` and ``errors`` by name, of a result with ``names``, ``values`` and ``stderr``."""

    names: tuple
    values: np.ndarray
    stderr: np.ndarray

    @property
    def params(self) -> dict[str, float]:
        """Estimates by name."""
        return dict(zip(self.names, self.values.tolist()))

    @property
    def errors(self) -> dict[str, float]:
        """Standard errors by name."""
        return dict(zip(self.names, self.stderr.tolist()))


# --- the JSON of the fields that need more than their annotation -----------------------------------
def _slots_field(f: Fields, key: str, done: dict) -> tuple:
    """The saved slots (null in files from before they existed: empty, rebuilt from the names)."""
    if f.raw(key) is None:
        return ()
    items = f.items(key)
    if len(items) != len(done["names"]):
        raise f.error(key, f"has {len(items)} entries for {len(done['names'])} names")
    return tuple(Slot.from_fields(x, n) for n, x in zip(done["names"], items))


def _warnings_field(f: Fields, key: str, done: dict) -> tuple:
    """Recorded warnings: ``{category, message}`` objects, or the strings of files from before."""
    items = f.raw(key) or []
    if not isinstance(items, list):
        raise f.error(key, "must be a list of warnings")
    out = []
    for i, w in enumerate(items):
        if not isinstance(w, (str, dict)):
            raise f.error(key, f"entry {i} is neither a string nor a {{category, message}} object")
        where = Fields(w, f.source, f"{f.name(key)}[{i}].") if isinstance(w, dict) else None
        out.append(RecordedWarning.from_value(w) if where is None else RecordedWarning.from_fields(where))
    return tuple(out)


def _options_field(f: Fields, key: str, done: dict) -> dict:
    """The fit's options: an object whose fit options are checked (:class:`~fdml.fit_options.FitOptions`)."""
    opts = f.mapping(key)
    fitted = FitOptions.from_fields(f.sub(key)).outputs  # a bad option names the file and the key
    rows = done["model"].outputs
    if not set(fitted) <= set(rows):
        raise f.error(f"{key}.outputs", f"is {list(fitted)}, but the model predicts {', '.join(rows)}")
    return opts


def _spectra_field(f: Fields, key: str, done: dict) -> tuple:
    """The fitted spectra, each holding the model's outputs (its rows)."""
    out = tuple(FrequencyData.from_fields(x) for x in f.items(key))
    rows = done["model"].outputs
    for i, d in enumerate(out):
        if d.outputs != rows:
            raise f.error(f"{key}[{i}].outputs", f"is {list(d.outputs)}, but the model predicts {', '.join(rows)}")
    return out


def _r_field(f: Fields, key: str, done: dict) -> np.ndarray:
    """R over the fitted outputs (their number from the options)."""
    k = len(FitOptions.from_dict(done["options"]).outputs)
    return f.complexes(key, (k, k))


def _model_dict(model) -> dict:
    from .models import model_to_dict

    return model_to_dict(model)


#: A saved parameter's keys: (key, the :class:`Fields` reader, its keywords).
_PARAMETER_KEYS: tuple[tuple[str, str, dict], ...] = (
    ("name", "string", {}),
    ("value", "number", {}),
    ("free", "boolean", {"default": True}),
    ("lower", "number", {"default": None, "allow_none": True}),
    ("upper", "number", {"default": None, "allow_none": True}),
    ("unit", "string", {"default": ""}),
    ("description", "string", {"default": ""}),
)


def _model_field(f: Fields, key: str, done: dict):
    """The saved model, checked key by key, then built by :func:`fdml.models.model_from_dict`."""
    from .models import model_from_dict

    m = f.sub(key)
    doc = {
        "kind": m.string("kind"),
        "options": m.mapping("options", default={}),
        "aircraft": None if m.raw("aircraft", None) is None else m.mapping("aircraft"),
        "parameters": [
            {k: getattr(p, reader)(k, **kw) for k, reader, kw in _PARAMETER_KEYS} for p in m.items("parameters")
        ],
        "effects": list(m.strings("effects", default=())),  # effect keys (H1, issue 8)
    }
    try:
        return model_from_dict(doc)
    except FdmlError as exc:
        raise f.error(key, f"does not describe a model: {exc}") from None
    except (TypeError, ValueError, LookupError, AttributeError, ArithmeticError) as exc:
        raise f.error(key, f"does not describe a model: {type(exc).__name__}: {exc}") from None


def _adequacy_field(f: Fields, key: str, done: dict):
    """The saved adequacy check (null in files from before it existed: None)."""
    if f.raw(key) is None:
        return None
    from .adequacy import Adequacy

    return Adequacy.from_fields(f.sub(key))


def _option(name: str, doc: str) -> property:
    """A result's property that reads the option ``name`` of its :attr:`FitResult.fit_options`."""

    def read(self):
        return getattr(self.fit_options, name)

    read.__doc__ = doc
    return property(read)


def _read_only(a: np.ndarray) -> np.ndarray:
    """``a`` (a new array) made read-only."""
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class FitResult(ByName, Codec, _Rebuilt):
    """The outcome of :func:`fdml.fit`.

    Each parameter is the attribute of the same name.
    Every array is read-only and every mapping immutable (lists become
    tuples): a result is a record of a fit, and ``res.values[0] = 99``
    raises.  :func:`dataclasses.replace` gives a changed copy.

    A result keeps what cannot be derived; the rest are properties derived
    from it when read: ``stderr`` and ``corr`` from ``cov``, ``derived`` by
    the delta method from ``cov`` and the model, ``fixed`` from the model,
    ``outputs``, ``boundary``, ``cov_type``, ``method`` and ``stop`` from
    ``options``, ``band``, ``n_freq``, ``records`` and ``time_records`` from
    ``spectra`` (see each property).

    Parameters
    ----------
    model : Model
        The model with its parameters set to the estimates.
    names : tuple of str
        Estimated quantities: free model parameters, then nuisance terms
        (output biases ``bias_*``, boundary values ``x0_*``, ``xT_*``).
    values : ndarray
        Estimates, in the units of each parameter.
    cov : ndarray
        Covariance of the estimates (``cov_type``; inf on the diagonal for an
        unidentifiable parameter).
    cov_naive : ndarray
        ``(2 Re sum A^H R^-1 A)^-1``, the Cramer-Rao bound if every frequency
        were independent.
    options : mapping
        Every option the fit was run with, as resolved
        (:meth:`fdml.fit_options.FitOptions.to_dict`: ``sensitivity`` and
        ``biases`` as chosen, the spectra's ``band`` and ``trim``), and how
        white noise reached the covariance per record (``noise_covariance``)
        and, when known parameters were fixed, their uncertainty
        (``known_uncertainty``, :mod:`fdml.propagate`).
        :func:`fdml.plotting.simulate_fit` and :func:`fdml.report.write_report`
        need nothing supplied again.
    R : ndarray, complex
        Residual covariance (Eq. 24) over the fitted outputs.
    cost_history : tuple of float
        J = det R (Eq. 25) at the start and after every iteration.
    iterations : int
        Gauss-Newton iterations taken.
    converged : bool
        Whether the stopping rule (``stop``) was met.
    message : str
        How the fit ended, in words.
    at_bound : tuple of str
        Parameters that ended on a bound.
    spectra : tuple of FrequencyData
        The fitted spectra of every record, each with its time-domain record
        (``record``, None when the fit was given spectra), for plots, reports
        and :meth:`record`.
    stopped : bool
        Whether a progress callback stopped the fit.
    warnings : tuple of RecordedWarning
        Every warning raised during the fit, with its category
        (:mod:`fdml.warning_log`), in the order first raised.
    elapsed : float
        Wall-clock time of the fit, s.
    findings : tuple of Finding
        What the data check (:func:`fdml.datacheck.check_data`) found in the
        records, each with a stable code; see :mod:`fdml.findings`.
    adequacy : fdml.adequacy.Adequacy or None
        The fit's adequacy check (score tests of the effect library,
        residual coherence and whiteness; :mod:`fdml.adequacy`), None when
        skipped (``fit(..., adequacy=False)``) or the fit did not converge.
    provenance : dict
        Where the model's flight condition came from, when a command set it
        (``fdml fit``): ``airspeed`` ``{"value", "source"}`` (``record``,
        ``--airspeed`` or ``aircraft``) and ``record_conditions`` (what the
        records carry); see :mod:`fdml.conditions`.
    slots : tuple of Slot
        What each estimate is (:class:`~fdml.parameters.Role`) and, for a
        nuisance term, which record it belongs to; in the order of ``names``.
    """

    model: Model
    names: tuple
    values: np.ndarray
    cov: np.ndarray
    cov_naive: np.ndarray
    options: Mapping  # before R: R's shape follows the fitted outputs
    R: np.ndarray
    cost_history: tuple
    iterations: int
    converged: bool
    message: str
    at_bound: tuple = ()
    spectra: tuple = field(default=(), repr=False)
    stopped: bool = False
    warnings: tuple = ()
    elapsed: float = 0.0
    findings: tuple = ()
    adequacy: Adequacy | None = None
    provenance: Mapping = field(default_factory=dict)
    slots: tuple = ()

    json_fields = {
        "model": Spec(_model_field, write=_model_dict),
        "names": texts(),
        "values": floats("names"),
        "cov": floats("names", "names"),
        "cov_naive": floats("names", "names"),
        "options": Spec(_options_field),
        "R": Spec(_r_field),
        "cost_history": numbers(min_length=1),
        "iterations": integer(0),
        "at_bound": texts(),
        "spectra": Spec(_spectra_field),
        "warnings": Spec(_warnings_field),
        "findings": nested_list(Finding),
        "adequacy": Spec(_adequacy_field),
        "slots": Spec(_slots_field),
    }
    json_source = "fdml result"
    json_format = RESULT_FORMAT

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name not in ("model", "adequacy", "findings", "warnings", "slots", "spectra"):
                object.__setattr__(self, f.name, frozen(getattr(self, f.name)))
        object.__setattr__(self, "spectra", tuple(_frozen_spectrum(d) for d in self.spectra))
        object.__setattr__(self, "warnings", as_recorded(self.warnings))
        if not self.slots or len(self.slots) != len(self.names):
            object.__setattr__(self, "slots", _legacy_slots(self.names, self.model, self.records))

    # --- construction -------------------------------------------------------------------
    @classmethod
    def build(cls, *, prob, model, theta, history, options, **state) -> "FitResult":
        """Assemble the result of a finished fit from the estimator's state (used by :func:`fdml.fit`).

        Parameters
        ----------
        prob : Problem
            The estimation problem (:func:`fdml.estimate.prepare`).
        model : Model
            The model with its parameters set to the estimates.
        theta : numpy.ndarray
            The estimates, in the order of ``prob.names``.
        history : sequence of float
            J = det R (Eq. 25) at the start and after every iteration.
        options : mapping
            The options as resolved (:attr:`options`).
        **state
            The other fields, by name: ``cov``, ``cov_naive``, ``R``, ``iterations``,
            ``converged``, ``message``, ``elapsed``, ``stopped``.

        Returns
        -------
        FitResult
            The result.
        """
        slots = tuple(
            Slot(s.name, s.base, s.role, None if s.record < 0 else prob.data[s.record].name) for s in prob.slots
        )
        return cls(
            model=model,
            names=tuple(prob.names),
            values=np.asarray(theta, float),
            options=options,
            cost_history=tuple(history),
            at_bound=_at_bound(prob, theta),
            spectra=tuple(prob.data),
            slots=slots,
            **state,
        )

    # --- derived ------------------------------------------------------------------------
    @functools.cached_property
    def stderr(self) -> np.ndarray:  # type: ignore[override]  # ByName's attribute, derived here
        """Standard errors, the square roots of the diagonal of ``cov`` (inf: unidentifiable); read-only."""
        return _read_only(np.sqrt(np.diag(np.asarray(self.cov, float))))

    @functools.cached_property
    def corr(self) -> np.ndarray:
        """Correlation of the estimates (:func:`correlation` of ``cov``); read-only."""
        return _read_only(correlation(self.cov))

    @functools.cached_property
    def derived(self) -> Mapping:
        """Alternate set, ``{name: (value, stderr)}``: the model's derived quantities, delta method on ``cov``."""
        return frozen(_derived(self.model, self.slots, self.cov))

    @property
    def fixed(self) -> Mapping:
        """Fixed model parameters and their values."""
        return MappingProxyType({p.name: p.value for p in self.model.parameters if not p.free})

    @functools.cached_property
    def fit_options(self) -> FitOptions:
        """:attr:`options` as :class:`~fdml.fit_options.FitOptions` (the defaults for keys an old file lacks)."""
        return FitOptions.from_dict(self.options, source="the result's options")

    outputs = _option("outputs", "Fitted outputs.")
    boundary = _option("boundary", "The boundary terms: ``estimated``, ``measured`` or ``none``.")
    cov_type = _option("cov_type", "The covariance of ``cov``: ``white``, ``colored`` or ``naive``.")
    method = _option("method", "The iteration: ``lm`` or ``gauss-newton``.")
    stop = _option("stop", "The stopping rule: ``converge`` or ``paper``.")

    @property
    def band(self) -> tuple | None:
        """(lo, hi, step) rad/s of the (first record's) spectra; None for frequencies given as such."""
        return self.spectra[0].band if self.spectra else None

    @property
    def n_freq(self) -> int:
        """Frequencies used, summed over records."""
        return int(sum(d.m for d in self.spectra))

    @property
    def records(self) -> tuple:
        """Names of the records fitted."""
        return tuple(d.name for d in self.spectra)

    @property
    def time_records(self) -> tuple:
        """The time-domain records as given to the fit (None for spectra given as such); () when none is kept."""
        out = tuple(d.record for d in self.spectra)
        return out if any(r is not None for r in out) else ()

    @property
    def nuisance(self) -> Mapping:
        """The nuisance terms used: ``boundary``, ``output_biases``, ``state_biases``, ``input_bias``, ``trim``.

        Also ``input_edges`` when any was: per record, how many elevator steps' timing was estimated.
        """
        o = self.fit_options
        edges = tuple(sum(x.role is Role.INPUT_EDGE and x.record == d.name for x in self.slots) for d in self.spectra)
        biased = dict.fromkeys(s.base[len("bias_") :] for s in self.slots if s.role is Role.OUTPUT_BIAS)
        return MappingProxyType(
            {
                "boundary": o.boundary,
                "output_biases": tuple(biased),
                "state_biases": o.state_biases,
                "input_bias": o.input_bias,
                "trim": tuple(d.trim_mode for d in self.spectra),
                **({"input_edges": edges} if any(edges) else {}),
            }
        )

    def without_records(self) -> "FitResult":
        """A copy whose spectra keep no time-domain records (what ``to_json(include_data=False)`` writes).

        Returns
        -------
        FitResult
            The copy; :meth:`record` of it refuses.
        """
        return replace(self, spectra=tuple(replace(d, record=None) for d in self.spectra))

    # --- accessors ----------------------------------------------------------------------

    @property
    def cost(self) -> float:
        """Final J = det R (Eq. 25)."""
        return self.cost_history[-1]

    @property
    def kind(self) -> str:
        """Model kind."""
        return self.model.kind

    def slot(self, name: str) -> Slot | None:
        """What the estimate ``name`` is (its :class:`~fdml.parameters.Slot`); None if not estimated.

        Parameters
        ----------
        name : str
            The estimate's name (as in :attr:`names`).

        Returns
        -------
        Slot or None
            Its slot.
        """
        return self.slots[self.names.index(name)] if name in self.names else None

    @property
    def model_names(self) -> tuple[str, ...]:
        """The estimated parameters of the model itself, without the nuisance terms, in order."""
        return tuple(s.name for s in self.slots if not s.role.nuisance)

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """Two-sided ``1 - alpha`` confidence intervals of the estimates, shape (n, 2): lower, upper.

        ``value -+ z stderr`` with z the standard normal quantile at
        ``1 - alpha/2`` (1.96 for 95 %): the estimates are asymptotically
        normal with the Cramer-Rao covariance (``cov_type``).  Rows follow
        :attr:`names`; an unidentifiable parameter has (-inf, inf).

        Parameters
        ----------
        alpha : float, optional
            One minus the confidence level (default 0.05 for 95 %).

        Returns
        -------
        numpy.ndarray
            Lower and upper limits, shape (n, 2), in each parameter's unit; read-only.
        """
        from scipy.stats import norm

        if not 0.0 < float(alpha) < 1.0:
            raise FdmlError(f"alpha must lie strictly between 0 and 1, got {alpha!r}")
        z = float(norm.ppf(1.0 - float(alpha) / 2.0))
        half = z * np.asarray(self.stderr, float)
        return _read_only(np.column_stack([self.values - half, self.values + half]))

    @property
    def resid(self) -> np.ndarray:
        """Residual spectra z - y at the estimate, records stacked, shape (n_freq, fitted outputs); read-only.

        The ``v`` of Eq. 19 whose covariance is ``R`` (Eq. 24): the measured
        spectra minus :meth:`fitted_spectra`, for the fitted outputs.
        """
        idx = [self.model.outputs.index(o) for o in self.outputs]
        parts = [(s.z - self.fitted_spectra(r))[:, idx] for r, s in enumerate(self.spectra)]
        return _read_only(np.concatenate(parts) if parts else np.zeros((0, len(idx)), complex))

    def __getitem__(self, name: str) -> float:
        if name in self.names:
            return float(self.values[self.names.index(name)])
        if name in self.derived:
            return self.derived[name][0]
        if name in self.fixed:
            return self.fixed[name]
        raise KeyError(f"{name!r} is neither an estimate, a derived quantity nor a fixed parameter")

    # --- text ---------------------------------------------------------------------------
    def summary(self, digits: int = 6):
        """The fit as a table: value, standard error, relative error %, flags, unit.

        Returns a :class:`fdml.summary.Summary`, a ``str`` holding the text
        table that also renders as Markdown, HTML (a notebook shows it),
        LaTeX and a pandas DataFrame (``as_markdown()``, ``as_html()``,
        ``as_latex()``, ``to_frame()``).

        Parameters
        ----------
        digits : int, optional
            Significant digits of the values.

        Returns
        -------
        Summary
            The tables.
        """
        from .summary import fit_summary

        return fit_summary(self, digits=digits)

    def to_frame(self, table: str | None = None):
        """The summary's ``parameters`` (or ``derived``, ``correlations``) table as a pandas DataFrame.

        Parameters
        ----------
        table : str, optional
            The table's key; default ``parameters``.

        Returns
        -------
        pandas.DataFrame
            The table.
        """
        return self.summary().to_frame(table)

    def _repr_html_(self) -> str:
        return self.summary().as_html()

    def __str__(self) -> str:
        return str(self.summary())

    def __repr__(self) -> str:
        state = "converged" if self.converged else "not converged"
        return (
            f"<FitResult {self.kind}: {len(self.names)} estimates, {state} in {self.iterations} "
            f"iterations, J = {self.cost:.4g}, records {', '.join(self.records)}>"
        )

    # --- JSON ---------------------------------------------------------------------------------
    def brief(self) -> dict:
        """The short JSON form printed by ``fdml fit --json``.

        Keys: model, effects (:meth:`effects_brief`), params (name -> {value,
        stderr}), derived (name -> {value, stderr}), cost, iterations, converged, message, band, outputs,
        records, boundary, cov_type, warnings (each ``{category, message}``), findings (the data check's,
        each with its ``code``), adequacy (flagged effects and residual
        checks, :meth:`fdml.adequacy.Adequacy.brief`), provenance.  Infinite standard errors are
        written as the string "inf".

        Returns
        -------
        dict
            JSON-ready.
        """
        return {
            "model": self.kind,
            "effects": self.effects_brief(),
            "params": {
                n: {"value": float(v), "stderr": _num(float(s))}
                for n, v, s in zip(self.names, self.values, self.stderr)
            },
            "derived": {k: {"value": v, "stderr": _num(s)} for k, (v, s) in self.derived.items()},
            "fixed": self.fixed,
            "cost": self.cost,
            "iterations": self.iterations,
            "converged": self.converged,
            "message": self.message,
            "band": None if self.band is None else list(self.band),
            "n_freq": self.n_freq,
            "outputs": list(self.outputs),
            "records": list(self.records),
            "boundary": self.boundary,
            "cov_type": self.cov_type,
            "warnings": list(self.warnings),
            "findings": [f.to_dict() for f in self.findings],
            "adequacy": None if self.adequacy is None else self.adequacy.brief(),
            "provenance": self.provenance,  # I1: where the flight condition came from (fdml.conditions)
        }

    def effects_brief(self) -> list:
        """The model's effects in order: ``[{"key", "parameters": {name: {value, stderr, unit}}}]``.

        ``stderr`` is None for a parameter the fit held fixed (the string "inf" when
        infinite), unless the parameter was fixed at a value known to a standard error
        (``options["known_uncertainty"]``, :mod:`fdml.propagate`): then that one, with
        ``"known": true``.  A plain model has none (``[]``).

        Returns
        -------
        list of dict
            One entry per effect, in order.
        """
        from .models.effects import root_model

        se = self.errors
        known = {k: v["stderr"] for k, v in dict(self.options).get("known_uncertainty", {}).items()}
        vals = self.model.parameters.values
        out = []
        for eff in getattr(self.model, "parts", ()):
            pars = {}
            for p in eff.param_list(root_model(self.model)):
                s = se.get(p.name, known.get(p.name))
                pars[p.name] = {"value": float(vals[p.name]), "unit": p.unit, "stderr": None if s is None else _num(s)}
                if p.name in known and p.name not in se:
                    pars[p.name]["known"] = True
            out.append({"key": eff.key, "parameters": pars})
        return out

    def to_dict(self, include_data: bool = True) -> dict:
        """JSON-ready dict (format ``fdml.FitResult`` version 2) of the fields (:class:`~fdml.jsoncodec.Codec`).

        Float arrays are nested lists, complex arrays ``{"re": ..., "im": ...}``,
        non-finite numbers the strings ``"nan"``, ``"inf"``, ``"-inf"``; each
        record's spectra hold its time-domain record.  ``include_data=False``
        leaves out the time-domain records (most of a result's size;
        :meth:`record` and :func:`fdml.plotting.simulate_fit` need them); the
        spectra stay, so :attr:`resid` and the plots of the fit still work.
        What is derived (:attr:`stderr`, :attr:`corr`, :attr:`derived`, ...)
        is not written.

        Parameters
        ----------
        include_data : bool, optional
            Keep the time-domain records.

        Returns
        -------
        dict
            JSON-ready.
        """
        return Codec.to_dict(self if include_data else self.without_records())

    def to_json(self, path: str | Path | None = None, indent: int = 1, *, inputs=(), include_data: bool = True):
        """JSON text, or, given ``path``, write it atomically there and return the path.

        ``inputs`` (paths) are files the result must not replace (see
        :func:`fdml.outputs.atomic_write_text`); ``include_data=False``
        leaves the time-domain records out (:meth:`to_dict`).

        Parameters
        ----------
        path : str or Path, optional
            Where to write; None returns the text.
        indent : int, optional
            Spaces per nesting level.
        inputs : iterable of str or Path, optional
            Files the result must not replace.
        include_data : bool, optional
            Keep the time-domain records.

        Returns
        -------
        str or Path
            The JSON text, or the path written.
        """
        text = json_text(self.to_dict(include_data=include_data), path, inputs=inputs, indent=indent)
        return text if path is None else Path(path)

    @classmethod
    def from_dict(cls, d, *, source: str | None = "fdml result", **given) -> "FitResult":
        """Inverse of :meth:`to_dict`; files of version 1 are read too (:func:`_from_version_1`).

        Every key is checked for presence, type and shape; a problem raises
        :class:`~fdml.errors.FdmlError` ``"<source>: key '<key>' ..."``
        (``source`` names the file, e.g. ``"result file run.json"``).

        Parameters
        ----------
        d : dict
            A dict as written by :meth:`to_dict`.
        source : str, optional
            What and where, for the messages.
        **given
            Field values the dict does not hold.

        Returns
        -------
        FitResult
            The result.
        """
        f = Fields(d, cls.json_source if source is None else source)
        fmt = f.raw("format", None)
        if fmt is None:
            raise f.error("format", "is missing: not an fdml result file")
        if fmt != RESULT_FORMAT[0]:
            raise f.error("format", f"is {str(fmt)[:40]!r}, not {RESULT_FORMAT[0]!r}: not an fdml result file")
        if f.version("version", RESULT_FORMAT[1], older=(1,)) == 1:
            return _from_version_1(cls, f, given)
        return cls.from_fields(f, **given)

    def record(self, index: int = 0):
        """The time-domain record ``index`` as given to the fit (a :class:`~fdml.record.Record`).

        Parameters
        ----------
        index : int, optional
            Which record (default the first).

        Returns
        -------
        Record
            The record (its arrays read-only).
        """
        rec = self.spectra[index].record
        if rec is None:
            raise FdmlError(f"this result holds no time-domain records for record {index} (the fit was given spectra)")
        return rec

    def nuisance_values(self, record: int = 0):
        """Nuisance values of record ``record`` as arrays (:class:`fdml.models.measurement.Nuisance`).

        Estimated values where the fit estimated them, else the model's
        (fixed) output biases and the measured boundary values; no boundary
        terms for ``boundary="none"``.

        Parameters
        ----------
        record : int, optional
            Which record (default the first).

        Returns
        -------
        Nuisance
            The record's nuisance terms.
        """
        s = self.spectra[record]
        own = [(x, float(v)) for x, v in zip(self.slots, self.values) if x.role.nuisance and x.record == s.name]
        edges = sum(x.role is Role.INPUT_EDGE for x, _ in own)
        eta = np.concatenate([self.model.biases(), s.x0, s.xT, np.zeros(3 + edges)])  # nuisance_names order
        names = nuisance_names(self.model.outputs) + edge_names(edges)
        for x, v in own:
            eta[names.index(x.base)] = v
        roles = {x.role for x, _ in own}
        return Nuisance.from_vector(
            eta,
            boundary=self.boundary != "none",
            state_biases=Role.STATE_BIAS in roles,
            input_bias=Role.INPUT_BIAS in roles,
            rows=self.model.outputs,
            edges=edges,
        )

    def fitted_spectra(self, record: int = 0) -> np.ndarray:
        """Model output spectra at the estimate for record ``record``, shape (m, n_y) (the model's rows).

        Includes the estimated (or measured) boundary terms and biases, so that
        it is directly comparable with the measured ``spectra[record].z``:
        :func:`fdml.models.measurement.predict`, as in the fit.

        Parameters
        ----------
        record : int, optional
            Which record (default the first).

        Returns
        -------
        numpy.ndarray
            Complex spectra of alpha (rad s), q (rad), a_z (g s)[, theta (rad s), qdot (rad)], shape (m, n_y).
        """
        from .models.measurement import end_shift, predict

        s = self.spectra[record]
        resp = self.model.evaluate(s.omega)
        nu = self.nuisance_values(record)
        u = s.u[:, : resp.G.shape[2]]
        k = 0 if nu.edges is None else nu.edges.size  # the steps whose timing the fit estimated
        if k not in (0, s.edges.size):
            raise FdmlError(
                f"record {s.name!r}: {k} step timing terms for its {s.edges.size} elevator steps between samples"
            )
        elevator = nu.elevator(s.ones, edge_basis(s.omega, s.edges, s.edge_steps)[:, :k])
        return predict(resp, u, s.ones, nu.boundary(end_shift(s.omega, s.T)), nu.biases, nu.state_biases, elevator)


def _num(x: float):
    """A float for JSON output: itself if finite, else its string ("inf", "nan")."""
    return x if math.isfinite(x) else str(x)


def correlation(cov) -> np.ndarray:
    """Correlation of estimates from their covariance: NaN where a standard error is 0 or not finite, 1 on the diagonal.

    Parameters
    ----------
    cov : array_like
        Covariance, shape (n, n).

    Returns
    -------
    numpy.ndarray
        Correlations, shape (n, n).
    """
    cov = np.asarray(cov, float)
    se = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    corr[~np.isfinite(corr)] = np.nan
    np.fill_diagonal(corr, 1.0)
    return corr


def _at_bound(prob, theta) -> tuple:
    """The names of the estimates on (or past) a finite bound."""
    lo, hi = prob.bounds()
    theta = np.asarray(theta, float)
    on = (np.isfinite(lo) & (theta <= lo)) | (np.isfinite(hi) & (theta >= hi))
    return tuple(n for n, x in zip(prob.names, on) if x)


def _derived(model, slots, cov) -> dict:
    """Derived quantities ``{name: (value, standard error)}`` by the delta method (inf where it fails)."""
    dvals = model.derived()
    idx = [i for i, s in enumerate(slots) if not s.role.nuisance]
    mnames = [slots[i].name for i in idx]
    if not dvals or not mnames:
        return {k: (float(v), 0.0) for k, v in dvals.items()}
    keys, J = model.derived_jacobian(model.parameters.values, mnames)
    C = np.asarray(cov, float)[np.ix_(idx, idx)]
    with np.errstate(invalid="ignore"):
        dcov = J @ np.where(np.isfinite(C), C, 0.0) @ J.T  # delta method
    se = np.sqrt(np.maximum(np.diag(dcov), 0.0))
    se[np.any((np.abs(J) > 0) & ~np.all(np.isfinite(C), axis=0), axis=1)] = math.inf  # needs an unidentified one
    return {key: (float(dvals[key]), float(x)) for key, x in zip(keys, se)}


def _frozen_record(rec):
    """A record with read-only arrays and immutable signals and meta (itself when it is so already)."""
    if rec is None or isinstance(rec.signals, MappingProxyType):
        return rec
    out = replace(rec, t=frozen(rec.t))
    object.__setattr__(out, "signals", MappingProxyType({k: frozen(v) for k, v in rec.signals.items()}))
    object.__setattr__(out, "meta", frozen(rec.meta))
    return out


def _frozen_spectrum(d: FrequencyData) -> FrequencyData:
    """Spectra with read-only arrays, an immutable meta and a frozen record (itself when they are so already)."""
    arrays = {k: getattr(d, k) for k in ("omega", "z", "u", "x0", "xT", "ones", "end_offset")}
    rec = _frozen_record(d.record)
    if rec is d.record and isinstance(d.meta, MappingProxyType) and not any(a.flags.writeable for a in arrays.values()):
        return d
    return replace(d, **{k: frozen(np.asarray(a)) for k, a in arrays.items()}, meta=frozen(d.meta), record=rec)


_NUISANCE_ROLE = {
    **dict.fromkeys(BOUNDARY_NAMES, Role.BOUNDARY),
    **dict.fromkeys(STATE_BIAS_NAMES, Role.STATE_BIAS),
    INPUT_BIAS_NAME: Role.INPUT_BIAS,
}


def _legacy_slots(names, model, records) -> tuple[Slot, ...]:
    """The slots of a result saved before they were (a name ``base[record]`` read once, here)."""
    out = []
    for n in names:
        base, _, rec = n.partition("[")
        role = model.parameters[base].role if base in model.parameters else _NUISANCE_ROLE.get(base, Role.AERO)
        record = rec[:-1] if rec else (records[0] if role.nuisance and records else None)
        out.append(Slot(n, base, role, record))
    return tuple(out)


def _from_version_1(cls, f: Fields, given: Mapping) -> FitResult:
    """A result from a file of version 1, the one converter of old files.

    Version 1 kept the fitted outputs, the boundary terms, the covariance type, the
    iteration and the stopping rule beside the options, the band beside the spectra
    and the time-domain records apart from them; and it kept what is now derived
    (``stderr``, ``corr``, ``derived``, ``fixed``, ``n_freq``, ``records``,
    ``nuisance``), which is read no more.  Errors name the file's own keys.
    """
    model = given["model"] if "model" in given else _model_field(f, "model", {})
    rows = list(model.outputs)  # the spectra's columns: version 1 kept them with the model only
    opts = {k: f.raw(k) for k in ("outputs", "boundary", "cov_type", "method", "stop") if k in f}
    opts.update(f.mapping("options", default={}))
    band = None if f.raw("band") is None else f.numbers("band", length=3)
    records = [None if r is None else Record.from_fields(r) for r in f.items("time_records", [], allow_none=True)]
    trims = list(f.mapping("nuisance", default={}).get("trim") or [])
    trims += [r.raw("trim_mode", "first") if r is not None else "first" for r in f.items("time_records", [], True)]
    spectra = []
    for i, s in enumerate(f.items("spectra", default=[])):
        mode = trims[i] if i < len(trims) else opts.get("trim", "first")
        dt = s.number("dt")
        # as fdml.spectra counts them: none for "none", the first sample for "first", else the window's
        window = {"none": None, "first": 0.0}.get(mode, float(opts.get("trim_window") or 0.5))
        lead = 0 if window is None else int(round(window / dt)) + 1
        spectra.append(
            FrequencyData.from_fields(
                Fields({**s.doc, "outputs": rows}, s.source, s.prefix),
                band=band,
                trim_mode=mode,
                trim_samples=lead,
                end_correction=opts.get("end_correction", "cubic"),
                record=records[i] if i < len(records) else None,
            )
        )
    return cls.from_fields(f, **{"options": opts, "spectra": tuple(spectra), **given, "model": model})


def load_result(path: str | Path) -> FitResult:
    """Read a result saved by :meth:`FitResult.to_json`.

    Parameters
    ----------
    path : str or Path
        The JSON file.

    Returns
    -------
    FitResult
        The result.

    Raises
    ------
    FdmlError
        One line naming ``path``: the file is missing, a folder, not UTF-8 or
        not JSON (:func:`fdml.jsoncodec.read_json`), or a key is missing or of
        the wrong type or shape (:meth:`FitResult.from_dict`).
    """
    path = Path(path)
    what = f"result file {path}"
    doc = read_json(path, what="result file")
    if isinstance(doc, dict) and "format" not in doc and {"verdict", "ranking", "recommended"} <= set(doc):
        records = ", ".join((doc.get("settings") or {}).get("records") or []) or "its records"
        raise FdmlError(
            f"{what} is a diagnosis report (fdml diagnose -o), not a fit result; fdml report reads the "
            f"diagnosis's recommended fit, which fdml diagnose writes with --recommended-output FIT.json: "
            f"run fdml diagnose again on {records} with --recommended-output FIT.json, then fdml report FIT.json"
        )
    return FitResult.from_dict(doc, source=what)
