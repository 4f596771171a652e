"""Frequency-domain maximum-likelihood estimation, docs/theory.md Eqs. 20-26.

The measured output spectra z(w) are modelled as (Eqs. 18-19)

    z(w_i) = G(w_i, theta) u(w_i) + H(w_i, theta) d_i + b ones(w_i) + v(w_i)

with Klein's boundary terms ``d_i = x(0) - x(T) exp(-j w_i T)`` (section 7;
measured, estimated, or none), output biases ``b`` and complex Gaussian
residuals ``v`` with covariance R.  Maximising Eq. 20 over R gives Eq. 24,
and the concentrated cost is ``ln det R(theta)`` (Eq. 25's J = det R).

Two iterations are offered:

``"lm"`` (default)
    Levenberg-Marquardt on the concentrated likelihood ``ln det R(theta)``:
    its gradient is ``-(2/N) Re sum A^H R^-1 v`` (the Eq. 23 right-hand side)
    and its Gauss-Newton Hessian ``(2/N) Re sum A^H R^-1 A - tr(R^-1 dR_k
    R^-1 dR_l)`` includes the dependence of R on theta, which the paper's
    alternation ignores; so it converges in a few passes where alternation
    needs tens.
``"gauss-newton"``
    The paper's algorithm: a Gauss-Newton step (Eq. 23) with R held at its
    last value, step halving while det R rises, then R re-estimated (Eq. 24).

Sensitivities are forward differences (Eq. 26) with the step halved until
they settle; the linear nuisance terms (boundary values, biases) have exact
sensitivities.  By default the iteration runs to convergence (every step
below ``tol`` times its standard error, ln det R settled); ``stop="paper"``
applies the paper's rule, relative change of J below 0.01.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from . import fourier
from .channels import STATES, boundary_channels
from .errors import (
    BandError,
    BoundsWarning,
    ConvergenceWarning,
    FdmlError,
    IdentifiabilityWarning,
    ParameterError,
    RecordError,
)
from .estimator_settings import SETTINGS, EstimatorSettings
from .findings import emit, raise_if_strict
from .fit_options import CHECKS, ITERATION, PROBLEM, SPECTRA, FitOptions, NoiseModel, parse_outputs, takes_options
from .models.base import Model, model_airspeed
from .models.measurement import (
    INPUT_BIAS_NAME,
    STATE_BIAS_NAMES,
    Nuisance,
    edge_basis,
    edge_names,
    end_shift,
    nuisance_columns,
    nuisance_names,
)
from .models.measurement import predict as _measure
from .parameters import Role
from .record import Record
from .results import FitResult, IterationInfo, correlation
from .spectral import FrequencyData, spectra
from .warning_log import recording

__all__ = ["SETTINGS", "EstimatorSettings", "FitOptions", "NoiseModel", "Problem", "fit", "parse_outputs", "prepare"]


def _nuisance_base(rows: tuple) -> dict:
    """Base names of each nuisance role of outputs ``rows``, by the slot's index (fdml.models.measurement order)."""
    names, ny, nb = nuisance_names(rows), len(rows), len(boundary_channels(rows))
    return {
        Role.OUTPUT_BIAS: names[:ny],
        Role.BOUNDARY: names[ny : ny + 2 * nb],  # x(0), x(T) of alpha, q[, theta] (docs/theory.md section 7)
        Role.STATE_BIAS: STATE_BIAS_NAMES,  # constants added to the alpha_dot (rad/s) and q_dot (rad/s^2) equations
        Role.INPUT_BIAS: (INPUT_BIAS_NAME,),
    }


@dataclass(frozen=True)
class _Slot:
    """Where one estimated quantity lives: a model parameter or a nuisance term of one record.

    ``name`` is the estimate's name (``bias_q[rec]`` for a record's term in a
    fit of several records), ``base`` the parameter's own (``bias_q``),
    ``role`` what it is, ``record`` the record's index (-1 for the shared model
    parameters) and ``index`` its place among the base names of its role
    (:func:`_nuisance_base`; -1 for model parameters).
    """

    name: str
    base: str
    role: Role
    record: int = -1
    index: int = -1


class Problem:
    """A fit set up: data, model, free parameters and nuisance terms.

    Built by :func:`prepare`; :func:`fit` iterates on it.  It evaluates
    predictions, residuals and sensitivities as array operations over all
    frequencies, outputs and (for nuisance terms) parameters at once.

    Parameters
    ----------
    data : list of FrequencyData
        The records' spectra.
    model : Model
        The model, its free parameters set.
    outputs : tuple of int
        Indices of the fitted outputs in the model's rows (``model.outputs``,
        alpha, q, a_z first; :attr:`rows`).
    boundary : {"estimated", "measured", "none"}
        The boundary terms (see :func:`fit`).
    sensitivity : {"analytic", "fd", "central"}
        How the sensitivities are computed (see :func:`fit`).
    state_biases : bool, optional
        Estimate the state-equation biases per record.
    input_bias : bool, optional
        Estimate the elevator offset per record.
    input_edges : {"none", "estimated"}, optional
        The timing of the elevator's steps between two samples, per record (section 7a):
        not estimated, or each estimated.
    """

    def __init__(
        self,
        data: list[FrequencyData],
        model: Model,
        outputs: tuple[int, ...],
        boundary: str,
        sensitivity: str,
        state_biases: bool = False,
        input_bias: bool = False,
        input_edges: str = "none",
    ):
        self.data = data
        self.model = model
        #: The model's output rows, which the spectra's columns and the predictions follow.
        self.rows = tuple(model.outputs)
        self.out_idx = np.array(outputs)
        self.boundary = boundary
        self.sensitivity = sensitivity
        multi = len(data) > 1
        slots = [_Slot(name, name, model.parameters[name].role) for name in model.parameters.free_model_names]
        bases = _nuisance_base(self.rows)
        # the step edges' elevator spectra per second of timing (section 7a), as the mode asks
        self._edges = [edge_basis(d.omega, d.edges, d.edge_steps, input_edges) for d in data]
        for r, d in enumerate(data):
            suffix = f"[{d.name}]" if multi else ""
            places = [(Role.OUTPUT_BIAS, k) for k in outputs if model.parameters[bases[Role.OUTPUT_BIAS][k]].free]
            places += [(Role.BOUNDARY, j) for j in range(len(bases[Role.BOUNDARY])) if boundary == "estimated"]
            places += [(Role.STATE_BIAS, j) for j in range(len(STATE_BIAS_NAMES)) if state_biases]
            places += [(Role.INPUT_BIAS, 0)] if input_bias else []
            places += [(Role.INPUT_EDGE, j) for j in range(self._edges[r].shape[1])]
            edge_base = edge_names(self._edges[r].shape[1])
            for role, j in places:
                base = edge_base[j] if role is Role.INPUT_EDGE else bases[role][j]
                slots.append(_Slot(base + suffix, base, role, r, j))
        self.state_biases = state_biases
        self.input_bias = input_bias
        self.input_edges = input_edges
        self.slots = slots
        self.names = tuple(s.name for s in slots)
        self.model_slots = [i for i, s in enumerate(slots) if not s.role.nuisance]
        # per record: the nuisance slots and their places in the measurement model's nuisance vector
        self._nu = []
        for r in range(len(data)):
            own = [i for i, s in enumerate(slots) if s.record == r]
            names = nuisance_names(self.rows) + edge_names(self._edges[r].shape[1])
            cols = [names.index(slots[i].base) for i in own]
            self._nu.append((np.array(own, int), np.array(cols, int)))
        self._shift = [end_shift(d.omega, d.T) for d in data]  # exp(-j w T) of each record
        # (model, fixed nuisance values per record): see _nuisance
        self._eta0: tuple[Model | None, list[np.ndarray]] = (None, [])
        self.N = sum(d.m for d in data)
        self._offsets = np.cumsum([0] + [d.m for d in data])  # first row of each record
        self._all_outputs = list(outputs) == list(range(len(self.rows)))
        self.n_out = len(outputs)
        self._steps: dict = {}

    @property
    def outputs(self) -> tuple[str, ...]:
        """The fitted outputs' names, in the fit's order."""
        return tuple(self.rows[k] for k in self.out_idx)

    # --- parameter vector ------------------------------------------------------------

    def initial(self) -> np.ndarray:
        """Start vector: model values, measured boundary values, model biases.

        Returns
        -------
        numpy.ndarray
            One value per slot, in its unit, shape (p,).
        """
        p = self.model.parameters.values
        out = []
        for s in self.slots:
            if not s.role.nuisance or s.role is Role.OUTPUT_BIAS:
                out.append(p[s.base])
            elif s.role in (Role.STATE_BIAS, Role.INPUT_BIAS, Role.INPUT_EDGE):
                out.append(0.0)
            else:
                d = self.data[s.record]
                nb = d.x0.size
                out.append((d.x0 if s.index < nb else d.xT)[s.index % nb])
        return np.array(out, dtype=float)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds per slot.

        Returns
        -------
        lower : numpy.ndarray
            Lower bounds, shape (p,); -inf for none.
        upper : numpy.ndarray
            Upper bounds, shape (p,); inf for none.
        """
        lo, hi = np.full(len(self.slots), -math.inf), np.full(len(self.slots), math.inf)
        for i, s in enumerate(self.slots):
            if not s.role.nuisance:
                par = self.model.parameters[s.name]
                lo[i], hi[i] = par.lower, par.upper
            elif s.role is Role.INPUT_EDGE:  # the step happened within its sample interval
                hi[i] = 0.5 * self.data[s.record].dt
                lo[i] = -hi[i]
        return lo, hi

    def model_values(self, theta: np.ndarray) -> dict[str, float]:
        """The model's parameter values with the model entries of ``theta`` in place.

        Parameters
        ----------
        theta : numpy.ndarray
            Values of every slot (:attr:`names`), each in its unit, shape (p,).

        Returns
        -------
        dict of str to float
            Every model parameter's value, by name.
        """
        vals = self.model.parameters.values
        for i in self.model_slots:
            vals[self.slots[i].name] = float(theta[i])
        return vals

    def _nuisance(self, theta: np.ndarray, r: int) -> Nuisance:
        """Nuisance values of record r: estimates from theta, else the model's biases and measured x(0), x(T)."""
        if self._eta0[0] is not self.model:  # nuisance_names order; the model's biases (it may be swapped)
            b = self.model.biases()
            self._eta0 = (self.model, [np.concatenate([b, d.x0, d.xT, np.zeros(3 + d.edges.size)]) for d in self.data])
        own, cols = self._nu[r]
        eta = self._eta0[1][r].copy()
        eta[cols] = theta[own]
        return Nuisance.from_vector(
            eta,
            boundary=self.boundary != "none",
            state_biases=self.state_biases,
            input_bias=self.input_bias,
            rows=self.rows,
            edges=self._edges[r].shape[1],
        )

    # --- predictions ---------------------------------------------------------------------
    def _responses(self, vals: Mapping[str, float]):
        return [self.model.evaluate(d.omega, vals) for d in self.data]

    def predict(self, theta: np.ndarray, responses=None) -> list[np.ndarray]:
        """Predicted output spectra per record, shape (m_r, n_y) (all the model's rows).

        Parameters
        ----------
        theta : numpy.ndarray
            Values of every slot (:attr:`names`), each in its unit, shape (p,).
        responses : list of ModelResponse, optional
            The model's response per record at ``theta`` when already computed.

        Returns
        -------
        list of numpy.ndarray
            Complex spectra of alpha (rad s), q (rad), a_z (g s), ... per record, shape (m_r, n_y).
        """
        if responses is None:
            responses = self._responses(self.model_values(theta))
        return [self._measured(theta, r, resp, biases=True) for r, resp in enumerate(responses)]

    def linear_predict(self, theta: np.ndarray, r: int, change) -> np.ndarray:
        """The change of record ``r``'s predicted outputs for a change of the model response.

        Without the output biases y is linear in (G, H, P) (Eqs. 18-19 with section 7's
        boundary terms at ``theta``), so this is ``dy`` for ``change`` = (dG, dH, dP), any
        object with ``G``, ``H``, ``P`` whose leading axes (one per parameter, say)
        broadcast; shape (..., m_r, n_y), all the model's rows.

        Parameters
        ----------
        theta : numpy.ndarray
            Values of every slot (:attr:`names`), each in its unit, shape (p,).
        r : int
            The record.
        change : object
            The change (dG, dH, dP) as attributes ``G``, ``H``, ``P`` (e.g. a :class:`ModelResponse`).

        Returns
        -------
        numpy.ndarray
            The change of the predicted outputs, complex, shape (..., m_r, n_y).
        """
        return self._measured(theta, r, change, biases=False)

    def _measured(self, theta: np.ndarray, r: int, response, biases: bool) -> np.ndarray:
        """Record r's outputs from the model's ``response`` (Eqs. 18-19 with section 7's boundary terms at
        ``theta``), with the output biases when ``biases``."""
        d, nu = self.data[r], self._nuisance(theta, r)
        bias = nu.biases if biases else None
        return _measure(
            response, d.u, d.ones, nu.boundary(self._shift[r]), bias, nu.state_biases, self._elevator(nu, r)
        )

    def _elevator(self, nu: Nuisance, r: int) -> np.ndarray | None:
        """What record r's nuisance terms add to its elevator spectrum (offset, step edges' timing)."""
        return nu.elevator(self.data[r].ones, self._edges[r])

    def _forcing(self, nu: Nuisance, r: int):
        """Record r's inputs u (the elevator offset added), boundary vector d and state forcing f 1(w).

        The linear part of the measurement model (:func:`fdml.models.measurement.predict`
        without output biases) is ``G u + H d + P f 1 + G_de b_de 1 = C M^-1 (B u' + E d + f 1)``
        with ``u' = u + b_de 1 e_de``: the forcing of :meth:`Model.forced_sensitivity`.
        """
        d = self.data[r]
        u = d.u
        extra = self._elevator(nu, r)
        if extra is not None:
            u = u.copy()
            u[:, 0] += extra
        f = None if nu.state_biases is None else d.ones[:, None] * nu.state_biases[None, :]
        return u, nu.boundary(self._shift[r]), f

    def residuals(self, theta: np.ndarray, responses=None) -> np.ndarray:
        """Stacked residuals v = z - y over records, selected outputs, shape (N, n_out).

        Parameters
        ----------
        theta : numpy.ndarray
            Values of every slot (:attr:`names`), each in its unit, shape (p,).
        responses : list of ModelResponse, optional
            The model's response per record at ``theta`` when already computed.

        Returns
        -------
        numpy.ndarray
            The residuals, complex, shape (N, n_out).
        """
        ys = self.predict(theta, responses)
        return np.concatenate([(d.z - y)[:, self.out_idx] for d, y in zip(self.data, ys)])

    def sensitivities(
        self, theta: np.ndarray, y0: list[np.ndarray] | None = None, tol: float = SETTINGS.settle_tol
    ) -> np.ndarray:
        """The sensitivities dy/dtheta, shape (N, n_out, p): Eq. 26 for model parameters, exact for nuisances.

        Parameters
        ----------
        theta : numpy.ndarray
            Values of every slot (:attr:`names`), each in its unit, shape (p,).
        y0 : list of numpy.ndarray, optional
            Predictions at ``theta`` (:meth:`predict`) when already computed.
        tol : float, optional
            Relative change at which finite-difference columns count as settled.

        Returns
        -------
        numpy.ndarray
            The sensitivities, complex, shape (N, n_out, p).
        """
        p = len(self.slots)
        A = np.zeros((self.N, self.n_out, p), complex)
        offs = self._offsets
        vals = self.model_values(theta)
        if self.sensitivity == "analytic":
            mnames = [self.slots[i].name for i in self.model_slots]
            responses = []
            pm = len(mnames)  # the model's slots come first (Problem.__init__)
            for r, d in enumerate(self.data):
                forcing = self._forcing(self._nuisance(theta, r), r)
                resp, dy = self.model.forced_sensitivity(d.omega, vals, mnames, *forcing)
                responses.append(resp)
                A[offs[r] : offs[r + 1], :, :pm] = np.moveaxis(self._fitted(dy, -1), 0, -1)
        else:
            responses = self._responses(vals)
            if y0 is None:
                y0 = self.predict(theta, responses)
            y0s = np.concatenate([y[:, self.out_idx] for y in y0])
            lo, hi = self.bounds()
            for i in self.model_slots:
                A[:, :, i] = self._fd_column(theta, i, y0s, lo[i], hi[i], tol)
        for r, d in enumerate(self.data):
            own, cols = self._nu[r]
            if own.size:  # exact: every nuisance value enters linearly
                C = self._fitted(nuisance_columns(responses[r], self._shift[r], d.ones, self._edges[r]), 1)
                A[offs[r] : offs[r + 1], :, own[0] : own[-1] + 1] = C[:, :, cols]  # a record's slots are adjacent
        return A

    def _fitted(self, y: np.ndarray, axis: int) -> np.ndarray:
        """The fitted outputs of ``y``, whose ``axis`` runs over all the model's rows."""
        return y if self._all_outputs else np.take(y, self.out_idx, axis=axis)

    def _eval_moved(self, theta: np.ndarray, i: int, h: float) -> np.ndarray:
        """The fitted outputs' predictions, stacked over records, with slot ``i`` moved by ``h``."""
        t = theta.copy()
        t[i] += h
        return np.concatenate([y[:, self.out_idx] for y in self.predict(t)])

    def _fd_column(self, theta, i, y0s, lo, hi, tol=SETTINGS.settle_tol) -> np.ndarray:
        """Eq. 26 with step reduction until the sensitivity settles to ``tol``.

        Forward differences err by O(h) (truncation) and O(eps/h) (rounding):
        the halving stops when successive columns agree to ``tol`` or when the
        change starts to grow again (rounding has taken over), keeping the
        column with the smallest change.
        """
        name = self.slots[i].name
        scale = max(abs(theta[i]), 1e-3)
        h = SETTINGS.fd_start * scale  # docs/theory.md 7: start at 5 % of |theta|
        if tol >= SETTINGS.settle_tol:
            h = self._steps.get(name, h)
        if self.sensitivity == "central":
            h = SETTINGS.central_step * scale
            return (self._eval_moved(theta, i, h) - self._eval_moved(theta, i, -h)) / (2 * h)

        def column(step):
            step = step if theta[i] + step <= hi else -step  # stay inside the bounds
            if tol < SETTINGS.settle_tol and theta[i] - step >= lo:
                # final covariance: central differences, O(h^2), settle far below Eq. 26's 1e-4
                return (self._eval_moved(theta, i, step) - self._eval_moved(theta, i, -step)) / (2 * step)
            return (self._eval_moved(theta, i, step) - y0s) / step

        prev = column(h)
        best, best_change, best_h = prev, math.inf, h
        for _ in range(SETTINGS.fd_max_halvings):
            h *= 0.5
            cur = column(h)
            denom = np.linalg.norm(cur)
            change = float(np.linalg.norm(cur - prev) / denom) if denom > 0 else 0.0
            if change < best_change:
                best, best_change, best_h = cur, change, h
            if change <= tol or change > 4 * best_change:
                break
            prev = cur
        if tol >= SETTINGS.settle_tol:
            self._steps[name] = 2.0 * best_h  # next pass starts one halving above the settled step
        return best


def _as_data(data, model: Model, opts: FitOptions) -> list[FrequencyData]:
    items = data if isinstance(data, (list, tuple)) else [data]
    if not items:
        raise RecordError("no records were given to fit")
    given = {k: v for k, v in opts.pick(SPECTRA).items() if v is not None and k != "omega"}
    out = []
    for i, item in enumerate(items):
        if isinstance(item, Record):
            item = spectra(item, opts.omega, outputs=model.outputs, **given)
        elif not isinstance(item, FrequencyData):
            raise RecordError(f"cannot fit a {type(item).__name__}: give an fdml Record or FrequencyData")
        elif tuple(item.outputs) != tuple(model.outputs):
            raise RecordError(
                f"spectra {item.name!r} hold {', '.join(item.outputs)}, the fit needs {', '.join(model.outputs)}: "
                "transform the record with fdml.spectra(record, outputs=...)"
            )
        else:
            opts.refuse_inapplicable(item, i)  # a band (trim, ...) given with spectra made otherwise
        if model.gust and "alpha_w" not in item.inputs:
            raise RecordError(
                f"record {item.name!r} has no alpha_w column but the model has a gust input; "
                "fit without --gust (Python: a model without gust=True) or supply the measured gust angle"
            )
        if not model.gust and item.u.shape[1] > 1:
            item = replace(item, u=item.u[:, :1], inputs=("de",))
        out.append(item)
    _refuse_duplicates(out)
    names = [d.name for d in out]
    if len(set(names)) != len(names):
        out = [replace(d, name=f"{d.name}#{i}") for i, d in enumerate(out)]
    return out


def _sample_keys(d: FrequencyData) -> set:
    """Fingerprints of what a fit sees: the time samples (when the record is known) and the spectra."""
    import hashlib

    def digest(tag, *arrays):
        h = hashlib.sha256(tag.encode())
        for a in arrays:
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()

    keys = {digest("spectra", d.omega, d.z, d.u)}
    rec = d.record
    if rec is not None:  # the samples and the interval; a shift of the time origin changes nothing
        names = sorted(rec.signals)
        keys.add(digest(f"samples {rec.n} {rec.dt:.12g} {','.join(names)}", *(rec.signals[k] for k in names)))
    return keys


def _refuse_duplicates(items: list[FrequencyData]) -> None:
    """Refuse the same record given twice: it counts the same noise twice, so the standard errors
    shrink by sqrt(2) for no information."""
    seen: dict[str, int] = {}
    for i, d in enumerate(items):
        keys = _sample_keys(d)
        j = next((seen[k] for k in keys if k in seen), None)
        if j is not None:
            first, second = (_label(x) for x in (items[j], d))
            raise RecordError(
                f"records {j + 1} ({first}) and {i + 1} ({second}) have the same samples: the same "
                "record given twice would shrink the standard errors by sqrt(2); give it once"
            )
        seen.update(dict.fromkeys(keys, i))


def _label(d: FrequencyData) -> str:
    src = (d.record.meta.get("source") if d.record is not None else None) or d.meta.get("source")
    return f"{d.name!r}, {src}" if src else repr(d.name)


def _configure_model(model: Model, opts: FitOptions, biases: bool, out_idx) -> Model:
    params = model.parameters
    if biases:
        params = params.free([f"bias_{model.outputs[k]}" for k in out_idx])
    if opts.fix:
        params.check_names(list(opts.fix))
        params = params.fix(dict(opts.fix) if isinstance(opts.fix, Mapping) else list(opts.fix))
    if opts.free:
        params.check_names(list(opts.free))
        params = params.free(list(opts.free))
    for name, (lo, hi) in opts.bounds.items():
        params.check_names([name])
        params = params.bound(name, -math.inf if lo is None else lo, math.inf if hi is None else hi)
    return model.with_parameters(params)


@takes_options(SPECTRA, PROBLEM)
def prepare(data, model: Model, options: FitOptions | None = None, **keywords) -> Problem:
    """Set up a fit without running it (see :func:`fit`).

    Parameters
    ----------
    data : Record, FrequencyData or list of them
        The records.
    model : Model
        The model; its free parameters are estimated.
    options : FitOptions, optional
        Options made before (those of the iteration and the checks are not used here); the
        keywords below replace its fields.
    <the fit options: FitOptions' fields>

    Returns
    -------
    Problem
        The fit, set up.
    """
    unused = sorted(set(keywords) & set(FitOptions.names(ITERATION, CHECKS)))
    if unused:
        raise FdmlError(f"prepare does not take the fit option(s) {unused}: give them to fit")
    opts = FitOptions.of(options, **keywords)
    if not isinstance(model, Model):
        raise ParameterError(f"model must be an fdml Model, got {type(model).__name__}")
    model = model.with_outputs(opts.outputs)  # the rows the spectra and the predictions follow
    out_idx = tuple(model.outputs.index(o) for o in opts.outputs)
    fdata = _as_data(data, model, opts)
    _refuse_unexcited(fdata)
    biases = any(d.trim_mode != "none" for d in fdata) if opts.biases == "auto" else bool(opts.biases)
    # an integral output's bias is its own boundary values' (b 1(w) = (b - b e^{-jwT})/(jw)): estimated with them
    own = set(boundary_channels(model.outputs)) - set(STATES) if opts.boundary == "estimated" else set()
    model = _configure_model(model, opts, biases, [k for k in out_idx if model.outputs[k] not in own])
    _check_model_effects(model, list(opts.outputs), fdata[0].omega)  # H1: effects vs outputs
    sensitivity = opts.sensitivity
    if sensitivity == "auto":
        # analytic where every free model parameter has a closed form, else Eq. 26
        closed: frozenset = getattr(model, "closed_form_parameters", frozenset())
        sensitivity = "analytic" if all(n in closed for n in model.parameters.free_model_names) else "fd"
    prob = Problem(
        fdata,
        model,
        out_idx,
        opts.boundary,
        sensitivity,
        opts.state_biases,
        opts.input_bias,
        "none" if opts.input_edges == "auto" else opts.input_edges,
    )
    p = len(prob.slots)
    if p == 0:
        raise ParameterError("no free parameters: nothing to estimate")
    # 2 real numbers per output and independent frequency; fewer than p cannot identify theta
    n_indep = sum(d.independent_frequencies() for d in fdata) * 2 * len(out_idx)
    if n_indep < p:
        raise BandError(
            f"the band carries about {n_indep:.0f} independent real data (record length x band width) "
            f"for {p} free parameters: lengthen the record or widen the band"
        )
    return prob


def _refuse_unexcited(fdata: list[FrequencyData]) -> None:
    """Refuse a record whose inputs carry no power in the band (fdml.quality's measure, as ``fdml check``).

    Without input power the input derivatives are unidentifiable and the
    iterations run away (Cm_de = -2.9e137 on a constant elevator).
    """
    from .quality import LOW_INPUT_DB, unexcited

    for d in fdata:
        if d.record is not None:
            dead = all(unexcited(d.record[k], d.record.dt, d.omega) for k in d.inputs)
        else:  # spectra given without their record: only an input that is exactly zero is known dead
            dead = not np.any(d.u)
        if dead:
            names = " and ".join("elevator" if k == "de" else k for k in (d.inputs or ("de",)))
            raise RecordError(
                f"record {d.name!r}: the {names} carr{'y' if ' and ' in names else 'ies'} no power in the band "
                f"{d.omega[0]:g}-{d.omega[-1]:g} rad/s (never moving, or more than {LOW_INPUT_DB:g} dB below "
                "its peak throughout): nothing to identify; see fdml check"
            )


def _check_model_effects(model: Model, outputs, omega) -> None:
    """Refuse effects on channels the fit lacks, or not identifiable with these outputs (one line)."""
    from .models.effects import check_effects, confounded_effect_parameters

    check_effects(model, outputs)
    bad = confounded_effect_parameters(model, omega, outputs)
    if bad:
        key, name, _ = bad[0]
        raise ParameterError(
            f"effect {key}: {name} is not identifiable with outputs {','.join(outputs)} (any value is matched "
            f"by the other free parameters); add a channel that separates it (e.g. az) or fix {name}"
        )


def _end_findings(prob: Problem) -> list:
    """Records that end far from trim while boundary='none' (docs/theory.md section 7)."""
    from .findings import Finding

    out = []
    if prob.boundary == "none":
        for d in prob.data:
            far = [prob.rows[k] for k in (0, 1) if d.end_offset[k] > SETTINGS.end_offset_warn]
            if far:
                out.append(
                    Finding(
                        "boundary.truncated",
                        f"the record ends far from trim in {', '.join(far)} ({100 * max(d.end_offset[:2]):.0f} % of "
                        "the peak) and boundary 'none': the transform sees a truncated response; use "
                        "--boundary estimated or measured (Python: boundary=)",
                        kind="estimation",
                        record=d.name,
                        value=float(max(d.end_offset[:2])),
                        expected=SETTINGS.end_offset_warn,
                    )
                )
    return out


def _band_mean(fn: Callable[[np.ndarray], float], R: np.ndarray, rows: np.ndarray | None) -> float:
    """``fn(R)``; for band-wise R_b (``rows``: band of each residual row), (1/N) sum_b N_b fn(R_b)."""
    if rows is None:
        return fn(R)
    counts = np.bincount(rows, minlength=R.shape[0])
    return sum(float(c) * fn(Rb) for c, Rb in zip(counts, R) if c) / rows.size


def _logdet(R: np.ndarray, rows: np.ndarray | None = None) -> float:
    """ln det R (Eq. 25); for band-wise R_b (``rows``: band of each residual row), (1/N) sum_b N_b ln det R_b."""
    if rows is not None:
        return _band_mean(_logdet, R, rows)
    sign, ld = np.linalg.slogdet(R)
    if sign == 0 or not np.isfinite(ld):
        raise FdmlError("the residual covariance R is singular: an output is fitted exactly or is all zero")
    return float(ld)


def _cov_R(V: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """Eq. 24 over all rows, shape (n, n); with ``rows`` (band of each row), R_b per band, shape (nb, n, n)."""
    if rows is not None:
        return np.stack(
            [_cov_R(V[rows == b]) if np.any(rows == b) else np.eye(V.shape[1]) for b in range(int(rows.max()) + 1)]
        )
    # Eq. 24: R_jk = (1/N) sum_i v_ij conj(v_ik) (docs/theory.md 7, conjugation convention)
    R = V.T @ V.conj() / V.shape[0]
    diag = R.reshape(-1)[:: R.shape[0] + 1]  # a view of the diagonal
    floor = SETTINGS.r_floor * float(diag.real.max())
    if floor > 0:
        diag += floor
    return R


def _weights(R: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """R^-1, shape (n, n); band-wise, R_b^-1 of each residual row, shape (N, n, n)."""
    return np.linalg.inv(R) if rows is None else np.linalg.inv(R)[rows]


def _grad_hess(A: np.ndarray, V: np.ndarray, R: np.ndarray, full: bool, rows: np.ndarray | None = None):
    """Gradient and Gauss-Newton Hessian of ln det R(theta) (band-wise: of (1/N) sum_b N_b ln det R_b).

    With residual rows v_n and A_n = dy_n/dtheta (so dv = -A dtheta):
    g = -(2/N) Re sum A^H R^-1 v (the Eq. 23 right-hand side), H1 = (2/N) Re
    sum A^H R^-1 A (Eq. 23's matrix), and, for the concentrated likelihood,
    H = H1 - sum_b (N_b/N) tr(R_b^-1 dR_bk R_b^-1 dR_bl) with dR_bk = -(1/N_b)
    sum_{n in b} (a_k v^H + v a_k^H).  Each R_b is taken out by its Cholesky
    factor R_b = L L^H: with a~ = L^-1 a and w = L^-1 v every sum above is a
    plain product of the whitened rows, and the trace is tr(D_k D_l) with the
    Hermitian D_k = L^-1 dR_k L^-H = -(1/N_b) sum (a~_k w^H + w a~_k^H).
    """
    N, no, p = A.shape
    bands = [(slice(None), R)] if rows is None else [(rows == b, Rb) for b, Rb in enumerate(R) if np.any(rows == b)]
    Ar = np.empty((2, no, N, p))  # whitened sensitivities, real and imaginary parts
    Vr = np.empty((2, no, N))
    H2 = np.zeros((p, p))
    for sel, Rb in bands:
        Li = np.linalg.inv(np.linalg.cholesky(Rb))
        Aw = (Li @ A[sel].transpose(1, 0, 2).reshape(no, -1)).reshape(no, -1, p)
        Vw = Li @ V[sel].T  # (no, N_b)
        Ar[0][:, sel], Ar[1][:, sel], Vr[0][:, sel], Vr[1][:, sel] = Aw.real, Aw.imag, Vw.real, Vw.imag
        if full:
            Nb = Vw.shape[1]
            S = (np.transpose(Aw, (2, 0, 1)).reshape(p * no, Nb) @ Vw.conj().T).reshape(p, no, no)
            X = (-(S + np.conj(np.transpose(S, (0, 2, 1)))) / Nb).reshape(p, no * no)  # D_k, flattened
            H2 += (Nb / N) * np.real(X @ X.conj().T)
    Ar2 = Ar.reshape(-1, p)  # Re(a^H b) = a_r . b_r + a_i . b_i
    H1 = (2.0 / N) * (Ar2.T @ Ar2)
    g = -(2.0 / N) * (Ar2.T @ Vr.reshape(-1))
    if not full:
        return g, H1, H1
    Hc = H1 - H2
    return g, H1, 0.5 * (Hc + Hc.T)


def _solve(H: np.ndarray, g: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Solve H d = -g on the active (unconstrained) set with a scaled pseudo-inverse."""
    d = np.zeros_like(g)
    idx = np.flatnonzero(active)
    if idx.size == 0:
        return d
    Hs = H[np.ix_(idx, idx)]
    D = np.sqrt(np.maximum(np.abs(np.diag(Hs)), 1e-300))
    Hn = Hs / np.outer(D, D)
    d[idx] = -np.linalg.lstsq(Hn, g[idx] / D, rcond=1e-12)[0] / D
    return d


def _project(theta, lo, hi):
    return np.minimum(np.maximum(theta, lo), hi)


def _identifiability(H1: np.ndarray, names: Sequence[str]) -> tuple[list[str], list[str]]:
    """Warnings for a singular information matrix; returns (messages, unidentified names)."""
    diag = np.diag(H1)
    dead = [n for n, h in zip(names, diag) if h <= 0]
    msgs = [f"parameter {n} has no effect on the fitted outputs in this band: it cannot be identified" for n in dead]
    live = np.flatnonzero(diag > 0)
    if live.size:
        D = np.sqrt(diag[live])
        Hn = H1[np.ix_(live, live)] / np.outer(D, D)
        w, U = np.linalg.eigh(Hn)
        for k in np.flatnonzero(w < SETTINGS.singular_eig * max(w.max(), 1e-300)):
            comp = np.abs(U[:, k])
            top = [names[live[j]] for j in np.argsort(comp)[::-1][:3] if comp[j] > 0.2]
            msgs.append(
                "the information matrix is singular: the combination of "
                f"{', '.join(top)} is not identifiable from these data"
            )
            dead.extend(t for t in top if t not in dead)
    return msgs, dead


@takes_options()
def fit(
    data,
    model: Model,
    options: FitOptions | None = None,
    *,
    callback: Callable[[IterationInfo], bool | None] | None = None,
    **keywords,
) -> FitResult:
    """Fit a model to one or more records by frequency-domain maximum likelihood.

    The options are the fields of :class:`~fdml.fit_options.FitOptions`: given by name
    (``fit(record, model, band="0.5:8")``), or made once and passed on
    (``fit(record, model, opts)``; names given beside it replace its fields).

    Parameters
    ----------
    data : Record, FrequencyData or list of them
        Several records are fitted together with shared model parameters and
        per-record nuisance terms (boundary values, output biases).
    model : Model
        From :func:`fdml.models.make_model`; its free parameters are estimated
        from their current values.
    options : FitOptions, optional
        Options made before; the keywords below replace its fields.
    <the fit options: FitOptions' fields>
    callback : callable, optional
        Called after every iteration with an :class:`IterationInfo`; return
        True to stop the fit cleanly (the result says so).

    Returns
    -------
    FitResult
        With every warning raised during the fit in ``warnings`` (each also
        raised as usual) and every option, as resolved, in ``options``.
    """
    opts = FitOptions.of(options, **keywords)
    with recording() as log:  # fdml.warning_log: every warning of the fit is kept in its result
        res, prob = _fit(data, model, opts, callback)
    return replace(res, warnings=tuple(log))


def _stored_options(opts: FitOptions, prob: Problem) -> dict:
    """The options of a fit as plain data for :attr:`FitResult.options` (``auto`` choices as resolved)."""
    biases = any(s.role is Role.OUTPUT_BIAS for s in prob.slots)
    out = opts.resolved(prob.data, biases=biases, sensitivity=prob.sensitivity).to_dict()
    out["input_edges"] = prob.input_edges  # "auto" as its score test decided
    if opts.cov_type != "naive":  # how white noise reached the covariance, per record
        out["noise_covariance"] = _noise_routes(prob)
    return out


def _fit(data, model: Model, opts: FitOptions, callback) -> tuple[FitResult, Problem]:
    """:func:`fit` after its options are checked: the result (without its warnings) and the problem."""
    t_start = time.perf_counter()
    prob = prepare(data, model, opts)
    found = (_data_findings(prob, opts.strict) if opts.check else []) + _end_findings(prob)
    emit(found, stacklevel=3)
    state = _iterate(prob, prob.initial(), opts, callback)
    if opts.input_edges == "auto" and state.converged:
        edged = _edges_needed(prob, state)
        if edged is not None:  # section 7a: the steps' timing is significant; go on with it estimated
            start = _carried(prob, state.theta, edged)
            prob, state = edged, replace(_iterate(edged, start, opts, callback), prior=state.history)
    res = _finish(prob, state, opts.cov_type, time.perf_counter() - t_start, _stored_options(opts, prob))
    found += _band_findings(prob, state.theta)
    res = replace(res, findings=tuple(found)) if found else res
    if opts.adequacy and state.converged:
        res = _with_adequacy(prob, res, state.V, state.A, opts)
    return res, prob


@dataclass(frozen=True)
class _State:
    """Where the iteration of :func:`_iterate` ended."""

    theta: np.ndarray
    V: np.ndarray
    R: np.ndarray
    rows: np.ndarray | None
    history: list
    it: int
    converged: bool
    stopped: bool
    message: str
    A: np.ndarray | None
    prior: list = field(default_factory=list)  # costs of an earlier problem (auto edges)


def _iterate(prob: Problem, theta: np.ndarray, opts: FitOptions, callback) -> _State:
    """The Levenberg-Marquardt (or Gauss-Newton) passes on ln det R from ``theta`` until a stop rule holds."""
    method, stop, tol = opts.method, opts.stop, opts.tol
    lo, hi = prob.bounds()
    theta = _project(theta, lo, hi)
    full = method == "lm"
    V = prob.residuals(theta)
    rows = opts.noise.rows(prob)  # band of each residual row (None: white)
    R = _cov_R(V, rows)
    J = _logdet(R, rows)
    history = [math.exp(J)]
    converged, stopped = False, False
    A_final = None
    message = "maximum number of iterations reached"
    it = 0
    rel_prev = math.inf
    radius = math.inf  # the trust region of the Levenberg-Marquardt steps (scaled metric)
    for it in range(1, opts.max_iter + 1):
        # Eq. 26 columns settled to 1e-4 while far from the optimum; near it, tight central
        # differences, so the fixed point (and the bounds) match the analytic sensitivities
        tight = prob.sensitivity == "fd" and rel_prev < SETTINGS.tight_below
        A = prob.sensitivities(theta, tol=SETTINGS.settle_tol_final if tight else SETTINGS.settle_tol)
        g, H1, H = _grad_hess(A, V, R, full, rows)
        at_lo = (theta <= lo) & (g > 0)
        at_hi = (theta >= hi) & (g < 0)
        active = ~(at_lo | at_hi)
        # standard errors for the step test: naive CRB (N H1)^-1
        sig = _naive_sigma(prob.N * H1)
        step_n, eig = _proposal(g, H1, H, active, full)
        rel_step = np.max(np.abs(step_n) / np.where(sig > 0, sig, np.inf)) if step_n.size else 0.0
        if stop == "converge" and rel_step < tol and (prob.sensitivity != "fd" or tight):
            # theta is within tol standard errors of the optimum: stop without the step,
            # so the sensitivities just computed serve the covariance too
            converged = True
            it -= 1  # this pass only confirmed convergence: it took no step
            message = f"converged: every step below {tol:g} standard errors after {it} iterations"
            A_final = A
            break
        rel_prev = rel_step
        J_old = J
        if full:
            accepted, t_new, V_new, R_new, J_new, radius = _hybrid_step(
                prob, theta, g, H1, J, active, lo, hi, rows, eig, radius, _logdet_rounding(R, rows)
            )
        else:
            accepted, t_new, V_new, R_new, J_new = _halving_step(
                prob, theta, step_n, lo, hi, J, rows, SETTINGS.gn_max_halvings
            )
        if accepted:
            theta, V, R, J = t_new, V_new, R_new, J_new
        history.append(math.exp(J))
        if callback is not None and callback(
            IterationInfo(
                iteration=it,
                cost=math.exp(J),
                params=dict(zip(prob.names, theta.tolist())),
                step_in_stderr=float(rel_step),
            )
        ):
            stopped = True
            message = f"stopped by the callback after {it} iterations"
            break
        floor = "" if accepted else _floor_reached(R, rows, history, _least_resolved(g, H1, H, active, step_n, full))
        end = _end_of_pass(stop, accepted, J_old, J, rel_step, tol, it, floor)
        if end is not None:
            converged, message = end
            break
    if not converged and not stopped:
        warnings.warn(f"fit did not converge: {message}", ConvergenceWarning, stacklevel=4)
    return _State(theta, V, R, rows, history, it, converged, stopped, message, A_final)


def _edges_needed(prob: Problem, state: _State) -> Problem | None:
    """The problem with the step edges' timing terms when the steps' timings differ, else None.

    At the fit without them (docs/theory.md section 7a), the Lagrange-multiplier statistic
    ``LM(S) = N g^T H1_S^-1 g / K`` of ln det R's gradient g and Eq. 23's matrix H1 over the fit's
    slots and the columns S (K: the grid's oversampling, as in the adequacy check) is taken for
    every step's timing and for a shift common to all; their difference is chi-squared with one
    degree of freedom fewer than there are steps.  A common shift alone is an elevator delay,
    which an input lag of the model resembles, so it does not count as evidence of steps apart.
    """
    from .tails import chi2_sf

    if sum(d.edges.size for d in prob.data) < 2:  # one step: its timing is the common shift
        return None
    big = Problem(
        prob.data,
        prob.model,
        tuple(prob.out_idx),
        prob.boundary,
        prob.sensitivity,
        prob.state_biases,
        prob.input_bias,
        "estimated",
    )
    A = big.sensitivities(_carried(prob, state.theta, big))
    edge = np.array([s.role is Role.INPUT_EDGE for s in big.slots])
    common = np.concatenate([A[:, :, ~edge], A[:, :, edge].sum(axis=2, keepdims=True)], axis=2)
    oversample = big.N / sum(d.independent_frequencies() for d in big.data)

    def lm(cols: np.ndarray) -> float:
        g, H1, _ = _grad_hess(cols, state.V, state.R, False, state.rows)
        return big.N * float(g @ np.linalg.lstsq(H1, g, rcond=1e-12)[0]) / oversample

    apart = lm(A) - lm(common)
    return big if chi2_sf(apart, int(edge.sum()) - 1) < SETTINGS.edge_level else None


def _carried(prob: Problem, theta: np.ndarray, other: Problem) -> np.ndarray:
    """``other``'s start vector with the values of the slots it shares with ``prob`` taken from ``theta``."""
    shared = dict(zip(prob.names, theta))
    return np.array([shared.get(n, v) for n, v in zip(other.names, other.initial())])


def _band_findings(prob: Problem, theta: np.ndarray) -> list:
    """The ``band.hz`` finding when the band looks like Hz (:mod:`fdml.band_units`), issued as a warning."""
    from .band_units import hz_band_finding

    try:
        found = hz_band_finding(prob.data, prob.model.with_values(prob.model_values(theta)))
    except (FdmlError, np.linalg.LinAlgError):  # a model the check cannot evaluate: nothing to say
        return []
    if found is None:
        return []
    emit([found], stacklevel=4)
    return [found]


def _halving_step(prob, theta, step, lo, hi, J, rows, halvings: int):
    """A Gauss-Newton step, halved while the cost rises: (accepted, theta, V, R, J) as :func:`_try`."""
    accepted, t_new, V_new, R_new, J_new = False, theta, None, None, J
    for _ in range(halvings):
        accepted, t_new, V_new, R_new, J_new = _try(prob, theta, step, lo, hi, J, rows)
        if accepted:
            break
        step = 0.5 * step  # step halving when the cost rises
    return accepted, t_new, V_new, R_new, J_new


def _end_of_pass(
    stop: str, accepted: bool, J_old: float, J: float, rel_step: float, tol: float, it: int, floor: str = ""
):
    """(converged, message) when the iteration ends after this pass's step, else None.

    ``floor``: why det R is at the floating-point floor (:func:`_floor_reached`), or "" when it is not;
    a pass that finds no decrease there has converged.
    """
    if stop == "paper":
        if abs(math.exp(J_old - J) - 1.0) < SETTINGS.paper_rel_change:  # Eq. 25 rule |J_k-1 - J_k| / J_k
            return True, (
                f"paper's rule: relative change of det R below {SETTINGS.paper_rel_change:g} after {it} iterations"
            )
        return None
    if not accepted:
        if rel_step < SETTINGS.stall_factor * tol:
            return True, "converged: no further decrease of det R"
        if floor:
            return True, f"converged at the floating-point floor: {floor}; no step can decrease det R further"
        return False, "stalled: no step decreases det R"
    return None


def _logdet_rounding(R: np.ndarray, rows: np.ndarray | None = None) -> float:
    """The rounding error of ln det R (Eq. 25): eps * lambda_max * tr(R^-1), band-weighted as :func:`_logdet`.

    Rounding R perturbs each eigenvalue by about eps * lambda_max (Weyl), and d ln det R = tr(R^-1 dR):
    a nearly singular R (residuals of the outputs nearly linearly dependent, as on noise-free data)
    makes ln det R uncertain far above eps.
    """
    if rows is not None:
        return _band_mean(_logdet_rounding, R, rows)
    w = np.linalg.eigvalsh(R)
    return float(np.finfo(float).eps * w[-1] * np.sum(1.0 / w)) if w[0] > 0 else math.inf


def _least_resolved(g, H1, H, active, step_n, full: bool) -> float:
    """The decrease of ln det R predicted for the shortest step a failed pass made or would make.

    The Gauss-Newton step halved the pass's last time (first order), or for ``full`` the Newton
    step ``step_n`` (second order, with the concentrated Hessian H) when that is less.
    """
    gn = _solve(H1, g, active) if full else step_n
    halvings = SETTINGS.fallback_halvings if full else SETTINGS.gn_max_halvings
    least = -float(g @ gn) * 0.5 ** (halvings - 1)
    if not full:
        return least
    newton = -float(g @ step_n + 0.5 * step_n @ H @ step_n)  # with an indefinite H, below zero: no decrease
    return min(least, newton) if newton > 0 else least


def _floor_reached(R: np.ndarray, rows, history: list, least: float = math.inf) -> str:
    """Why det R is at the floating-point floor, or "" when it is not (the cost still resolves progress).

    At the floor, for a pass no trial of which lowered the cost, when the rounding error of ln det R
    (:func:`_logdet_rounding`) exceeds the last decrease an accepted step made, or the decrease
    ``least`` predicted for the pass's shortest trial: the iteration had come to where the cost
    cannot tell steps apart.  Before any accepted step, when R is singular to working precision: its
    smallest eigenvalue is the floor of :func:`_cov_R` (``r_floor`` times the largest variance),
    the outputs' residuals being linearly dependent to rounding.
    """
    rounding = _logdet_rounding(R, rows)
    if least <= rounding:
        return (
            f"the decrease of ln det R predicted for the shortest step ({least:.2g}) is below its rounding "
            f"error ({rounding:.2g}; the outputs' residuals are nearly linearly dependent, as on a noise-free "
            "record)"
        )
    drops = -np.diff(np.log(history))
    drops = drops[drops > 0]
    if drops.size:
        if drops[-1] <= rounding:
            return (
                f"the last decrease of ln det R ({drops[-1]:.2g}) is below its rounding error ({rounding:.2g}; "
                "the outputs' residuals are nearly linearly dependent, as on a noise-free record)"
            )
        return ""
    for Rb in R.reshape(-1, *R.shape[-2:]):
        w = np.linalg.eigvalsh(Rb)
        if w[0] <= 2.0 * SETTINGS.r_floor * w[-1]:
            return "R is singular to rounding (the outputs' residuals are linearly dependent, as on noise-free data)"
    return ""


def _with_adequacy(prob, res, V, A_final, opts: FitOptions):
    """The result with its adequacy check (:mod:`fdml.adequacy`; it warns when the check flags anything).

    The check refits the candidates it ranks with the fit's own options on the fit's own spectra.
    """
    from .adequacy import attach

    def refit(model, **changes):
        # closed-form sensitivities where the model has them, else central differences (as the
        # diagnosis's fits): a refit starts near its optimum and needs no settled Eq. 26 columns;
        # within 1e-2 standard errors of its optimum its likelihood ratio is off by about 1e-4
        tol = max(opts.tol, 1e-2)
        refit_opts = FitOptions.of(opts, adequacy=False, check=False, sensitivity="analytic", **{"tol": tol, **changes})
        with recording(reemit=False):  # the refits' warnings belong to them, not to this fit
            return _fit(list(res.spectra), model, refit_opts, None)[0]  # the fit's spectra, frozen once

    # analytic sensitivities at the estimate do not depend on the settling tolerance, so the last ones
    # serve the check too
    A_est = A_final if prob.sensitivity == "analytic" else None
    return attach(prob, res, V, A_est, refit=refit)


def _data_findings(prob: Problem, strict: bool) -> list:
    """The data check on every record the fit was given in the time domain (strict: raise)."""
    from .datacheck import check_data

    U = model_airspeed(prob.model)
    found: list = []
    for d in prob.data:
        if d.record is not None:
            found.extend(check_data(d.record, airspeed=U, data=d).findings)
    raise_if_strict(found, strict)
    return found


def _try(prob, theta, step, lo, hi, J, rows=None):
    t_new = _project(theta + step, lo, hi)
    V_new = prob.residuals(t_new)
    R_new = _cov_R(V_new, rows)
    try:
        J_new = _logdet(R_new, rows)
    except FdmlError:  # an exactly singular R at a trial point: reject the trial
        return False, t_new, V_new, R_new, math.inf
    return J_new <= J + 1e-12 * abs(J), t_new, V_new, R_new, J_new


def _proposal(g, H1, H, active, full):
    """The pass's full step on the active set, and for ``full`` (Levenberg-Marquardt) the scaled eigensystem.

    ``full``: the Newton step on ln det R, ``-H^+ g`` with the pseudo-inverse of
    the concentrated Hessian in the metric of diag H1 (eigenvalues below 1e-12 of
    the largest dropped), from the eigensystem that :func:`_hybrid_step` shifts.
    Otherwise the Gauss-Newton step ``-H1^+ g`` (Eq. 23).
    """
    if not full or not np.all(np.isfinite(H)):
        return _solve(H1, g, active), None
    idx = np.flatnonzero(active)
    eig = _scaled_eig(H1, H, idx)
    step = np.zeros_like(g)
    if idx.size:
        D, w, Q = eig
        inv = np.zeros_like(w)
        keep = np.abs(w) > 1e-12 * np.max(np.abs(w))
        inv[keep] = 1.0 / w[keep]
        step[idx] = -(Q @ ((Q.T @ (g[idx] / D)) * inv)) / D
    return step, eig


def _scaled_eig(H1, H, idx):
    """(D, w, Q): D = sqrt(diag H1) on the active set ``idx`` (1 where not positive), and the
    eigenvalues w and vectors Q of H[idx, idx] / (D D^T)."""
    d1 = np.diag(H1)[idx]
    D = np.sqrt(np.where(d1 > 0, d1, 1.0))
    w, Q = np.linalg.eigh(H[np.ix_(idx, idx)] / np.outer(D, D))
    return D, w, Q


def _hybrid_step(prob, theta, g, H1, J, active, lo, hi, rows=None, eig=None, radius=math.inf, rounding=0.0):
    """One step on ln det R in a trust region: ``(accepted, theta, V, R, J, radius)``.

    Newton with the concentrated Hessian ``Hc`` when it is positive definite
    and its step lies within ``radius`` (in the metric scaled by diag H1).
    Otherwise ``Hc + mu I`` with the shift mu that puts the step on the
    region's edge (:func:`_shifted_step`), which keeps the curvature the
    paper's alternation ignores.  The paper's Gauss-Newton step with R held
    (Eq. 23), with step halving, is the last resort; a step it makes leaves
    the next pass's region unbounded.  Where ``Hc`` is strongly indefinite
    (far from the optimum) the Gauss-Newton step goes first, as it goes
    further; when it finds no decrease, the shifted steps are tried after
    all (Sundowner, q and theta fitted with a q delay: its steps of every
    length raised the cost).  ``eig`` is :func:`_scaled_eig` of ``Hc`` on
    the active set (None: no finite Hc, straight to the last resort).
    """
    idx = np.flatnonzero(active)
    shifted = idx.size > 0 and eig is not None
    strongly = shifted and float(eig[1].min()) <= -SETTINGS.shift_limit * max(float(eig[1].max()), 1e-300)
    if shifted and not strongly:
        done, radius = _shifted_step(prob, theta, g, idx, eig, J, lo, hi, rows, radius, rounding)
        if done is not None:
            return done
    accepted, *rest = _halving_step(prob, theta, _solve(H1, g, active), lo, hi, J, rows, SETTINGS.fallback_halvings)
    if accepted or not strongly:
        return (accepted, *rest, math.inf if accepted else radius)
    done, radius = _shifted_step(prob, theta, g, idx, eig, J, lo, hi, rows, radius, rounding)
    return done if done is not None else (False, *rest, radius)


def _shifted_step(prob, theta, g, idx, eig, J, lo, hi, rows, radius: float, rounding: float) -> tuple:
    """Levenberg-Marquardt trials in the trust region: ``(result, radius)``, ``result`` as :func:`_hybrid_step`'s
    or None when none lowered the cost (``radius`` then the region they shrank to).

    The shift puts the step on the region's edge (Moré and Sorensen's secular equation,
    :func:`_shift_for`), at least the smallest that makes ``Hc`` positive definite.  A trial that does
    not lower the cost shrinks the region to a quarter of its step; the ratio of the actual to the
    quadratic model's decrease sets the next pass's region (Nocedal and Wright, Algorithm 4.1), so a
    pass seldom needs a second trial.  An unbounded step whose predicted decrease is below
    ``rounding`` (the rounding error of ln det R) is not tried: the cost cannot tell the points apart.
    """
    D, w, Q = eig
    c = Q.T @ (g[idx] / D)  # the scaled gradient in the eigenvectors' basis
    top = max(float(w.max()), 1e-300)
    least = 0.0 if w.min() > SETTINGS.singular_eig * top else 2.0 * abs(float(w.min())) + 1e-8 * top
    for _ in range(SETTINGS.shift_tries):
        y = -c / (w + _shift_for(c, w, least, radius))
        size = float(np.linalg.norm(y))
        predicted = -float(c @ y + 0.5 * (w * y) @ y)  # the quadratic model's decrease of ln det R
        if predicted <= rounding:  # a decrease the cost cannot resolve
            if math.isinf(radius):  # even the unbounded step's: the cost cannot tell the points apart
                return (False, theta, None, None, J, radius), radius
            break  # the region has shrunk enough
        step = np.zeros_like(g)
        step[idx] = (Q @ y) / D
        ok, *rest = _try(prob, theta, step, lo, hi, J, rows)
        if ok:
            return (True, *rest, _next_radius((J - rest[3]) / predicted, size, radius)), radius
        radius = 0.25 * size  # the trial did not lower the cost: a quarter of the region
    return None, radius


def _shift_for(c: np.ndarray, w: np.ndarray, least: float, radius: float) -> float:
    """The shift mu >= ``least`` with ``||c / (w + mu)|| <= radius``, on the edge where it binds.

    Newton's method on ``1/||s(mu)|| - 1/radius``, which is concave and
    increasing in mu, converges from below without overshooting (Moré and
    Sorensen 1983); the eigenvalues ``w`` and the rotated gradient ``c`` make
    each iteration a few vector operations.
    """
    mu = least
    for _ in range(30):
        s2 = float(np.sum((c / (w + mu)) ** 2))
        if s2 <= radius * radius * (1.0 + 1e-6):
            break
        size = math.sqrt(s2)
        slope = float(np.sum(c * c / (w + mu) ** 3)) / size**3  # d(1/||s||)/dmu
        mu += (1.0 / radius - 1.0 / size) / slope
    return mu


def _next_radius(ratio: float, size: float, radius: float) -> float:
    """The next trust radius after an accepted step of scaled length ``size`` taken within ``radius``.

    By the ratio of the actual to the predicted decrease (Nocedal and Wright, Algorithm 4.1): half
    the step where the quadratic model overstated the decrease fourfold, at least four times the
    step where it held to half (the first region, unbounded, takes the step's scale), else kept.
    The generous growth follows long, slightly indefinite valleys: against the textbook's doubling
    beyond three quarters, 14 passes instead of 17 on Twin Otter 017 and 956 instead of 1,060 over
    twelve short, ill-conditioned records (4 s, 10 frequencies).
    """
    if ratio < 0.25:
        return 0.5 * size
    bound = radius if math.isfinite(radius) else size
    return max(bound, 4.0 * size) if ratio > 0.5 else bound


def _residual_shape(prob: Problem, V: np.ndarray) -> np.ndarray:
    """Relative noise amplitude per frequency and output from the residuals, shape (N, n_out).

    The residual power |v_ij|^2 is averaged over a moving window of
    +-2 independent frequency spacings (2 * 2 pi / T, at least 3 grid points):
    a smoothed periodogram of the residual.  Its square root, normalised to
    unit mean power per output, scales white noise into coloured noise whose
    spectrum varies slowly over 2 pi / T: the frequency-domain analogue of
    Morelli and Klein's correction of the Cramer-Rao bounds for coloured
    residuals.
    """
    parts = []
    for d, v in zip(prob.data, np.split(V, prob._offsets[1:-1])):
        p2 = np.abs(v) ** 2
        half = 2 * 2 * math.pi / d.T
        step = np.median(np.diff(d.omega)) if d.m > 1 else half
        k = max(int(round(half / step)), 3)
        kernel = np.ones(2 * k + 1)
        num = np.apply_along_axis(lambda x: np.convolve(x, kernel, mode="same"), 0, p2)
        den = np.convolve(np.ones(d.m), kernel, mode="same")[:, None]
        sm = num / den
        parts.append(np.sqrt(sm / np.mean(sm, axis=0, keepdims=True)))
    return np.concatenate(parts)


def _white_cov_g(
    prob: Problem, A: np.ndarray, R: np.ndarray, shape: np.ndarray | None = None, W: np.ndarray | None = None
) -> np.ndarray:
    """Cov of g = Re sum A^H R^-1 v for white time-domain noise (exact, linear in the noise).

    The residual is linear in the sampled noise e_n (one vector per sample,
    covariance Sigma): v_i = sum_n (F P)_in e_n through the transform F and the
    trim removal P, plus, for measured boundary terms, -H_i (delta_0 -
    delta_T exp(-j w_i T)) with delta the trimmed noise at the first and last
    samples.  So g = sum_n Re(K_n) e_n and Cov g = sum_n Re K_n Sigma Re K_n^T.
    Sigma comes from R: E R = Sigma * mean_i ||F_i||^2 (the trim offset is a
    constant, which the output biases absorb; without biases the estimate is
    conservative), scaled by N_real/(N_real - p) for the noise the p
    estimated parameters absorb, N_real = 2 n_out x independent frequencies.
    """
    W = np.linalg.inv(R) if W is None else W  # the fit's weights (band-wise: per row)
    C = np.conj(np.transpose(A, (0, 2, 1))) @ W  # A_i^H W, shape (N, p, n_out)
    if shape is not None:
        C = C * shape[:, None, :]  # coloured noise: v_i = diag(rho_i) (F P e)_i
    gains = np.concatenate([d.noise_gain(include_trim=False) for d in prob.data])
    p, no = A.shape[2], A.shape[1]
    n_real = 2 * no * sum(d.independent_frequencies() for d in prob.data)
    dof = n_real / max(n_real - len(prob.slots), 1.0)
    Sigma = np.real(R) / np.mean(gains) * dof  # time-domain noise covariance per sample
    out_idx = list(prob.out_idx)
    # measured boundary channels (alpha, q[, theta]) in the fit: (their index, their fitted output's)
    bounds = [prob.rows.index(c) for c in boundary_channels(prob.rows)]
    bchan = [(j, out_idx.index(k)) for j, k in enumerate(bounds) if k in out_idx]
    cov = np.zeros((p, p))
    for d, Cr in zip(prob.data, np.split(C, prob._offsets[1:-1])):
        rows, E = _boundary_noise(prob, d, Cr, bchan) if prob.boundary == "measured" and bchan else (None, None)
        if _noise_route(prob, d) != "adjoint":
            # frequency-domain form, O(m^2): g = Re sum_i C_i v_i with E{v v^H} = Sigma (x) Psi,
            # E{v v^T} = Sigma (x) Phi, Psi = (F P)(F P)^H, Phi = (F P)(F P)^T, so
            # Cov g = 1/2 Re sum_ik [Psi_ik C_i Sigma C_k^H + Phi_ik C_i Sigma C_k^T]
            Psi, Phi = d.noise_gram()
            CS = np.transpose(Cr @ Sigma, (1, 0, 2)).reshape(p, -1)
            Y = np.tensordot(Psi, Cr.conj(), axes=(1, 0))
            Z = np.tensordot(Phi, Cr, axes=(1, 0))
            cov += 0.5 * np.real(CS @ np.transpose(Y + Z, (1, 0, 2)).reshape(p, -1).T)
            if rows is not None:  # K_n = Kf_n + E_n differs from the Gram's Kf_n on the rows of E only
                Kf = np.einsum("ms,mpo->spo", _noise_columns(d, rows), Cr)
                cov += _real_sum(Kf + E, Sigma) - _real_sum(Kf, Sigma)
            continue
        K = d.noise_adjoint(Cr.reshape(d.m, p * no)).reshape(d.n, p, no)
        if rows is not None:
            K[rows] += E
        cov += _real_sum(K, Sigma)
    return cov


def _noise_route(prob: Problem, d: FrequencyData) -> str:
    """How record ``d``'s white noise reaches the covariance (:func:`_white_cov_g`).

    ``"closed form"``: the Gram matrices of :meth:`FrequencyData.noise_gram`
    (Dirichlet sums, :func:`fdml.fourier.gram`); ``"explicit weights"``: the
    same from the explicit transform weights (a record too short for the closed
    form); ``"adjoint"``: the direct sums of the adjoint transform over the
    samples, for a grid beyond :attr:`EstimatorSettings.gram_max` frequencies,
    where the (m, m) matrices would cost more than the n samples.
    """
    if d.m > SETTINGS.gram_max:
        return "adjoint"
    return "closed form" if fourier.gram_form(d.n, d.end_correction) == "closed form" else "explicit weights"


def _noise_routes(prob: Problem) -> dict[str, str]:
    """:func:`_noise_route` of every record, by name, in words (for :attr:`FitResult.options`)."""
    words = {
        "closed form": "closed form",
        "explicit weights": "direct sum: explicit transform weights (record too short for the closed form)",
        "adjoint": f"direct sum: adjoint transform (more than {SETTINGS.gram_max} frequencies)",
    }
    return {d.name: words[_noise_route(prob, d)] for d in prob.data}


def _real_sum(K: np.ndarray, Sigma: np.ndarray) -> np.ndarray:
    """sum_n Re K_n Sigma Re K_n^T for K of shape (n, p, n_out)."""
    p = K.shape[1]
    K = np.real(K)
    KS = np.transpose(K @ Sigma, (1, 0, 2)).reshape(p, -1)
    return KS @ np.transpose(K, (1, 0, 2)).reshape(p, -1).T


def _noise_columns(d: FrequencyData, rows: np.ndarray) -> np.ndarray:
    """Columns ``rows`` of the noise map F P (transform after trim removal), shape (m, len(rows))."""
    cols = fourier.transform_columns(d.n, d.dt, d.omega, rows, end_correction=d.end_correction)
    ell = d.trim_vector()
    return cols if ell is None else cols - d.ones[:, None] * ell[rows][None, :]  # F (I - 1 l^T)


def _boundary_noise(prob: Problem, d: FrequencyData, Cr: np.ndarray, bchan) -> tuple[np.ndarray, np.ndarray]:
    """Rows n of the noise map K where measured boundary values add to it, and what they add.

    v = z - y: the noise of the measured x(0), x(T) (samples 0 and n - 1 of the
    fitted alpha, q[, theta], after trim removal) enters through y's exact
    boundary columns.  Returns the sample indices (the trim samples, 0 and
    n - 1) and E of shape (len(rows), p, n_out).
    """
    X = nuisance_columns(prob.model.evaluate(d.omega, prob.model.parameters.values), end_shift(d.omega, d.T), d.ones)
    ny, nb = len(prob.rows), d.x0.size
    CX = Cr @ X[:, prob.out_idx][:, :, ny : ny + 2 * nb]  # (m, p, 2 n_b): x0_alpha, x0_q, ..., xT_alpha, ...
    Q0, QT = -CX[:, :, :nb].sum(axis=0), -CX[:, :, nb:].sum(axis=0)
    ell = d.trim_vector()
    rows = np.unique(np.r_[0, d.n - 1, np.arange(0 if ell is None else d.trim_samples)])
    E = np.zeros((rows.size,) + Cr.shape[1:], complex)
    for j, col in bchan:
        E[rows == 0, :, col] += Q0[:, j]
        E[rows == d.n - 1, :, col] += QT[:, j]
        if ell is not None:
            E[:, :, col] -= np.outer(ell[rows], Q0[:, j] + QT[:, j])
    return rows, E


def information(A: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Re sum_i A_i^H W_i A_i (Eq. 23's matrix), shape (p, p), for sensitivities A (N, n_out, p).

    ``W`` is R^-1 (n_out, n_out), or one R_b^-1 per row (N, n_out, n_out).
    """
    p = A.shape[2]
    return np.real(A.reshape(-1, p).conj().T @ (W @ A).reshape(-1, p))


def white_covariance(
    prob: Problem,
    A: np.ndarray,
    R: np.ndarray,
    Minv: np.ndarray,
    shape: np.ndarray | None = None,
    W: np.ndarray | None = None,
) -> np.ndarray:
    """The fit's ``white`` covariance of the estimate: Minv Cov(g) Minv, inflated for an estimated R.

    ``Minv`` is the inverse of :func:`information`; Cov(g) carries white
    time-domain noise through the transform, grid and trim exactly
    (:func:`_white_cov_g`, whose noise level is the one R implies).  Used by
    :func:`fit` at the estimate and by :mod:`fdml.design` for a predicted R.
    """
    Cg = _white_cov_g(prob, A, R, shape, W)
    # R is estimated from the same residuals, so the weights are random: with N_eff
    # independent frequencies and n_out outputs the variance grows by about
    # N_eff / (N_eff - n_out) (verified by Monte Carlo: 6, 10 and 20 s records)
    n_eff = sum(d.independent_frequencies() for d in prob.data)
    inflate = n_eff / max(n_eff - prob.n_out, 1.0)
    return inflate * (Minv @ Cg @ Minv)


def _naive_sigma(F: np.ndarray) -> np.ndarray:
    """sqrt(diag(F^-1)) for an information matrix F (Cholesky; pseudo-inverse if singular)."""
    try:
        Li = np.linalg.inv(np.linalg.cholesky(F))  # F^-1 = Li^T Li
        return np.sqrt(np.sum(Li**2, axis=0))
    except np.linalg.LinAlgError:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.sqrt(np.abs(np.diag(np.linalg.pinv(F))))


def _warn_at_bounds(prob: Problem, theta: np.ndarray) -> None:
    """A :class:`~fdml.errors.BoundsWarning` for every estimate that ended on one of its bounds."""
    lo, hi = prob.bounds()
    edges = [s.role is Role.INPUT_EDGE for s in prob.slots]  # section 7a: their bounds are the physical interval
    for i, name in enumerate(prob.names):
        side = "lower" if theta[i] <= lo[i] else "upper" if theta[i] >= hi[i] else None
        if side is not None and not edges[i]:
            warnings.warn(
                f"parameter {name} ended on its {side} bound {theta[i]:g}: the likelihood's optimum may lie "
                "beyond it, and its standard error (an interior optimum's) does not hold; widen or drop the bound",
                BoundsWarning,
                stacklevel=5,
            )


def _finish(prob: Problem, state: _State, cov_type: str, elapsed: float, options: dict) -> FitResult:
    """The fit's result at the iteration's end ``state``: covariance, identifiability and bound warnings."""
    names, theta, V, R, rows, A = prob.names, state.theta, state.V, state.R, state.rows, state.A
    if A is None:  # Eq. 26 columns for the bounds are the tight central differences
        A = prob.sensitivities(theta, tol=SETTINGS.settle_tol_final)
    N = prob.N
    W = _weights(R, rows)  # band-wise noise: R_b^-1 per row
    M = information(A, W)
    msgs, dead = _identifiability(2 * M / N, names)
    for m in dict.fromkeys(msgs):
        warnings.warn(m, IdentifiabilityWarning, stacklevel=4)
    live = np.array([n not in dead for n in names])
    cov_naive = np.full((len(names), len(names)), np.nan)
    cov = np.full_like(cov_naive, np.nan)
    idx = np.flatnonzero(live)
    if idx.size:
        Minv = np.linalg.inv(M[np.ix_(idx, idx)])
        cov_naive[np.ix_(idx, idx)] = 0.5 * Minv  # (2 Re sum A^H R^-1 A)^-1
        if cov_type in ("white", "colored"):
            shape = _residual_shape(prob, V) if cov_type == "colored" else None
            if rows is not None and shape is None:  # the noise model's own level per band and output
                shape = np.sqrt(np.real(np.diagonal(R, axis1=1, axis2=2))[rows] / np.real(np.diag(_cov_R(V)))[None, :])
            R_g = R if rows is None else _cov_R(V)
            cov[np.ix_(idx, idx)] = white_covariance(prob, A[:, :, idx], R_g, Minv, shape, W)
        else:
            cov[np.ix_(idx, idx)] = cov_naive[np.ix_(idx, idx)]
    for k in np.flatnonzero(~live):
        cov[k, k] = cov_naive[k, k] = math.inf
    corr = correlation(cov)
    with np.errstate(invalid="ignore"):
        high = np.tril(np.abs(corr) > SETTINGS.correlation_warn, -1)  # NaN compares False
    for i, j in zip(*np.nonzero(high)):  # row by row, as the pairs (i, j < i) are listed
        m = (
            f"parameters {names[j]} and {names[i]} are correlated at {corr[i, j]:+.3f} "
            f"(beyond {SETTINGS.correlation_warn:g})"
        )
        warnings.warn(m, IdentifiabilityWarning, stacklevel=4)
    model = prob.model.with_values({n: theta[i] for i, n in enumerate(names) if not prob.slots[i].role.nuisance})
    _warn_at_bounds(prob, theta)
    return FitResult.build(
        prob=prob,
        model=model,
        theta=theta,
        history=state.prior + state.history,
        options=options,
        cov=cov,
        cov_naive=cov_naive,
        R=R if rows is None else _cov_R(V),
        iterations=state.it,
        converged=state.converged,
        message=state.message,
        elapsed=elapsed,
        stopped=state.stopped,
    )
