"""Fit results: a frozen record of an estimate, its uncertainty and how it was reached.

:class:`FitResult` holds the estimates, standard errors, covariance and
correlation, the residual covariance R, the cost history, the convergence
verdict, the band, the derived (alternate) parameter set with delta-method
standard errors (docs/theory.md section 6), and the spectra that were fitted.  It
prints as a table (:meth:`FitResult.summary`) and round-trips through
versioned JSON without loss (:meth:`FitResult.to_json`, :func:`load_result`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from .channels import ALL_OUTPUTS
from .errors import FdmlError
from .findings import Finding
from .jsoncodec import Fields, dumps, read_json, to_jsonable, write_json
from .models.measurement import BOUNDARY_NAMES, INPUT_BIAS_NAME, STATE_BIAS_NAMES, Nuisance, nuisance_names
from .parameters import Role, Slot
from .warning_log import RecordedWarning, as_recorded

if TYPE_CHECKING:
    from .adequacy import Adequacy
    from .models.base import Model

__all__ = ["FitResult", "IterationInfo", "frozen", "load_result", "RESULT_FORMAT"]

#: JSON format identifier and version of saved results.
RESULT_FORMAT = ("fdml.FitResult", 1)


@dataclass(frozen=True)
class IterationInfo:
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

    def __reduce__(self):
        return (_rebuild, (type(self), _thawed_fields(self)))


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
    """Mapping proxies back to dicts (they cannot be pickled); the rest as is."""
    if isinstance(value, MappingProxyType):
        return {k: _thawed(v) for k, v in value.items()}
    if isinstance(value, tuple) and not hasattr(value, "_fields"):
        return tuple(_thawed(v) for v in value)
    return value


def _thawed_fields(obj) -> dict:
    return {f.name: _thawed(getattr(obj, f.name)) for f in fields(obj)}


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


@dataclass(frozen=True)
class FitResult(ByName):
    """The outcome of :func:`fdml.fit`.

    Each parameter is the attribute of the same name.
    Every array is read-only and every mapping immutable (lists become
    tuples): a result is a record of a fit, and ``res.values[0] = 99``
    raises.  :func:`dataclasses.replace` gives a changed copy.

    Parameters
    ----------
    model : Model
        The model with its parameters set to the estimates.
    names : tuple of str
        Estimated quantities: free model parameters, then nuisance terms
        (output biases ``bias_*``, boundary values ``x0_*``, ``xT_*``).
    values : ndarray
        Estimates, in the units of each parameter.
    stderr : ndarray
        Standard errors (``cov_type``; inf for an unidentifiable parameter).
    cov, corr : ndarray
        Covariance and correlation of the estimates.
    cov_naive : ndarray
        ``(2 Re sum A^H R^-1 A)^-1``, the Cramer-Rao bound if every frequency
        were independent.
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
    derived : dict
        Alternate set, ``{name: (value, stderr)}``, delta method.
    fixed : dict
        Fixed model parameters and their values.
    at_bound : tuple of str
        Parameters that ended on a bound.
    outputs : tuple of str
        Fitted outputs.
    band : tuple or None
        (lo, hi, step) rad/s.
    n_freq : int
        Frequencies used (summed over records).
    records : tuple of str
        Names of the records fitted.
    boundary, cov_type, method, stop : str
        Options used.
    stopped : bool
        Whether a progress callback stopped the fit.
    warnings : tuple of RecordedWarning
        Every warning raised during the fit, with its category
        (:mod:`fdml.warning_log`), in the order first raised.
    elapsed : float
        Wall-clock time of the fit, s.
    spectra : tuple of dict
        The fitted spectra (``omega``, ``z``, ``u``, ``inputs``, ...) per record,
        for plots and reports.
    time_records : tuple of dict
        The time-domain records as given to the fit (``name``, ``t``,
        ``signals``, ``meta``, ``trim_mode``), when the fit was given records;
        see :meth:`record`.
    nuisance : dict
        Which nuisance terms the fit used: ``boundary`` (estimated, measured or
        none), ``output_biases`` (outputs with an estimated bias),
        ``state_biases`` and ``input_bias`` (bool), ``trim`` (per record).
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
    options : mapping
        Every option the fit was run with (``trim``, ``trim_window``,
        ``end_correction``, ``sensitivity`` as resolved, ``tol``,
        ``max_iter``, ``bounds``, ``noise`` band edges, ``band``, ``free``,
        ``fix``, ...), so that :func:`fdml.plotting.simulate_fit` and
        :func:`fdml.report.write_report` need nothing supplied again.
    """

    model: Model
    names: tuple
    values: np.ndarray
    stderr: np.ndarray
    cov: np.ndarray
    corr: np.ndarray
    cov_naive: np.ndarray
    R: np.ndarray
    cost_history: tuple
    iterations: int
    converged: bool
    message: str
    derived: Mapping
    fixed: Mapping
    at_bound: tuple
    outputs: tuple
    band: tuple | None
    n_freq: int
    records: tuple
    boundary: str
    cov_type: str
    method: str = "lm"
    stop: str = "converge"
    stopped: bool = False
    warnings: tuple = ()
    elapsed: float = 0.0
    spectra: tuple = field(default=(), repr=False)
    time_records: tuple = field(default=(), repr=False)
    nuisance: Mapping = field(default_factory=dict)
    findings: tuple = ()
    adequacy: Adequacy | None = None
    provenance: Mapping = field(default_factory=dict)
    slots: tuple = ()
    options: Mapping = field(default_factory=dict)

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name not in ("model", "adequacy", "findings", "warnings", "slots"):
                object.__setattr__(self, f.name, frozen(getattr(self, f.name)))
        object.__setattr__(self, "warnings", as_recorded(self.warnings))
        if not self.slots or len(self.slots) != len(self.names):
            object.__setattr__(self, "slots", _legacy_slots(self.names, self.model, self.records))

    def __reduce__(self):
        return (_rebuild, (type(self), _thawed_fields(self)))

    # --- construction -------------------------------------------------------------------
    @classmethod
    def build(
        cls,
        *,
        prob,
        model,
        theta,
        cov,
        cov_naive,
        stderr,
        corr,
        R,
        history,
        iterations,
        converged,
        message,
        cov_type,
        elapsed,
        stopped,
        method,
        stop,
    ) -> "FitResult":
        """Assemble the result of a finished fit from the estimator's state (used by :func:`fdml.fit`).

        Parameters
        ----------
        prob : Problem
            The estimation problem (:func:`fdml.estimate.prepare`).
        model : Model
            The model with its parameters set to the estimates.
        theta : numpy.ndarray
            The estimates, in the order of ``prob.names``.
        cov, cov_naive : numpy.ndarray
            Covariance of the estimates (``cov_type``) and the naive Cramer-Rao bound.
        stderr : numpy.ndarray
            Standard errors of the estimates.
        corr : numpy.ndarray
            Correlation of the estimates.
        R : numpy.ndarray
            Residual covariance (Eq. 24), complex.
        history : sequence of float
            J = det R (Eq. 25) at the start and after every iteration.
        iterations : int
            Iterations taken.
        converged : bool
            Whether the stopping rule was met.
        message : str
            How the fit ended.
        cov_type : str
            The covariance used for ``cov``.
        elapsed : float
            Wall-clock time of the fit, s.
        stopped : bool
            Whether a progress callback stopped the fit.
        method, stop : str
            The optimiser and the stopping rule used.

        Returns
        -------
        FitResult
            The result.
        """
        names = prob.names
        slots = tuple(
            Slot(s.name, s.base, s.role, None if s.record < 0 else prob.data[s.record].name) for s in prob.slots
        )
        fixed = {p.name: p.value for p in model.parameters if not p.free}
        band = None
        if prob.data[0].band is not None:
            band = tuple(prob.data[0].band)
        spectra = tuple(_spectrum_fields(d) for d in prob.data)
        time_records = tuple(_time_record_fields(d) for d in prob.data)
        if all(r is None for r in time_records):
            time_records = ()
        nuisance = {
            "boundary": prob.boundary,
            "output_biases": list(dict.fromkeys(s.base[len("bias_") :] for s in slots if s.role is Role.OUTPUT_BIAS)),
            "state_biases": bool(getattr(prob, "state_biases", False)),
            "input_bias": bool(getattr(prob, "input_bias", False)),
            "trim": [d.trim_mode for d in prob.data],
        }
        return cls(
            nuisance=nuisance,
            slots=slots,
            time_records=time_records,
            model=model,
            names=tuple(names),
            values=np.asarray(theta, float),
            stderr=np.asarray(stderr),
            cov=cov,
            corr=corr,
            cov_naive=cov_naive,
            R=R,
            cost_history=tuple(history),
            iterations=iterations,
            converged=converged,
            message=message,
            derived=_derived(prob, model, cov),
            fixed=fixed,
            at_bound=_at_bound(prob, theta),
            outputs=prob.outputs,
            band=band,
            n_freq=prob.N,
            records=tuple(d.name for d in prob.data),
            boundary=prob.boundary,
            cov_type=cov_type,
            method=method,
            stop=stop,
            stopped=stopped,
            elapsed=elapsed,
            spectra=spectra,
        )

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
        out = np.column_stack([self.values - half, self.values + half])
        out.setflags(write=False)
        return out

    @property
    def resid(self) -> np.ndarray:
        """Residual spectra z - y at the estimate, records stacked, shape (n_freq, fitted outputs); read-only.

        The ``v`` of Eq. 19 whose covariance is ``R`` (Eq. 24): the measured
        spectra minus :meth:`fitted_spectra`, for the fitted outputs.
        """
        idx = [self.model.outputs.index(o) for o in self.outputs]
        parts = [(s["z"] - self.fitted_spectra(r))[:, idx] for r, s in enumerate(self.spectra)]
        out = np.concatenate(parts) if parts else np.zeros((0, len(idx)), complex)
        out.setflags(write=False)
        return out

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

        def num(x):
            return x if math.isfinite(x) else str(x)

        return {
            "model": self.kind,
            "effects": self.effects_brief(),
            "params": {
                n: {"value": float(v), "stderr": num(float(s))} for n, v, s in zip(self.names, self.values, self.stderr)
            },
            "derived": {k: {"value": v, "stderr": num(s)} for k, (v, s) in self.derived.items()},
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

        se = dict(zip(self.names, (float(x) for x in self.stderr)))
        known = {k: v["stderr"] for k, v in dict(self.options).get("known_uncertainty", {}).items()}
        vals = self.model.parameters.values
        out = []
        for eff in getattr(self.model, "parts", ()):
            pars = {}
            for p in eff.param_list(root_model(self.model)):
                s = se.get(p.name, known.get(p.name))
                pars[p.name] = {
                    "value": float(vals[p.name]),
                    "unit": p.unit,
                    "stderr": None if s is None else (s if math.isfinite(s) else str(s)),
                }
                if p.name in known and p.name not in se:
                    pars[p.name]["known"] = True
            out.append({"key": eff.key, "parameters": pars})
        return out

    def to_dict(self, include_data: bool = True) -> dict:
        """JSON-ready dict (format ``fdml.FitResult`` version 1), through :func:`fdml.jsoncodec.to_jsonable`.

        Float arrays are nested lists, complex arrays ``{"re": ..., "im": ...}``,
        non-finite numbers the strings ``"nan"``, ``"inf"``, ``"-inf"``.
        ``include_data=False`` leaves out the time-domain records (most of
        a result's size; :meth:`record` and :func:`fdml.plotting.simulate_fit`
        need them); the spectra stay, so :attr:`resid` and the plots of the
        fit still work.

        Parameters
        ----------
        include_data : bool, optional
            Keep the time-domain records.

        Returns
        -------
        dict
            JSON-ready.
        """
        from .models import model_to_dict

        def f(a):
            return np.asarray(a, float)

        def c(a):
            return np.asarray(a, complex)

        return to_jsonable(
            {
                "format": RESULT_FORMAT[0],
                "version": RESULT_FORMAT[1],
                "model": model_to_dict(self.model),
                "names": list(self.names),
                "values": f(self.values),
                "stderr": f(self.stderr),
                "cov": f(self.cov),
                "corr": f(self.corr),
                "cov_naive": f(self.cov_naive),
                "R": c(self.R),
                "cost_history": [float(x) for x in self.cost_history],
                "iterations": int(self.iterations),
                "converged": bool(self.converged),
                "message": self.message,
                "derived": {k: [float(v), float(s)] for k, (v, s) in self.derived.items()},
                "fixed": {k: float(v) for k, v in self.fixed.items()},
                "at_bound": list(self.at_bound),
                "outputs": list(self.outputs),
                "band": None if self.band is None else [float(x) for x in self.band],
                "n_freq": int(self.n_freq),
                "records": list(self.records),
                "boundary": self.boundary,
                "cov_type": self.cov_type,
                "method": self.method,
                "stop": self.stop,
                "stopped": bool(self.stopped),
                "warnings": [w.to_dict() for w in self.warnings],
                "elapsed": float(self.elapsed),
                "slots": [x.to_dict() for x in self.slots],
                "options": self.options,
                "spectra": [
                    {
                        "name": s["name"],
                        "omega": f(s["omega"]),
                        "z": c(s["z"]),
                        "u": c(s["u"]),
                        "inputs": list(s["inputs"]),
                        "x0": f(s["x0"]),
                        "xT": f(s["xT"]),
                        "T": float(s["T"]),
                        "dt": float(s["dt"]),
                        "n": int(s["n"]),
                        "ones": c(s["ones"]),
                    }
                    for s in self.spectra
                ],
                "nuisance": self.nuisance,
                "findings": [x.to_dict() for x in self.findings],
                "adequacy": None if self.adequacy is None else self.adequacy.to_dict(),
                "provenance": self.provenance,
                "time_records": [
                    None
                    if r is None
                    else {
                        "name": r["name"],
                        "t": f(r["t"]),
                        "signals": {k: f(v) for k, v in r["signals"].items()},
                        "meta": r["meta"],
                        "trim_mode": r["trim_mode"],
                    }
                    for r in (self.time_records if include_data else ())
                ],
            }
        )

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
        doc = self.to_dict(include_data=include_data)
        if path is None:
            return dumps(doc, indent=indent)
        return write_json(path, doc, inputs=inputs, indent=indent)

    @classmethod
    def from_dict(cls, d: dict, *, source: str = "fdml result") -> "FitResult":
        """Inverse of :meth:`to_dict`.

        Every key is checked for presence, type and shape; a problem raises
        :class:`~fdml.errors.FdmlError` ``"<source>: key '<key>' ..."``
        (``source`` names the file, e.g. ``"result file run.json"``).

        Parameters
        ----------
        d : dict
            A dict as written by :meth:`to_dict`.
        source : str, optional
            What and where, for the messages.

        Returns
        -------
        FitResult
            The result.
        """
        f = Fields(d, source)
        fmt = f.raw("format", None)
        if fmt is None:
            raise f.error("format", "is missing: not an fdml result file")
        if fmt != RESULT_FORMAT[0]:
            raise f.error("format", f"is {str(fmt)[:40]!r}, not {RESULT_FORMAT[0]!r}: not an fdml result file")
        f.version("version", RESULT_FORMAT[1])
        model = _model_from_fields(f)
        names = f.strings("names")
        n = len(names)
        outputs = f.strings("outputs", choices=ALL_OUTPUTS)
        k = len(outputs)
        spectra = tuple(_spectrum_from_fields(s) for s in f.items("spectra", default=[]))
        return cls(
            model=model,
            names=names,
            values=f.floats("values", (n,)),
            stderr=f.floats("stderr", (n,)),
            cov=f.floats("cov", (n, n)),
            corr=f.floats("corr", (n, n)),
            cov_naive=f.floats("cov_naive", (n, n)),
            R=f.complexes("R", (k, k)),
            cost_history=f.numbers("cost_history", min_length=1),
            iterations=f.integer("iterations", minimum=0),
            converged=f.boolean("converged"),
            message=f.string("message"),
            derived=_derived_from_fields(f),
            fixed={name: _number_in(f, "fixed", name, v) for name, v in f.mapping("fixed").items()},
            at_bound=f.strings("at_bound"),
            outputs=outputs,
            band=None if f.raw("band") is None else f.numbers("band", length=3),
            n_freq=f.integer("n_freq", minimum=0),
            records=f.strings("records"),
            boundary=f.string("boundary"),
            cov_type=f.string("cov_type"),
            method=f.string("method", default="lm"),
            stop=f.string("stop", default="converge"),
            stopped=f.boolean("stopped", default=False),
            warnings=_warnings_from_fields(f),
            elapsed=f.number("elapsed", default=0.0),
            slots=_slots_from_fields(f, names),
            options=f.mapping("options", default={}),
            spectra=spectra,
            nuisance=f.mapping("nuisance", default={}),
            findings=tuple(Finding.from_fields(x) for x in f.items("findings", default=[])),
            adequacy=_adequacy_from_fields(f),
            provenance=f.mapping("provenance", default={}),
            time_records=tuple(
                None if r is None else _time_record_from_fields(r)
                for r in f.items("time_records", default=[], allow_none=True)
            ),
        )

    def record(self, index: int = 0):
        """The time-domain record ``index`` as given to the fit (a :class:`~fdml.record.Record`).

        Parameters
        ----------
        index : int, optional
            Which record (default the first).

        Returns
        -------
        Record
            The record.
        """
        from .record import Record

        if not self.time_records or self.time_records[index] is None:
            raise FdmlError(f"this result holds no time-domain records for record {index} (the fit was given spectra)")
        r = self.time_records[index]
        return Record(
            np.asarray(r["t"], float),
            {k: np.asarray(v, float) for k, v in r["signals"].items()},
            name=r["name"],
            meta=_thawed(r["meta"]),  # a plain dict, as the record had
            check_units=False,
        )

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
        eta = np.concatenate([self.model.biases(), s["x0"], s["xT"], np.zeros(3)])  # nuisance_names order
        own = [(x, float(v)) for x, v in zip(self.slots, self.values) if x.role.nuisance and x.record == s["name"]]
        names = nuisance_names(self.model.outputs)
        for x, v in own:
            eta[names.index(x.base)] = v
        roles = {x.role for x, _ in own}
        return Nuisance.from_vector(
            eta,
            boundary=self.boundary != "none",
            state_biases=Role.STATE_BIAS in roles,
            input_bias=Role.INPUT_BIAS in roles,
            rows=self.model.outputs,
        )

    def fitted_spectra(self, record: int = 0) -> np.ndarray:
        """Model output spectra at the estimate for record ``record``, shape (m, n_y) (the model's rows).

        Includes the estimated (or measured) boundary terms and biases, so that
        it is directly comparable with the measured ``spectra[record]["z"]``:
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
        resp = self.model.evaluate(s["omega"])
        nu = self.nuisance_values(record)
        u = s["u"][:, : resp.G.shape[2]]
        return predict(
            resp, u, s["ones"], nu.boundary(end_shift(s["omega"], s["T"])), nu.biases, nu.state_biases, nu.input_bias
        )


#: Roles of the per-record nuisance terms that are not model parameters, by base name.
def _at_bound(prob, theta) -> tuple:
    """The names of the estimates on (or past) a finite bound."""
    lo, hi = prob.bounds()
    return tuple(
        n
        for i, n in enumerate(prob.names)
        if (math.isfinite(lo[i]) and theta[i] <= lo[i]) or (math.isfinite(hi[i]) and theta[i] >= hi[i])
    )


def _derived(prob, model, cov) -> dict:
    """Derived quantities ``{name: (value, standard error)}`` by the delta method (inf where it fails)."""
    dvals = model.derived()
    mnames = [prob.slots[i].name for i in prob.model_slots]
    if not dvals or not mnames:
        return {k: (float(v), 0.0) for k, v in dvals.items()}
    keys, J = model.derived_jacobian(model.parameters.values, mnames)
    idx = np.array(prob.model_slots)
    C = cov[np.ix_(idx, idx)]
    with np.errstate(invalid="ignore"):
        dcov = J @ np.where(np.isfinite(C), C, 0.0) @ J.T  # delta method
    bad = ~np.all(np.isfinite(C), axis=0)
    derived = {}
    for k, key in enumerate(keys):
        se = math.sqrt(max(dcov[k, k], 0.0))
        if np.any(bad & (np.abs(J[k]) > 0)):
            se = math.inf
        derived[key] = (float(dvals[key]), se)
    return derived


def _spectrum_fields(d) -> dict:
    """What a result keeps of one record's spectra (to replot and recheck the fit)."""
    return {
        "name": d.name,
        "omega": d.omega,
        "z": d.z,
        "u": d.u,
        "inputs": list(d.inputs),
        "x0": d.x0,
        "xT": d.xT,
        "T": d.T,
        "dt": d.dt,
        "n": d.n,
        "ones": d.ones,
    }


def _time_record_fields(d) -> dict | None:
    """What a result keeps of one record's time history (None for spectra given without one)."""
    if d.record is None:
        return None
    return {
        "name": d.name,
        "t": d.record.t,
        "signals": dict(d.record.signals),
        "meta": dict(d.record.meta),
        "trim_mode": d.trim_mode,
    }


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
        if base in model.parameters:
            role = model.parameters[base].role
        else:
            role = _NUISANCE_ROLE.get(base, Role.AERO)
        record = rec[:-1] if rec else (records[0] if role.nuisance and records else None)
        out.append(Slot(n, base, role, record))
    return tuple(out)


def _slots_from_fields(f: Fields, names) -> tuple:
    """The saved slots (absent in files from before they existed: empty, rebuilt from the names)."""
    if f.raw("slots", None) is None:
        return ()
    items = f.items("slots")
    if len(items) != len(names):
        raise f.error("slots", f"has {len(items)} entries for {len(names)} names")
    return tuple(Slot.from_fields(x, n) for n, x in zip(names, items))


def _warnings_from_fields(f: Fields) -> tuple:
    """Recorded warnings: ``{category, message}`` objects, or the strings of files from before."""
    items = f.raw("warnings", None) or []
    if not isinstance(items, list):
        raise f.error("warnings", "must be a list of warnings")
    out = []
    for i, w in enumerate(items):
        if isinstance(w, str):
            out.append(RecordedWarning.from_value(w))
            continue
        if not isinstance(w, dict):
            raise f.error("warnings", f"entry {i} is neither a string nor a {{category, message}} object")
        out.append(RecordedWarning.from_fields(Fields(w, f.source, f"{f.name('warnings')}[{i}].")))
    return tuple(out)


def _number_in(f: Fields, key: str, name: str, v) -> float:
    """A number inside the object ``key`` (for messages ``key 'fixed.Cm_a' ...``)."""
    return Fields({name: v}, f.source, f"{f.name(key)}.").number(name)


def _derived_from_fields(f: Fields) -> dict:
    out = {}
    for name, v in f.mapping("derived").items():
        pair = Fields({name: v}, f.source, f"{f.name('derived')}.").numbers(name, length=2)
        out[name] = (pair[0], pair[1])
    return out


def _model_from_fields(f: Fields):
    """The saved model, checked key by key, then built by :func:`fdml.models.model_from_dict`."""
    from .models import model_from_dict

    m = f.sub("model")
    kind = m.string("kind")
    options = m.mapping("options", default={})
    aircraft = None if m.raw("aircraft", None) is None else m.mapping("aircraft")
    params = []
    for p in m.items("parameters"):
        params.append(
            {
                "name": p.string("name"),
                "value": p.number("value"),
                "free": p.boolean("free", default=True),
                "lower": p.number("lower", default=None, allow_none=True),
                "upper": p.number("upper", default=None, allow_none=True),
                "unit": p.string("unit", default=""),
                "description": p.string("description", default=""),
            }
        )
    effects = list(m.strings("effects", default=()))  # effect keys (H1, issue 8)
    try:
        return model_from_dict(
            {"kind": kind, "options": options, "aircraft": aircraft, "parameters": params, "effects": effects}
        )
    except FdmlError as exc:
        raise f.error("model", f"does not describe a model: {exc}") from None
    except (TypeError, ValueError, LookupError, AttributeError, ArithmeticError) as exc:
        raise f.error("model", f"does not describe a model: {type(exc).__name__}: {exc}") from None


def _spectrum_from_fields(s: Fields) -> dict:
    omega = s.floats("omega", (None,))
    m = omega.size
    return {
        "name": s.string("name"),
        "omega": omega,
        "z": s.complexes("z", (m, None)),
        "u": s.complexes("u", (m, None)),
        "inputs": list(s.strings("inputs")),
        "x0": s.floats("x0", (None,)),  # alpha, q[, theta]: the boundary channels of the model's outputs
        "xT": s.floats("xT", (None,)),
        "T": s.number("T"),
        "dt": s.number("dt"),
        "n": s.integer("n", minimum=0),
        "ones": s.complexes("ones", (m,)),
    }


def _time_record_from_fields(r: Fields) -> dict:
    t = r.floats("t", (None,))
    sig = r.sub("signals")
    return {
        "name": r.string("name"),
        "t": t,
        "signals": {k: sig.floats(k, (t.size,)) for k in sig.doc},
        "meta": r.mapping("meta"),
        "trim_mode": r.string("trim_mode"),
    }


def _adequacy_from_fields(f: Fields):
    """The saved adequacy check (absent or null in files from before it existed: None)."""
    if f.raw("adequacy", None) is None:
        return None
    from .adequacy import Adequacy

    return Adequacy.from_fields(f.sub("adequacy"))


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
