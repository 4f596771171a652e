"""Fit results: a frozen record of an estimate, its uncertainty and how it was reached.

:class:`FitResult` holds the estimates, standard errors, covariance and
correlation, the residual covariance R, the cost history, the convergence
verdict, the band, the derived (alternate) parameter set with delta-method
standard errors (THEORY.md section 6), and the spectra that were fitted.  It
prints as a table (:meth:`FitResult.summary`) and round-trips through
versioned JSON without loss (:meth:`FitResult.to_json`, :func:`load_result`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import FdmlError
from .findings import Finding

__all__ = ["FitResult", "IterationInfo", "load_result", "RESULT_FORMAT"]

#: JSON format identifier and version of saved results.
RESULT_FORMAT = ("fdml.FitResult", 1)


@dataclass(frozen=True)
class IterationInfo:
    """What a progress callback receives after each iteration.

    Attributes
    ----------
    iteration : int
    cost : float
        J = det R (Eq. 25) after the iteration.
    params : dict
        Current estimates by name.
    step_in_stderr : float
        Largest Gauss-Newton step of the iteration, in standard errors.
    """

    iteration: int
    cost: float
    params: dict
    step_in_stderr: float


def _c2j(a: np.ndarray):
    a = np.asarray(a)
    return {"re": a.real.tolist(), "im": a.imag.tolist()}


def _j2c(d) -> np.ndarray:
    return np.asarray(d["re"], float) + 1j * np.asarray(d["im"], float)


def _f2j(a):
    """Float array to nested lists with inf/nan as strings (JSON has neither)."""
    a = np.asarray(a, float)
    if a.ndim == 0:
        x = float(a)
        return x if math.isfinite(x) else str(x)
    return [_f2j(x) for x in a]


def _jsonable(obj):
    """A JSON-safe copy of record meta data (arrays to lists, other objects to str)."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    if obj is None or isinstance(obj, (str, int, float, bool)):
        return obj
    return str(obj)


def _j2f(v) -> np.ndarray:
    def conv(x):
        if isinstance(x, list):
            return [conv(y) for y in x]
        return float(x)
    return np.asarray(conv(v), float)


@dataclass(frozen=True)
class FitResult:
    """The outcome of :func:`fdml.fit`.

    Attributes
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
    converged : bool
    message : str
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
    boundary, cov_type, method, stop : str
        Options used.
    warnings : tuple of str
        Warnings raised during the fit.
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
    """

    model: object
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
    derived: dict
    fixed: dict
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
    nuisance: dict = field(default_factory=dict)
    findings: tuple = ()

    # --- construction -------------------------------------------------------------------
    @classmethod
    def build(cls, *, prob, model, theta, cov, cov_naive, stderr, corr, R, history, iterations,
              converged, message, cov_type, warnings, elapsed, stopped, method, stop) -> "FitResult":
        names = prob.names
        lo, hi = prob.bounds()
        at_bound = tuple(n for i, n in enumerate(names)
                         if (math.isfinite(lo[i]) and theta[i] <= lo[i]) or
                         (math.isfinite(hi[i]) and theta[i] >= hi[i]))
        mnames = [prob.slots[i].name for i in prob.model_slots]
        derived = {}
        dvals = model.derived()
        if dvals and mnames:
            keys, J = model.derived_jacobian(model.parameters.values, mnames)
            idx = np.array(prob.model_slots)
            C = cov[np.ix_(idx, idx)]
            with np.errstate(invalid="ignore"):
                dcov = J @ np.where(np.isfinite(C), C, 0.0) @ J.T  # delta method
            bad = ~np.all(np.isfinite(C), axis=0)
            for k, key in enumerate(keys):
                se = math.sqrt(max(dcov[k, k], 0.0))
                if np.any(bad & (np.abs(J[k]) > 0)):
                    se = math.inf
                derived[key] = (float(dvals[key]), se)
        elif dvals:
            derived = {k: (float(v), 0.0) for k, v in dvals.items()}
        fixed = {p.name: p.value for p in model.parameters if not p.free}
        band = None
        if prob.data[0].band is not None:
            band = tuple(prob.data[0].band)
        spectra = tuple(
            {
                "name": d.name, "omega": d.omega, "z": d.z, "u": d.u, "inputs": list(d.inputs),
                "x0": d.x0, "xT": d.xT, "T": d.T, "dt": d.dt, "n": d.n, "ones": d.ones,
            }
            for d in prob.data
        )
        time_records = tuple(
            None if d.record is None else
            {"name": d.name, "t": d.record.t, "signals": dict(d.record.signals),
             "meta": dict(d.record.meta), "trim_mode": d.trim_mode}
            for d in prob.data
        )
        if all(r is None for r in time_records):
            time_records = ()
        nuisance = {
            "boundary": prob.boundary,
            "output_biases": [["alpha", "q", "az"][k] for k in prob.out_idx
                              if prob.model.parameters[f"bias_{['alpha', 'q', 'az'][k]}"].free],
            "state_biases": bool(getattr(prob, "state_biases", False)),
            "input_bias": bool(getattr(prob, "input_bias", False)),
            "trim": [d.trim_mode for d in prob.data],
        }
        return cls(
            nuisance=nuisance,
            time_records=time_records,
            model=model, names=tuple(names), values=np.asarray(theta, float), stderr=np.asarray(stderr),
            cov=cov, corr=corr, cov_naive=cov_naive, R=R, cost_history=tuple(history),
            iterations=iterations, converged=converged, message=message, derived=derived, fixed=fixed,
            at_bound=at_bound, outputs=tuple(["alpha", "q", "az"][k] for k in prob.out_idx),
            band=band, n_freq=prob.N, records=tuple(d.name for d in prob.data),
            boundary=prob.boundary, cov_type=cov_type, method=method, stop=stop, stopped=stopped,
            warnings=tuple(warnings), elapsed=elapsed, spectra=spectra,
        )

    # --- accessors ----------------------------------------------------------------------
    @property
    def params(self) -> dict[str, float]:
        """Estimates by name."""
        return dict(zip(self.names, self.values.tolist()))

    @property
    def errors(self) -> dict[str, float]:
        """Standard errors by name."""
        return dict(zip(self.names, self.stderr.tolist()))

    @property
    def cost(self) -> float:
        """Final J = det R (Eq. 25)."""
        return self.cost_history[-1]

    @property
    def kind(self) -> str:
        """Model kind."""
        return self.model.kind

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
        """
        from .summary import fit_summary

        return fit_summary(self, digits=digits)

    def to_frame(self, table: str | None = None):
        """The summary's ``parameters`` (or ``derived``, ``correlations``) table as a pandas DataFrame."""
        return self.summary().to_frame(table)

    def _repr_html_(self) -> str:
        return self.summary().as_html()

    def _unit(self, name: str) -> str:
        base = name.split("[")[0]
        if base in self.model.parameters:
            u = self.model.parameters[base].unit
            return f"  [{u}]" if u else ""
        return ""

    def __str__(self) -> str:
        return str(self.summary())

    def __repr__(self) -> str:
        state = "converged" if self.converged else "not converged"
        return (f"<FitResult {self.kind}: {len(self.names)} estimates, {state} in {self.iterations} "
                f"iterations, J = {self.cost:.4g}, records {', '.join(self.records)}>")

    # --- JSON ---------------------------------------------------------------------------------
    def brief(self) -> dict:
        """The short JSON form printed by ``fdml fit --json``.

        Keys: model, params (name -> {value, stderr}), derived (name ->
        {value, stderr}), cost, iterations, converged, message, band, outputs,
        records, boundary, cov_type, warnings.  Infinite standard errors are
        written as the string "inf".
        """
        def num(x):
            return x if math.isfinite(x) else str(x)

        return {
            "model": self.kind,
            "params": {n: {"value": float(v), "stderr": num(float(s))}
                       for n, v, s in zip(self.names, self.values, self.stderr)},
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
        }

    def to_dict(self) -> dict:
        """JSON-ready dict (format ``fdml.FitResult`` version 1)."""
        from .models import model_to_dict

        return {
            "format": RESULT_FORMAT[0],
            "version": RESULT_FORMAT[1],
            "model": model_to_dict(self.model),
            "names": list(self.names),
            "values": _f2j(self.values),
            "stderr": _f2j(self.stderr),
            "cov": _f2j(self.cov),
            "corr": _f2j(self.corr),
            "cov_naive": _f2j(self.cov_naive),
            "R": _c2j(self.R),
            "cost_history": list(self.cost_history),
            "iterations": self.iterations,
            "converged": self.converged,
            "message": self.message,
            "derived": {k: [v, s if math.isfinite(s) else str(s)] for k, (v, s) in self.derived.items()},
            "fixed": self.fixed,
            "at_bound": list(self.at_bound),
            "outputs": list(self.outputs),
            "band": None if self.band is None else list(self.band),
            "n_freq": self.n_freq,
            "records": list(self.records),
            "boundary": self.boundary,
            "cov_type": self.cov_type,
            "method": self.method,
            "stop": self.stop,
            "stopped": self.stopped,
            "warnings": list(self.warnings),
            "elapsed": self.elapsed,
            "spectra": [
                {
                    "name": s["name"], "omega": _f2j(s["omega"]), "z": _c2j(s["z"]), "u": _c2j(s["u"]),
                    "inputs": s["inputs"], "x0": _f2j(s["x0"]), "xT": _f2j(s["xT"]), "T": s["T"],
                    "dt": s["dt"], "n": s["n"], "ones": _c2j(s["ones"]),
                }
                for s in self.spectra
            ],
            "nuisance": self.nuisance,
            "findings": [f.to_dict() for f in self.findings],
            "time_records": [
                None if r is None else
                {"name": r["name"], "t": _f2j(r["t"]),
                 "signals": {k: _f2j(v) for k, v in r["signals"].items()},
                 "meta": _jsonable(r["meta"]), "trim_mode": r["trim_mode"]}
                for r in self.time_records
            ],
        }

    def to_json(self, path: str | Path | None = None, indent: int = 1):
        """JSON text, or, given ``path``, write it atomically there and return the path."""
        text = json.dumps(self.to_dict(), indent=indent)
        if path is None:
            return text
        from .record import atomic_write_text

        atomic_write_text(path, text)
        return Path(path)

    @classmethod
    def from_dict(cls, d: dict) -> "FitResult":
        """Inverse of :meth:`to_dict`."""
        from .models import model_from_dict

        if d.get("format") != RESULT_FORMAT[0]:
            raise FdmlError("not an fdml result file (format field missing or wrong)")
        if d.get("version") != RESULT_FORMAT[1]:
            raise FdmlError(f"fdml result version {d.get('version')} is not supported (expected {RESULT_FORMAT[1]})")
        spectra = tuple(
            {
                "name": s["name"], "omega": _j2f(s["omega"]), "z": _j2c(s["z"]), "u": _j2c(s["u"]),
                "inputs": s["inputs"], "x0": _j2f(s["x0"]), "xT": _j2f(s["xT"]), "T": s["T"],
                "dt": s["dt"], "n": s["n"], "ones": _j2c(s["ones"]),
            }
            for s in d.get("spectra", [])
        )
        return cls(
            model=model_from_dict(d["model"]),
            names=tuple(d["names"]),
            values=_j2f(d["values"]),
            stderr=_j2f(d["stderr"]),
            cov=_j2f(d["cov"]),
            corr=_j2f(d["corr"]),
            cov_naive=_j2f(d["cov_naive"]),
            R=_j2c(d["R"]),
            cost_history=tuple(d["cost_history"]),
            iterations=d["iterations"],
            converged=d["converged"],
            message=d["message"],
            derived={k: (float(v[0]), float(v[1])) for k, v in d["derived"].items()},
            fixed=dict(d["fixed"]),
            at_bound=tuple(d["at_bound"]),
            outputs=tuple(d["outputs"]),
            band=None if d["band"] is None else tuple(d["band"]),
            n_freq=d["n_freq"],
            records=tuple(d["records"]),
            boundary=d["boundary"],
            cov_type=d["cov_type"],
            method=d.get("method", "lm"),
            stop=d.get("stop", "converge"),
            stopped=d.get("stopped", False),
            warnings=tuple(d.get("warnings", ())),
            elapsed=d.get("elapsed", 0.0),
            spectra=spectra,
            nuisance=d.get("nuisance", {}),
            findings=tuple(Finding.from_dict(f) for f in d.get("findings", ())),
            time_records=tuple(
                None if r is None else
                {"name": r["name"], "t": _j2f(r["t"]),
                 "signals": {k: _j2f(v) for k, v in r["signals"].items()},
                 "meta": r["meta"], "trim_mode": r["trim_mode"]}
                for r in d.get("time_records", [])
            ),
        )

    def record(self, index: int = 0):
        """The time-domain record ``index`` as given to the fit (a :class:`~fdml.record.Record`)."""
        from .record import Record

        if not self.time_records or self.time_records[index] is None:
            raise FdmlError(f"this result holds no time-domain records for record {index} (the fit was given spectra)")
        r = self.time_records[index]
        return Record(np.asarray(r["t"], float), {k: np.asarray(v, float) for k, v in r["signals"].items()},
                      name=r["name"], meta=r["meta"], check_units=False)

    def fitted_spectra(self, record: int = 0) -> np.ndarray:
        """Model output spectra at the estimate for record ``record``, shape (m, 3).

        Includes the estimated (or measured) boundary terms and biases, so that
        it is directly comparable with the measured ``spectra[record]["z"]``.
        """
        s = self.spectra[record]
        resp = self.model.evaluate(s["omega"])
        multi = len(self.spectra) > 1
        suffix = f"[{s['name']}]" if multi else ""
        p = self.params
        x0 = np.array([p.get(f"x0_alpha{suffix}", s["x0"][0]), p.get(f"x0_q{suffix}", s["x0"][1])])
        xT = np.array([p.get(f"xT_alpha{suffix}", s["xT"][0]), p.get(f"xT_q{suffix}", s["xT"][1])])
        if self.boundary == "none":
            bd = np.zeros((s["omega"].size, 2), complex)
        else:
            bd = x0[None] - xT[None] * np.exp(-1j * s["omega"] * s["T"])[:, None]
        b = np.array([p.get(f"bias_{o}{suffix}", self.model.parameters.values[f"bias_{o}"])
                      for o in ("alpha", "q", "az")])
        u = s["u"][:, : resp.G.shape[2]]
        y = (np.einsum("mij,mj->mi", resp.G, u) + np.einsum("mij,mj->mi", resp.H, bd)
             + s["ones"][:, None] * b[None])
        sb = np.array([p.get(f"bias_alpha_dot{suffix}", 0.0), p.get(f"bias_q_dot{suffix}", 0.0)])
        y = y + (resp.P @ sb) * s["ones"][:, None]
        y = y + resp.G[:, :, 0] * (p.get(f"bias_de{suffix}", 0.0) * s["ones"])[:, None]
        return y


def load_result(path: str | Path) -> FitResult:
    """Read a result saved by :meth:`FitResult.to_json`."""
    path = Path(path)
    if not path.exists():
        raise FdmlError(f"result file {path} does not exist")
    try:
        d = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise FdmlError(f"result file {path} is not valid JSON: {exc}") from None
    return FitResult.from_dict(d)
