"""The options of a fit, declared once: :class:`FitOptions`.

Each field of :class:`FitOptions` is one option of :func:`fdml.fit`, with its
default, its allowed values, its documentation and (where the command line
shows it) its ``--help`` text, all in the field's declaration.  From that one
table come:

* the keyword arguments of :func:`fdml.fit` and :func:`fdml.estimate.prepare`
  (their signatures and the option part of their docstrings);
* the fit options of the command line (``fdml.commands._options``);
* the check and the input hash of ``fdml batch`` and ``fdml montecarlo``;
* :attr:`fdml.results.FitResult.options` (:meth:`FitOptions.to_dict` of the
  options as resolved).

Values are checked once, when a :class:`FitOptions` is made, and each bad one
is a one-line :class:`~fdml.errors.FdmlError`.  The options that say how a
record becomes spectra (``omega``, ``band``, ``trim``, ``trim_window``,
``end_correction``) default to None, "not given": a time-domain record then
gets :func:`fdml.spectral.spectra`'s defaults, and spectra given as
:class:`~fdml.spectral.FrequencyData` keep their own.  Given with spectra that
were made otherwise, such an option does not apply, and the fit refuses it
(:meth:`FitOptions.refuse_inapplicable`).
"""

from __future__ import annotations

import inspect
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from .channels import ALL_OUTPUTS, row_space
from .errors import FdmlError, ParameterError
from .fourier import END_CORRECTIONS
from .parameters import as_names, check_fix_free, fixed_values
from .record import TRIM_MODES
from .spectral import parse_band

if TYPE_CHECKING:
    from .estimate import Problem
    from .spectral import FrequencyData

__all__ = ["FitOptions", "NoiseModel", "parse_outputs"]


def known_outputs(outputs, prefix: str = "") -> tuple[str, ...]:
    """``outputs`` as a tuple, after checking that each is one of :data:`~fdml.channels.ALL_OUTPUTS`.

    Parameters
    ----------
    outputs : sequence of str
        The output names.
    prefix : str, optional
        Put before the message (the option's name).

    Returns
    -------
    tuple of str
        The output names, in the order given.

    Raises
    ------
    FdmlError
        An unknown name, named in the message.
    """
    bad = [o for o in outputs if o not in ALL_OUTPUTS]
    if bad:
        raise FdmlError(f"{prefix}unknown output(s) {bad}; choose from {', '.join(ALL_OUTPUTS)}")
    return tuple(outputs)


def parse_outputs(outputs, *, what: str = "outputs") -> tuple[str, ...]:
    """The fitted outputs as a tuple of names, from a sequence or ``"alpha,q,az"``.

    None gives :data:`~fdml.channels.OUTPUTS` (alpha, q, a_z); any of
    :data:`~fdml.channels.ALL_OUTPUTS` (``theta``, ``qdot`` too) may be named.  An unknown name, a
    name given twice (``alpha,alpha``) or an empty list is an
    :class:`~fdml.errors.FdmlError` naming it (``what`` names the option).

    Parameters
    ----------
    outputs : None, str or sequence of str
        The outputs; None for all.
    what : str, optional
        The option's name, for messages.

    Returns
    -------
    tuple of str
        The output names, in the order given.
    """
    if outputs is None:
        return row_space()
    items = [str(o).strip() for o in (outputs.split(",") if isinstance(outputs, str) else outputs)]
    if not items or not any(items):
        raise FdmlError(f"{what}: empty; choose from {', '.join(ALL_OUTPUTS)}")
    if "" in items:
        raise FdmlError(f"{what} {outputs!r}: an empty item; give names separated by commas")
    dup = sorted({o for o in known_outputs(items, f"{what}: ") if items.count(o) > 1})
    if dup:
        raise FdmlError(f"{what}: {', '.join(dup)} given more than once; name each output once")
    return tuple(items)


@dataclass(frozen=True)
class NoiseModel:
    """The noise model of the likelihood: which residual covariance the estimator concentrates out.

    ``NoiseModel()`` (white, the default of :func:`fdml.fit`): one R over the whole band (Eq. 24), cost
    ln det R (Eq. 25).  ``NoiseModel(edges)``: one R_b per frequency band [e_b, e_b+1) (Eq. 24 within
    each band), cost (1/N) sum_b N_b ln det R_b: the likelihood of noise whose spectrum is flat within
    each band but not across them (coloured sensor noise, turbulence; fdml.diagnose uses it).

    Parameters
    ----------
    edges : tuple of float
        Band edges, rad/s, increasing; empty (or two edges, one band) is white.
    """

    edges: tuple = ()

    def __post_init__(self):
        try:
            e = tuple(float(x) for x in self.edges)
        except (TypeError, ValueError):
            e = (math.nan,)
        if len(e) == 1 or not all(map(math.isfinite, e)) or any(b <= a for a, b in itertools.pairwise(e)):
            raise FdmlError(f"noise band edges must be two or more increasing numbers in rad/s, got {self.edges!r}")
        object.__setattr__(self, "edges", e)

    @property
    def n(self) -> int:
        """Number of noise bands (1: white)."""
        return max(len(self.edges) - 1, 1)

    def assign(self, omega) -> np.ndarray:
        """Band index of each frequency (rad/s); frequencies beyond the edges join the outer bands.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.

        Returns
        -------
        numpy.ndarray
            Band index (int) of each frequency, same shape.
        """
        if self.n == 1:
            return np.zeros(np.shape(omega), int)
        idx = np.searchsorted(np.asarray(self.edges), omega, side="right") - 1
        return np.clip(idx, 0, self.n - 1)

    def rows(self, prob: Problem) -> np.ndarray | None:
        """Band of each stacked residual row of ``prob`` (records in order); None when white.

        Parameters
        ----------
        prob : Problem
            The fit.

        Returns
        -------
        numpy.ndarray or None
            Band index of each row, shape (N,).
        """
        return None if self.n == 1 else self.assign(np.concatenate([d.omega for d in prob.data]))


# --- the table ------------------------------------------------------------------------------------
#: Where an option acts: how records become spectra, how the problem is set up (both taken by
#: :func:`fdml.estimate.prepare`), how the likelihood is maximised, and the checks around it.
SPECTRA, PROBLEM, ITERATION, CHECKS = "spectra", "problem", "iteration", "checks"


def _option(default, stage: str, *, choices=None, cli: str | None = None, **cli_kw) -> Any:
    """One option's declaration: a dataclass field whose metadata holds the rest of the table's row.

    ``stage`` says where it acts; ``choices`` are the allowed values (checked, and the command
    line's choices); ``cli`` its ``--help`` text when the command line shows it, with ``cli_kw``
    what the command line needs beyond it (``values``: the command line's spellings).  Its
    documentation is its entry in :class:`FitOptions`' docstring.
    """
    meta = {"stage": stage, "choices": choices, "cli": cli, "cli_kw": cli_kw}
    return field(default=default, metadata=MappingProxyType(meta))


def _bool(name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise FdmlError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def _one_of(name: str, value, choices) -> Any:
    if not any(value is c or (type(value) is type(c) and value == c) for c in choices):
        spelled = ", ".join(map(repr, choices[:-1])) + f" or {choices[-1]!r}"
        raise FdmlError(f"{name} must be {spelled}, got {value!r}")
    return value


def _number(name: str, value, *, minimum: float, integer: bool = False):
    ok = isinstance(value, (int, np.integer)) if integer else isinstance(value, (int, float, np.integer, np.floating))
    if isinstance(value, (bool, np.bool_)) or not ok or not math.isfinite(value) or value < minimum:
        what = "an integer" if integer else "a finite number"
        raise FdmlError(f"{name} must be {what} of at least {minimum:g}, got {value!r}")
    return int(value) if integer else float(value)


def _omega(value) -> tuple | None:
    if value is None:
        return None
    try:
        w = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise FdmlError(f"omega must be frequencies in rad/s (a list of numbers), got {value!r}") from None
    if w.ndim != 1 or w.size == 0:
        raise FdmlError(f"omega must be a non-empty list of frequencies in rad/s, got shape {w.shape}")
    return tuple(w.tolist())


def _fix(value):
    fix = fixed_values(value)
    return MappingProxyType(fix) if isinstance(fix, dict) else tuple(fix)


def _side(name: str, x) -> float | None:
    """One side of a bound as kept: a finite number, or None for an open side."""
    if x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ParameterError(f"bounds: {name} must be (lower, upper) with numbers or None, got {x!r}") from None
    if math.isnan(v):
        raise ParameterError(f"bounds: {name} has a NaN bound; give a number or None")
    return v if math.isfinite(v) else None


def _bounds(value) -> Mapping:
    if value is None:
        return MappingProxyType({})
    if not isinstance(value, Mapping):
        raise ParameterError(f"bounds must be a mapping {{name: (lower, upper)}}, got {type(value).__name__}")
    out = {}
    for k, pair in value.items():
        if isinstance(pair, (str, bytes)) or not hasattr(pair, "__len__") or len(pair) != 2:
            raise ParameterError(f"bounds: {k} must be (lower, upper) with numbers or None, got {pair!r}")
        out[str(k)] = (_side(k, pair[0]), _side(k, pair[1]))
    return MappingProxyType(out)


def _noise(value) -> NoiseModel:
    if isinstance(value, NoiseModel):
        return value
    if value is None or isinstance(value, (list, tuple)):
        return NoiseModel(tuple(value or ()))  # None: white
    raise FdmlError(f"noise must be an fdml.estimate.NoiseModel, got {type(value).__name__}")


@dataclass(frozen=True)
class FitOptions:
    """Every option of :func:`fdml.fit`, checked once.

    Frozen: :func:`dataclasses.replace` (or :meth:`of`) gives a changed copy,
    checked again.  ``fdml.fit(record, model, band=..., ...)`` makes one from its
    keywords; ``fdml.fit(record, model, options)`` takes one made before (and
    keywords given beside it replace its fields).  The entries below are the
    options' documentation everywhere (:func:`takes_options`).

    Parameters
    ----------
    omega : array_like, optional
        Frequencies, rad/s; default the ``band`` grid (time-domain records).
    band : tuple or str, optional
        ``(lo, hi, step)`` rad/s or ``"LO:HI:STEP"``; default 0.1:10:0.1
        (time-domain records).
    outputs : sequence of str or str, optional
        Outputs that enter the fit (default ``alpha, q, az``); ``theta`` and
        ``qdot`` may be named too (:data:`fdml.channels.ALL_OUTPUTS`).
    boundary : {"estimated", "measured", "none"}, optional
        Klein's boundary terms ``x(0) - x(T) exp(-jwT)`` for alpha, q (and
        theta when fitted; docs/theory.md section 7): estimated as nuisance parameters (default),
        taken from the measured first and last samples, or omitted (then a
        record that ends far from trim triggers a :class:`~fdml.errors.DataWarning`).
    biases : {"auto", True, False}, optional
        Estimate an output bias for every fitted output.  ``"auto"`` (default)
        does so whenever trim was removed from a record: the trim value is
        itself a noisy estimate (the first sample, or a short mean), and its
        error is a constant offset on the whole record, i.e. exactly an
        output bias; left unestimated it biases the low-frequency fit.
    state_biases : bool, optional
        Estimate constants ``bias_alpha_dot`` (rad/s) and ``bias_q_dot``
        (rad/s^2) added to the two state equations, per record: they absorb a
        trim that is not an equilibrium (an elevator trim error, a trimmed
        pitch acceleration).
    input_bias : bool, optional
        Estimate a constant elevator offset ``bias_de`` (rad) per record: the
        error of the elevator trim (a special case of state-equation biases
        along the elevator's input direction).
    input_edges : {"auto", "estimated", "none"}, optional
        Where the elevator steps between two samples (:func:`fdml.fourier.step_edges`),
        the record does not keep the step's time: the transform puts it mid-interval.
        ``"estimated"`` estimates each such step's timing ``edge_de_k`` (s, within
        +-dt/2) per record (docs/theory.md section 7a); ``"none"`` (default) takes
        the interpolated record as the input; ``"auto"`` fits without them,
        then estimates them when the steps' timings differ: when their score test,
        given a shift common to every step, rejects equal timing at
        :attr:`~fdml.estimator_settings.EstimatorSettings.edge_level`.  A common
        shift alone is an elevator delay, which the model's lags resemble: auto
        leaves it to the model (``--effect time_delay:de``).  The result's
        ``options`` say what was done.  Records without such steps are unaffected.
        The terms also absorb part of a misfit of the model itself (a steady
        model fitted to unsteady data), which is why they are not on by default.
    free : str or sequence of str, optional
        Names to free: one name (``free="Cm_de"``), several separated by
        commas, or a sequence.
    fix : str, sequence of str or mapping, optional
        Names to fix, or a ``{name: value}`` mapping, as for ``free``.  A name
        in both is an error, not "the last wins".
    bounds : mapping, optional
        ``{name: (lower, upper)}``; None for an open side.
    method : {"lm", "gauss-newton"}, optional
        Levenberg-Marquardt on ln det R (default) or the paper's alternation.
    stop : {"converge", "paper"}, optional
        Run to convergence (default) or stop when the relative change of
        J = det R falls below 0.01 (the paper's rule).
    tol : float, optional
        Convergence: every parameter step below ``tol`` standard errors.
    max_iter : int, optional
        Most iterations (default 200).
    sensitivity : {"auto", "analytic", "fd", "central"}, optional
        ``analytic``: derivatives of the model matrices propagated exactly
        through the solve (closed forms for every model's theta; central
        differences of the matrices for freed constants).  ``fd``: the paper's
        Eq. 26 forward differences of the outputs with the step halved until
        they settle.  ``central``: central differences of the outputs.
        ``auto`` (default): ``analytic`` when every free model parameter has a
        closed form, else ``fd``.  Both give the same estimates and bounds to
        six significant figures or better.
    cov_type : {"white", "colored", "naive"}, optional
        ``white`` (default): covariance of the estimate for white measurement
        noise, carried exactly through the transform, the frequency grid and
        the trim removal (a sandwich form); at independent frequency spacing
        2 pi/T it equals the Cramer-Rao bound.  ``colored``: the same with the
        noise level following the smoothed residual spectrum (the
        frequency-domain analogue of the Morelli-Klein correction; use it on
        real data, where residuals hold model error).  ``naive``: the inverse of
        ``2 Re sum A^H R^-1 A``, which treats every frequency as independent
        and is optimistic on a grid finer than 2 pi/T (docs/theory.md section 7).
    noise : NoiseModel or sequence of float, optional
        The noise model of the likelihood: white, one R over the band (Eq. 24;
        the default), or ``NoiseModel(edges)`` (or the edges), one R_b per
        frequency band (edges in rad/s).  With band-wise noise, ``R`` in the
        result is still Eq. 24 over the whole band, ``cost`` is
        exp((1/N) sum_b N_b ln det R_b), and the ``white`` covariance scales
        the noise to each band's level.
    trim : {"first", "mean", "none"}, optional
        Trim removal of time-domain records (:func:`fdml.spectral.spectra`;
        default ``first``).
    trim_window : float, optional
        Leading window for ``trim="mean"``, s (default 0.5 s).
    end_correction : {"cubic", "trapezoid", "none"}, optional
        End correction of the finite Fourier integral (default ``cubic``).
    check : bool, optional
        Run the data check (:func:`fdml.datacheck.check_data`: units, signs,
        swapped channels, no response) on every record given in the time
        domain (default True); its findings are issued as
        :class:`~fdml.errors.DataWarning` and kept in ``FitResult.findings``.
    strict : bool, optional
        Raise :class:`~fdml.errors.DataCheckError` before fitting when the
        data check finds anything (default False).
    adequacy : bool, optional
        After a converged fit, check its adequacy (:func:`fdml.adequacy.check`:
        score tests of the effect library, residual coherence and whiteness,
        no refits); kept in ``FitResult.adequacy``, and an
        :class:`~fdml.errors.AdequacyWarning` names a flagged effect and the
        command that refits with it.  False skips it (default True).
    """

    omega: tuple | None = _option(None, SPECTRA)
    band: tuple | None = _option(None, SPECTRA)
    outputs: tuple = _option(
        None, PROBLEM, cli="outputs in the fit, comma-separated, each once (default alpha,q,az)", metavar="NAME,..."
    )
    boundary: str = _option(
        "estimated",
        PROBLEM,
        choices=("estimated", "measured", "none"),
        cli="boundary terms x(0) - x(T)exp(-jwT) (default estimated)",
    )
    biases: bool | str = _option(
        "auto",
        PROBLEM,
        choices=("auto", True, False),
        cli="estimate output biases (default auto: when trim is removed)",
        values={"auto": "auto", "yes": True, "no": False},
    )
    state_biases: bool = _option(
        False,
        PROBLEM,
        cli="estimate constant biases of the two state equations per record (a trim that is not an equilibrium)",
    )
    input_bias: bool = _option(
        False, PROBLEM, cli="estimate a constant elevator offset per record (an elevator trim error)"
    )
    input_edges: str = _option(
        "none",
        PROBLEM,
        choices=("auto", "estimated", "none"),
        cli="timing of elevator steps between two samples, one term per step within +-dt/2 "
        "(default none; auto: when their score test asks for it)",
    )
    free: tuple = _option((), PROBLEM, cli="free parameters (repeatable)", metavar="NAME", repeat=True)
    fix: Any = _option((), PROBLEM, cli="fix parameters at values (repeatable)", metavar="NAME=VALUE", repeat=True)
    bounds: Mapping = _option(None, PROBLEM)
    method: str = _option(
        "lm",
        ITERATION,
        choices=("lm", "gauss-newton"),
        cli="Levenberg-Marquardt (default lm) or the paper's alternation",
    )
    stop: str = _option(
        "converge",
        ITERATION,
        choices=("converge", "paper"),
        cli="run to convergence (default) or the paper's 1 %% rule",
    )
    tol: float = _option(1e-3, ITERATION)
    max_iter: int = _option(200, ITERATION)
    sensitivity: str = _option(
        "auto",
        PROBLEM,
        choices=("auto", "analytic", "fd", "central"),
        cli="output sensitivities (default auto: analytic where closed forms exist, else Eq. 26)",
    )
    cov_type: str = _option(
        "white",
        ITERATION,
        choices=("white", "colored", "naive"),
        cli="error bounds: white noise (default), colored (the noise level follows the residual "
        "spectrum; recommended on real records) or naive",
    )
    noise: NoiseModel = _option(None, ITERATION)
    trim: str | None = _option(None, SPECTRA, choices=TRIM_MODES, cli="trim removal (default first: the first sample)")
    trim_window: float | None = _option(None, SPECTRA)
    end_correction: str | None = _option(None, SPECTRA, choices=END_CORRECTIONS)
    check: bool = _option(True, CHECKS)
    strict: bool = _option(False, CHECKS)
    adequacy: bool = _option(True, CHECKS)

    def __post_init__(self) -> None:
        for f in fields(self):
            choices = f.metadata["choices"]
            value = getattr(self, f.name)
            if choices is not None and not (value is None and f.default is None):
                _one_of(f.name, value, choices)
        check_fix_free(self.fix, self.free)  # a name in both: neither wins
        set_ = object.__setattr__
        set_(self, "omega", _omega(self.omega))
        set_(self, "band", None if self.band is None else parse_band(self.band))
        set_(self, "outputs", parse_outputs(self.outputs))
        set_(self, "free", tuple(as_names(self.free, "free")))
        set_(self, "fix", _fix(self.fix))
        set_(self, "bounds", _bounds(self.bounds))
        set_(self, "noise", _noise(self.noise))
        set_(self, "tol", _number("tol", self.tol, minimum=0.0))
        set_(self, "max_iter", _number("max_iter", self.max_iter, minimum=0, integer=True))
        if self.trim_window is not None:
            set_(self, "trim_window", _number("trim_window", self.trim_window, minimum=0.0))
        for name in ("state_biases", "input_bias", "check", "strict", "adequacy"):
            set_(self, name, _bool(name, getattr(self, name)))

    # --- making one -----------------------------------------------------------------------------
    @classmethod
    def of(cls, options: FitOptions | None = None, **keywords) -> FitOptions:
        """``options`` with ``keywords`` (option names) replacing its fields; from the defaults without it.

        Parameters
        ----------
        options : FitOptions, optional
            Options made before; default all the defaults.
        **keywords
            Options by name (the fields of :class:`FitOptions`).

        Returns
        -------
        FitOptions
            The options, checked.
        """
        unknown = sorted(set(keywords) - set(cls.names()))
        if unknown:
            raise FdmlError(f"unknown fit option(s) {unknown}; fit takes {', '.join(sorted(cls.names()))}")
        if options is None:
            return cls(**keywords)
        if not isinstance(options, FitOptions):
            raise FdmlError(f"options must be an fdml FitOptions, got {type(options).__name__}")
        return replace(options, **keywords) if keywords else options

    @classmethod
    def names(cls, *stages: str) -> tuple[str, ...]:
        """The option names, in declaration order; only those of ``stages`` when given.

        Parameters
        ----------
        *stages : str
            ``"spectra"``, ``"problem"``, ``"iteration"``, ``"checks"``.

        Returns
        -------
        tuple of str
            The names.
        """
        return tuple(f.name for f in _declared(*stages))

    def pick(self, *stages: str) -> dict:
        """The options of ``stages`` by name (keyword arguments for the stage's function).

        Parameters
        ----------
        *stages : str
            As for :meth:`names`.

        Returns
        -------
        dict
            Option name -> value.
        """
        return {n: getattr(self, n) for n in self.names(*stages)}

    # --- spectra given as such ------------------------------------------------------------------
    def refuse_inapplicable(self, d: FrequencyData, index: int) -> None:
        """Refuse a spectral option given with spectra that were made otherwise (the option does not apply).

        Parameters
        ----------
        d : FrequencyData
            Spectra given to the fit as such.
        index : int
            Their place among the fit's data (0 for the first), for the message.
        """
        own = {
            "omega": None if self.omega is None or np.array_equal(self.omega, d.omega) else "its own frequencies",
            "band": None if self.band is None or self.band == d.band else f"band {_band_text(d.band)}",
            "trim": None if self.trim is None or self.trim == d.trim_mode else f"trim {d.trim_mode!r}",
            "end_correction": None
            if self.end_correction is None or self.end_correction == d.end_correction
            else f"end correction {d.end_correction!r}",
        }
        if self.trim_window is not None and d.trim_mode == "mean" and d.trim_samples != _lead(self.trim_window, d.dt):
            own["trim_window"] = f"a {(d.trim_samples - 1) * d.dt:g} s trim window"
        bad = next((k for k, v in own.items() if v is not None), None)
        if bad is not None:
            raise FdmlError(
                f"{bad}={_text(getattr(self, bad))} does not apply to record {index + 1} ({d.name!r}): it was "
                f"given as spectra, made with {own[bad]}; give the time-domain record, or its spectra made so"
            )

    def resolved(self, data, *, biases: bool, sensitivity: str) -> FitOptions:
        """The options as a fit used them: ``auto`` choices made, spectral defaults read from ``data``.

        Parameters
        ----------
        data : list of FrequencyData
            The spectra fitted.
        biases : bool
            Whether output biases were estimated.
        sensitivity : str
            The sensitivities used.

        Returns
        -------
        FitOptions
            The resolved copy.
        """
        d = data[0]
        window = self.trim_window
        if window is None and d.trim_mode == "mean":
            window = (d.trim_samples - 1) * d.dt
        return replace(
            self,
            band=d.band if self.band is None else self.band,
            trim=d.trim_mode if self.trim is None else self.trim,
            trim_window=window,
            end_correction=d.end_correction if self.end_correction is None else self.end_correction,
            biases=biases,
            sensitivity=sensitivity,
        )

    # --- JSON -----------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The options as plain JSON data (lists for tuples, noise as its band edges, open bounds None).

        Returns
        -------
        dict
            Option name -> value.
        """
        out = self.pick()
        out["noise"] = list(self.noise.edges)
        out["fix"] = dict(self.fix) if isinstance(self.fix, Mapping) else list(self.fix)
        out["bounds"] = {k: list(v) for k, v in self.bounds.items()}
        for name in ("omega", "band", "outputs", "free"):
            out[name] = None if out[name] is None else list(out[name])
        return out

    @classmethod
    def from_dict(cls, d: Mapping, *, source: str = "fit options") -> FitOptions:
        """Inverse of :meth:`to_dict`; keys that are no option are left alone, absent ones get the default.

        Parameters
        ----------
        d : mapping
            As written by :meth:`to_dict`.
        source : str, optional
            What ``d`` came from, for the message.

        Returns
        -------
        FitOptions
            The options.
        """
        from .jsoncodec import Fields

        return cls.from_fields(Fields(d, source))

    @classmethod
    def from_fields(cls, f) -> FitOptions:
        """:meth:`from_dict` from the fields of a JSON object (a bad option names the object's key).

        Parameters
        ----------
        f : fdml.jsoncodec.Fields
            The options' object.

        Returns
        -------
        FitOptions
            The options.
        """
        kw = {name: f.raw(name) for name in cls.names() if name in f}
        try:
            return cls(**kw)
        except (FdmlError, TypeError, ValueError) as exc:
            where = f"key '{f.prefix.rstrip('.')}'" if f.prefix else "the object"
            raise FdmlError(f"{f.source}: {where} holds no valid fit options: {exc}") from None

    def __reduce__(self):  # as plain data: mapping proxies cannot be pickled as they are
        return (FitOptions.from_dict, (self.to_dict(),))


def _declared(*stages: str) -> list:
    """The fields of :class:`FitOptions` (the options' declarations) of ``stages``, all without."""
    return [f for f in fields(FitOptions) if not stages or f.metadata["stage"] in stages]


def _lead(window: float, dt: float) -> int:
    """Samples in a leading trim window (as :meth:`fdml.record.Record.remove_trim` counts them)."""
    return int(round(window / dt)) + 1


def _band_text(band) -> str:
    return "(none: its own frequencies)" if band is None else ":".join(f"{x:g}" for x in band)


def _text(value) -> str:
    if isinstance(value, tuple) and len(value) == 3:
        return _band_text(value)
    if isinstance(value, tuple):
        return f"({len(value)} frequencies)"
    return repr(value)


# --- what the table gives the functions that take the options ------------------------------------
def option_docs(*stages: str) -> str:
    """The numpydoc entries of the options of ``stages`` (all without), from :class:`FitOptions`' docstring.

    Parameters
    ----------
    *stages : str
        As for :meth:`FitOptions.names`.

    Returns
    -------
    str
        ``name : type`` lines, each followed by its description, indented for a Parameters section.
    """
    entries: dict[str, list[str]] = {}
    section = (inspect.getdoc(FitOptions) or "").split("----------\n", 1)[1]
    for line in section.splitlines():
        if line and not line.startswith(" "):
            entries[line.split(" : ")[0]] = []
        entries[next(reversed(entries))].append(line)
    return "\n".join("    " + ln if ln else ln for n in FitOptions.names(*stages) for ln in entries[n])


def keyword_parameters(*stages: str) -> list[inspect.Parameter]:
    """The options of ``stages`` (all without) as keyword-only parameters with their defaults.

    Parameters
    ----------
    *stages : str
        As for :meth:`FitOptions.names`.

    Returns
    -------
    list of inspect.Parameter
        One per option, in declaration order.
    """
    return [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default) for f in _declared(*stages)]


def command_line_options() -> list[dict]:
    """The options the command line shows, in declaration order, as argparse needs them.

    Returns
    -------
    list of dict
        Per option: ``name``, ``flag`` (``--name`` with hyphens), ``help``, ``choices`` (the command
        line's spellings, or None), ``values`` (spelling -> option value), ``switch`` (a bool option:
        a flag without value), ``repeat`` (given several times) and ``metavar`` where it has one.
    """
    out = []
    for f in fields(FitOptions):
        if f.metadata["cli"] is None:
            continue
        kw = dict(f.metadata["cli_kw"])
        values = kw.pop("values", {})
        out.append(
            {
                "name": f.name,
                "flag": "--" + f.name.replace("_", "-"),
                "help": f.metadata["cli"],
                "choices": tuple(values or f.metadata["choices"] or ()) or None,
                "values": values,
                "switch": isinstance(f.default, bool),
                "repeat": kw.pop("repeat", False),
                **kw,
            }
        )
    return out


#: The line of a docstring that the options' entries replace (see :func:`takes_options`).
OPTIONS_MARK = "    <the fit options: FitOptions' fields>\n"


def takes_options(*stages: str):
    """Decorator: the function takes the options of ``stages`` (all without) as keywords.

    Its signature gets them as keyword-only parameters with their defaults (before
    its own keyword-only ones), and the line :data:`OPTIONS_MARK` of its docstring
    their entries: the options are declared once, in :class:`FitOptions`.

    Parameters
    ----------
    *stages : str
        As for :meth:`FitOptions.names`.

    Returns
    -------
    callable
        The decorator.
    """

    def wrap(func):
        sig = inspect.signature(func)
        params = [p for p in sig.parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
        own_kw = [p for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY]
        head = [p for p in params if p.kind is not inspect.Parameter.KEYWORD_ONLY]
        func.__signature__ = sig.replace(parameters=head + keyword_parameters(*stages) + own_kw)
        func.__doc__ = (func.__doc__ or "").replace(OPTIONS_MARK, option_docs(*stages) + "\n")
        return func

    return wrap
