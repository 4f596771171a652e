"""The common frame of every fdml model: a short-period system seen through a table of outputs.

Each model supplies, per frequency, the matrices of

    E (s x~ - d) = A(s) x~ + B(s) u~,      x = [alpha, q],  d = x(0) - x(T) e^{-sT}

(the finite-record transform of ``E xdot = A x + B u``; docs/theory.md section 7,
Klein's boundary terms): a :class:`DescriptorModel` from its constant descriptor
``E x' = A x + B0 u + B1 u'``, written once, the Wells-Keskar models from their
transfer functions.  The measured outputs are the rows of :data:`fdml.channels.OUTPUT_TABLE`,
``y = v.x + r.x' + i.int x``, whose transform is ``C(s) x~ - r.d (+ d_y/s)`` with
``C(s) = v + s r + i/s`` (a_z of Eq. 5, theta = q/s with its own boundary term, q_dot = s q).  So

    G(s) = C(s) M(s)^-1 B(s),        M(s) = s E - A(s)        (Eq. 18)
    H(s) = [C(s) M(s)^-1 E - r,  1/s on each integral row's own boundary value]
    P(s) = C(s) M(s)^-1

where H maps the boundary vector to the outputs and P maps a forcing f~ added to
the right-hand side (a state-equation bias, ``E xdot = A x + B u + f``).  The 2 x 2
solve is done in closed form over all frequencies at once.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from ..aircraft import Aircraft
from ..channels import INPUTS, OUTPUT_TABLE, OUTPUTS, SIGNALS, STATIONS, row_space
from ..errors import ParameterError
from ..parameters import Parameter, Parameters, Role

__all__ = ["Descriptor", "DescriptorModel", "Model", "ModelResponse", "OUTPUTS", "solve_short_period"]

#: The table's rows by name.
_ROWS = {o.name: o for o in OUTPUT_TABLE}


@dataclass(frozen=True)
class ModelResponse:
    """Frequency response of a model, frequency first (for array work).

    Parameters
    ----------
    omega : ndarray, shape (n,)
        Frequencies, rad/s.
    G : ndarray, shape (n, n_y, n_in)
        Outputs (the rows ``outputs``) per input (de[, alpha_w]).
    H : ndarray, shape (n, n_y, n_b)
        Outputs per boundary term d = x(0) - x(T) e^{-sT} of each channel of
        :func:`fdml.channels.boundary_channels` (alpha, q[, theta]).
    P : ndarray, shape (n, n_y, 2)
        Outputs per state-equation forcing f~ (alpha_dot and q_dot equations).
    outputs : tuple of str, optional
        The rows: alpha (rad), q (rad/s), a_z (g)[, theta (rad), qdot (rad/s^2)].
    """

    omega: np.ndarray
    G: np.ndarray
    H: np.ndarray
    P: np.ndarray
    outputs: tuple = OUTPUTS


@dataclass(frozen=True)
class Descriptor:
    """``E x' = A x + B0 u + B1 u'`` with x = [alpha, q, extra states...] and input channels.

    The form a :class:`DescriptorModel` gives once (its frequency response, its
    realisation and its export all read it), and the one matrix-level effects act
    on in the time domain (:meth:`fdml.models.effects.MatrixEffect.realize`).

    Parameters
    ----------
    E, A : numpy.ndarray
        Shape (n, n): the descriptor and state matrices.
    B0, B1 : numpy.ndarray
        Shape (n, n_channels): input and input-rate matrices.
    channels : tuple of (str, float)
        Input channels: signal name and delay, s.
    """

    E: np.ndarray
    A: np.ndarray
    B0: np.ndarray
    B1: np.ndarray
    channels: tuple

    def with_state(self, a_row: np.ndarray, a_col: np.ndarray) -> "Descriptor":
        """One more state ``x_n`` with ``x_n' = a_row . [x, x_n]`` feeding ``A[:, n] = a_col`` (E_nn = 1).

        Parameters
        ----------
        a_row : numpy.ndarray
            Shape (n + 1,): the new state's row of A.
        a_col : numpy.ndarray
            Shape (n,): how the new state enters the old states' equations.

        Returns
        -------
        Descriptor
            The system with n + 1 states.
        """
        n = self.A.shape[0]
        E, A = np.pad(self.E, (0, 1)), np.pad(self.A, (0, 1))  # one more row and column of zeros
        E[n, n] = 1.0
        A[:n, n] = a_col
        A[n] = a_row
        row = ((0, 1), (0, 0))
        return Descriptor(E, A, np.pad(self.B0, row), np.pad(self.B1, row), self.channels)


def output_rows(rows: Sequence[str], U: float, p: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The coefficients of ``rows`` on the states, their rates and their integrals (:data:`fdml.channels.OUTPUT_TABLE`).

    Parameters
    ----------
    rows : sequence of str
        Output names.
    U : float
        Airspeed, m/s.
    p : mapping of str to float
        Parameter values (the sensor stations, m).

    Returns
    -------
    V, R, I : numpy.ndarray
        Shape (n_y, 2) each: coefficients on (alpha, q), (alpha', q') and their integrals.
    """
    terms = [(_ROWS[r].value(U, p), _ROWS[r].rate(U, p), _ROWS[r].integral(U, p)) for r in rows]
    V, R, I = (np.array([t[k] for t in terms], dtype=float).reshape(len(rows), 2) for k in range(3))
    return V, R, I


def model_airspeed(model) -> float | None:
    """The model's airspeed U, m/s, or None when it has none.

    Parameters
    ----------
    model : Model
        The model.

    Returns
    -------
    float or None
        U, m/s.
    """
    try:
        return float(model.U)
    except (AttributeError, NotImplementedError, TypeError, ValueError):
        return None


def solve_short_period(s: np.ndarray, M: np.ndarray, B: np.ndarray, E: np.ndarray, rows):
    """Solve ``M x = B u`` (and ``M x = E d``) for all frequencies at once and form the output rows.

    Parameters
    ----------
    s : ndarray, shape (n,)
        The Laplace variable j omega, rad/s.
    M : ndarray, shape (n, 2, 2)
        ``s E - A(s)``.
    B : ndarray, shape (n, 2, n_in)
        Input matrix, with input delays applied.
    E : ndarray, shape (2, 2) or (n, 2, 2)
        Matrix multiplying the state derivative.
    rows : tuple of (V, R, I)
        The rows' coefficients (:func:`output_rows`).

    Returns
    -------
    G : ndarray, shape (n, n_y, n_in)
        Outputs per unit input.
    H : ndarray, shape (n, n_y, n_b)
        Outputs per boundary term of alpha, q and of each integral row.
    P : ndarray, shape (n, n_y, 2)
        Outputs per unit forcing of each state equation.
    """
    return _response_rows(s, _inverse(s, M), B, E, rows)


#: Parameters that place a sensor (they enter the output rows, :data:`fdml.channels.STATIONS`).
_STATION_NAMES = frozenset(STATIONS.values())


def _response_rows(s: np.ndarray, inv: np.ndarray, B: np.ndarray, E: np.ndarray, rows):
    """(G, H, P) of :func:`solve_short_period` from ``inv`` = M^-1, (n, 2, 2)."""
    coef = [c.tolist() for c in rows]  # value, rate, integral: (n_y, 2) each
    ny = len(coef[0])
    terms = [[(f, k, c) for f in range(3) for k in range(2) if (c := coef[f][r][k])] for r in range(ny)]
    by_state = inv.transpose(1, 0, 2)  # row k of M^-1 over the frequencies, (2, n, 2)
    factors = (None, s[:, None], 1.0 / s[:, None])
    scaled: dict = {}  # s M^-1 and M^-1 / s rows, each formed once
    P = np.empty((s.size, ny, 2), complex)  # C(s) M^-1, C(s) = V + s R + I/s: only the nonzero terms
    for r in range(ny):
        row = None
        for f, k, c in terms[r]:
            if f and (f, k) not in scaled:
                scaled[f, k] = factors[f] * by_state[k]
            x = scaled[f, k] if f else by_state[k]
            x = x if c == 1.0 else c * x
            row = x if row is None else row + x
        P[:, r] = 0.0 if row is None else row
    G = P[..., :1] * B[..., None, 0, :] + P[..., 1:] * B[..., None, 1, :]  # C(s) M^-1 B
    H = P.copy() if _is_identity(E) else P @ np.broadcast_to(E, inv.shape)  # state per boundary term: M^-1 E
    for r in range(ny):
        for f, k, c in terms[r]:
            if f == 1:
                H[:, r, k] -= c  # the finite transform of x' is s x~ - d
    own = [r for r in range(ny) if any(f == 2 for f, _, _ in terms[r])]  # integral rows: own boundary term d_y
    if own:
        Hown = np.zeros((s.size, ny, len(own)), complex)
        Hown[:, own, np.arange(len(own))] = 1.0 / s[:, None]
        H = np.concatenate([H, Hown], axis=2)
    return G, H, P


def _inverse(s: np.ndarray, M: np.ndarray) -> np.ndarray:
    """M^-1 = adj(M) / det M per frequency, (n, 2, 2): state per unit forcing of each equation.

    A view of a state-major array, so that each row of M^-1 over the frequencies is contiguous.
    """
    det = M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0]
    if (det == 0).any():  # a pole on the grid
        raise ParameterError(f"the model is singular at s = {s[det == 0][0]}: a pole lies on the frequency grid")
    a = np.empty((2, s.size, 2), complex)
    a[0, :, 0], a[0, :, 1], a[1, :, 0], a[1, :, 1] = M[:, 1, 1], -M[:, 0, 1], -M[:, 1, 0], M[:, 0, 0]
    a /= det[None, :, None]
    return a.transpose(1, 0, 2)


_EYE2 = np.eye(2)


def _is_identity(E: np.ndarray) -> bool:
    """Whether a (2, 2) E is the identity (an (n, 2, 2) one is taken as general)."""
    E = np.asarray(E)
    return E.ndim == 2 and bool((E == _EYE2).all())


def _apply(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A @ x`` per frequency for ``A`` (..., r, 2) and 2-vectors ``x`` (n, 2), as two broadcast products."""
    return A[..., 0] * x[..., :1] + A[..., 1] * x[..., 1:]


def _inputs(B: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``B @ u`` per frequency for ``B`` (..., n, 2, n_in) and inputs ``u`` (n, n_in): shape (..., n, 2)."""
    return sum(B[..., j] * u[:, j : j + 1] for j in range(u.shape[1]))


def _right_side(Bd: np.ndarray, E: np.ndarray, u: np.ndarray, boundary, forcing) -> np.ndarray:
    """The right-hand side ``B u + E d + f`` of ``M x = ...`` per frequency, shape (n, 2) (d: the states' columns)."""
    r = _inputs(Bd, u)
    if boundary is not None:
        d = boundary[:, :2]
        r = r + (d if _is_identity(E) else _apply(E, d))
    return r if forcing is None else r + forcing


def _responded(resp: ModelResponse, u: np.ndarray, boundary, forcing) -> np.ndarray:
    """``G u + H d + P f`` of a response (or of its derivatives, with a leading axis), shape (..., n, n_y)."""
    y = (resp.G @ u[:, :, None])[..., 0]
    if boundary is not None:
        y = y + (resp.H @ boundary[:, :, None])[..., 0]
    return y if forcing is None else y + (resp.P @ forcing[:, :, None])[..., 0]


def _row_space(outputs) -> tuple[str, ...]:
    """:func:`fdml.channels.row_space`, an unknown name a ParameterError."""
    try:
        return row_space(outputs)
    except ValueError as exc:
        raise ParameterError(str(exc)) from None


def _bias_parameter(name: str, free: bool) -> Parameter:
    """The output bias of output ``name``, in its unit."""
    return Parameter(
        f"bias_{name}", 0.0, free=free, unit=SIGNALS[name], description=f"output bias on {name}", role=Role.OUTPUT_BIAS
    )


def _rebiased(params: Parameters, rows: tuple, free: bool) -> Parameters:
    """``params`` with one output bias per row of ``rows``: the others' dropped, the missing ones added."""
    keep = tuple(q for q in params if not (q.role is Role.OUTPUT_BIAS and q.name[len("bias_") :] not in rows))
    return Parameters(keep).extended(_bias_parameter(r, free) for r in rows if f"bias_{r}" not in params)


def _stepped(f, p: Mapping[str, float], name: str, rel: float, floor: float):
    """``(f(p with name + h), f(p with name - h), h)``, h = rel max(|p[name]|, floor): a central difference's
    two evaluations."""
    h = rel * max(abs(p[name]), floor)
    return f({**p, name: p[name] + h}), f({**p, name: p[name] - h}), h


def _padded(dH: np.ndarray, nb: int) -> np.ndarray:
    """``dH`` of the states' boundary columns with zero columns for the integral rows' own, up to ``nb``."""
    return np.pad(dH, [(0, 0)] * (dH.ndim - 1) + [(0, nb - dH.shape[-1])])


#: Roles whose derivatives are not derivatives of the model matrices (M, B, E): input delays
#: (exact, through exp(-s tau)) and the measurement's nuisance terms.
_NOT_IN_MATRICES = frozenset({Role.DELAY}) | frozenset(r for r in Role if r.nuisance)


@dataclass(frozen=True, kw_only=True)
class Model:
    """Base class of fdml's short-period models.

    Subclasses define :attr:`kind`, :meth:`_default_parameters` and
    :meth:`_matrices`.  A model is immutable; :meth:`with_values`,
    :meth:`fix` and :meth:`free` return new models.

    Parameters
    ----------
    gust : bool, optional
        If True the model has a second input, the vertical gust angle alpha_w
        (rad, positive for an up-gust).
    output_bias : bool, optional
        If True the output biases ``bias_alpha, bias_q, bias_az`` (one per
        output) are free parameters (they are present, fixed at zero, otherwise).
    parameters : Parameters, optional
        Overrides the default parameter set.
    outputs : sequence of str, optional
        The outputs the model predicts (:func:`fdml.channels.row_space`): alpha, q,
        a_z, and those of ``theta``, ``qdot`` asked for (:meth:`with_outputs`).
    """

    kind: ClassVar[str] = "base"
    #: Parameters whose matrix derivatives are coded in closed form.
    closed_form_parameters: ClassVar[frozenset] = frozenset(
        {"tau_de", "tau_alpha_w", "bias_alpha", "bias_q", "bias_az"}
    )

    gust: bool = False
    output_bias: bool = False
    parameters: Parameters = field(default=None)  # type: ignore[assignment]
    outputs: tuple[str, ...] = OUTPUTS

    def __post_init__(self) -> None:
        object.__setattr__(self, "outputs", _row_space(self.outputs))
        if self.parameters is None:
            object.__setattr__(self, "parameters", self._default_parameters().extended(self._common_parameters()))
        elif not isinstance(self.parameters, Parameters):
            raise ParameterError("parameters must be an fdml.Parameters set")

    # --- to be provided by subclasses -------------------------------------------
    def _default_parameters(self) -> Parameters:  # pragma: no cover - abstract
        raise NotImplementedError

    def _matrices(self, s: np.ndarray, p: Mapping[str, float]):  # pragma: no cover - abstract
        """Return (M, B, E) for ``s`` (see :func:`solve_short_period`)."""
        raise NotImplementedError

    def matrices(self, omega, values: Mapping[str, float] | None = None):
        """(M, B, E) of ``E (s x - d) = A(s) x + B(s) u`` at ``omega`` (rad/s), M = s E - A.

        ``M`` has shape (n, 2, 2), ``B`` (n, 2, n_in) without the input delays,
        ``E`` (2, 2) or (n, 2, 2); the state is x = [alpha, q].

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        M : numpy.ndarray
            ``s E - A(s)``, complex, shape (n, 2, 2).
        B : numpy.ndarray
            Input matrix without the input delays, complex, shape (n, 2, n_in).
        E : numpy.ndarray
            Matrix multiplying the state derivative, shape (2, 2) or (n, 2, 2).
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        return self._matrices(1j * omega, self.values(values))

    def short_period_frequency(self, values: Mapping[str, float] | None = None) -> float:
        """The undamped natural frequency of the short period, rad/s.

        ``det(s E - A) = det(E) s^2 + ... + det(A)`` (the two-state system of
        :func:`solve_short_period`), so omega_n = sqrt(|det A / det E|).  Where A
        depends on s (the lags of the unsteady model, effects), it is taken at
        s = j omega_n itself: a few fixed-point passes from 1 rad/s, each exact
        for constant matrices.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        float
            The frequency omega_n, rad/s (NaN when the matrices are not finite).
        """
        w = 1.0
        for _ in range(4):
            M, _, E = self.matrices([w], values)
            E0 = E if E.ndim == 2 else E[0]
            A = 1j * w * E0 - M[0]
            with np.errstate(all="ignore"):
                w_new = float(np.sqrt(np.abs(np.linalg.det(A) / np.linalg.det(E0))))
            if not np.isfinite(w_new) or w_new <= 0.0:
                return w_new if np.isfinite(w_new) else float("nan")
            w = w_new
        return w

    @property
    def U(self) -> float:  # pragma: no cover - abstract
        """Airspeed, m/s."""
        raise NotImplementedError

    def placeholders(self) -> dict[str, str]:
        """Parameters still at a generic start value that no aircraft file and no user gave.

        Such a value is not data: a design, a simulation or a prediction made
        with it says little about the real aircraft.  A value changed since the
        model was built (:meth:`with_values`, ``--set``) is no longer a placeholder.

        Returns
        -------
        dict of str to str
            Parameter name -> what generic value it stands on.
        """
        return {
            n: why
            for n, (start, why) in self._placeholder_sources().items()
            if n in self.parameters and self.parameters[n].value == start
        }

    def _placeholder_sources(self) -> dict[str, tuple[float, str]]:
        """Parameter name -> (its generic start value, why) for the parameters built on generic values."""
        return {}

    def derived(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        """Derived quantities (the alternate set); empty by default.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        dict of str to float
            Derived quantity name -> value (in its unit).
        """
        return {}

    # --- common machinery --------------------------------------------------------
    @property
    def inputs(self) -> tuple[str, ...]:
        """Input names: ``('de',)`` or ``('de', 'alpha_w')``."""
        return INPUTS if self.gust else INPUTS[:1]

    def _common_parameters(self) -> list[Parameter]:
        what = {"tau_de": "elevator time delay", "tau_alpha_w": "gust-angle time delay"}
        return [
            Parameter(n, 0.0, free=False, lower=0.0, unit="s", description=what[n], role=Role.DELAY)
            for n in self._delay_names()
        ] + [_bias_parameter(name, self.output_bias) for name in self.outputs]

    def _delay_names(self) -> tuple[str, ...]:
        """The input delays of B, one per input (``tau_de``, ``tau_alpha_w``)."""
        return ("tau_de", "tau_alpha_w") if self.gust else ("tau_de",)

    def values(self, values: Mapping[str, float] | Parameters | None = None) -> dict[str, float]:
        """All parameter values, with ``values`` (by name) overriding the defaults.

        Parameters
        ----------
        values : mapping of str to float, or Parameters, optional
            Values by name overriding the model's own.

        Returns
        -------
        dict of str to float
            Every parameter's value, by name.
        """
        p = self.parameters.values
        if values is None:
            return p
        if isinstance(values, Parameters):
            values = values.values
        unknown = [k for k in values if k not in p]
        if unknown:
            raise ParameterError(
                f"unknown parameter {unknown[0]!r} for the {self.kind} model; known: {', '.join(self.parameters.names)}"
            )
        p.update({k: float(v) for k, v in values.items()})
        return p

    def evaluate(self, omega, values: Mapping[str, float] | None = None) -> ModelResponse:
        """G and H at ``omega`` (rad/s), frequency first; see :class:`ModelResponse`.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        ModelResponse
            The response at ``omega``.
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        *_, (G, H, P) = self._solved(omega, self.values(values))
        return ModelResponse(omega, G, H, P, self.outputs)

    def sensitivity(
        self,
        omega,
        values: Mapping[str, float] | None = None,
        names: Sequence[str] = (),
        parts: Sequence[str] = ("G", "H", "P"),
    ):
        """Response and its derivatives with respect to ``names``.

        Returns ``(resp, dG, dH, dP)`` with ``resp`` the :class:`ModelResponse`
        and ``dG`` of shape (len(names), n, n_y, n_in), ``dH`` of shape
        (len(names), n, n_y, n_b) and ``dP`` of shape (len(names), n, n_y, 2).
        For the two-state models the derivatives are propagated through the
        solve exactly,

            dG = P (dB - dM M^-1 B),  dH = P (dE - dM M^-1 E),  dP = -P dM M^-1,

        from the derivatives of the matrices (analytic for the parameters a
        model knows in closed form, central differences of the matrices, not
        of the solution, otherwise).  A subclass that overrides
        :meth:`evaluate` without providing matrices gets central differences
        of :meth:`evaluate` instead.  ``parts`` limits which derivatives are
        computed (the others are returned as None).

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.
        names : sequence of str, optional
            Parameters to differentiate with respect to.
        parts : sequence of {"G", "H", "P"}, optional
            Which derivatives to compute (``dG`` always is).

        Returns
        -------
        resp : ModelResponse
            The response at ``omega``.
        dG : numpy.ndarray
            Derivatives dG/d(name), shape (len(names), n, n_y, n_in).
        dH, dP : numpy.ndarray or None
            Derivatives dH/d(name) and dP/d(name), shapes (len(names), n, n_y, n_b) and (len(names), n, n_y, 2),
            or None when not in ``parts``.
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        p = self.values(values)
        names = list(names)
        if type(self).evaluate is not Model.evaluate:
            return self._fd_sensitivity(omega, p, names)
        return self._matrix_sensitivity(omega, p, names, parts)

    def _matrix_sensitivity(self, omega, p, names, parts):
        """:meth:`sensitivity` through the solve, for parameters that enter :meth:`_matrices` (or input delays)."""
        s, M, Bd, E, Dl, inv, (G, H, P) = self._solved(omega, p)
        X = inv @ Bd
        IE = inv if _is_identity(E) else inv @ np.broadcast_to(E, M.shape)
        dM, dBd, dE = self._derivative_stack(s, p, names, Bd, Dl)
        # all parameters at once: dG = P (dB - dM X), dH = P (dE - dM M^-1 E), dP = -P dM M^-1
        PdM = P @ dM
        dG = P @ dBd - PdM @ X
        dH = _padded(P @ dE - PdM @ IE, H.shape[2]) if "H" in parts else None  # integral rows' own: constant
        dP = -(PdM @ inv) if "P" in parts else None
        for i, nm in enumerate(names):
            if nm in _STATION_NAMES:
                for dx, d in zip((dG, dH, dP), self._station_derivative(s, inv, Bd, E, p, nm, H.shape[2])):
                    if dx is not None:
                        dx[i] = d
        return ModelResponse(omega, G, H, P, self.outputs), dG, dH, dP

    def forced_sensitivity(self, omega, values, names, u, boundary=None, forcing=None):
        """The response and the derivatives of the outputs it gives for one forcing.

        With ``x = M^-1 (B u + E d + f)`` the states for inputs ``u``, boundary
        vector ``d`` and state forcing ``f`` (the linear part of
        :func:`fdml.models.measurement.predict`: ``y = G u + H d + P f``), the
        derivative of ``y`` with respect to each name is ``P (dB u + dE d - dM
        x)``: the same quantity as :meth:`sensitivity`'s ``dG u + dH d + dP f``,
        formed without the derivative matrices (one 2-vector per frequency and
        name instead of 2 x 2 blocks).  Models without matrices (an overridden
        :meth:`evaluate`) apply :meth:`sensitivity`'s derivatives instead.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s, shape (n,).
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.
        names : sequence of str
            Parameters to differentiate with respect to.
        u : numpy.ndarray
            Input spectra (de rad s[, alpha_w rad s]), complex, shape (n, n_in).
        boundary : numpy.ndarray, optional
            Boundary vector d (alpha rad s, q rad[, theta rad s]), complex, shape (n, n_b); None for none.
        forcing : numpy.ndarray, optional
            State forcing f (transform of the alpha_dot and q_dot equations' constants), shape (n, 2).

        Returns
        -------
        resp : ModelResponse
            The response at ``omega``.
        dy : numpy.ndarray
            Derivatives of the outputs (alpha rad s, q rad, a_z g s, ...) per name, complex, shape (len(names), n, n_y).
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        names = list(names)
        if not self._solves_matrices():
            parts = ("G",) + (("H",) if boundary is not None else ()) + (("P",) if forcing is not None else ())
            resp, dG, dH, dP = self.sensitivity(omega, values, names, parts)
            return resp, _responded(ModelResponse(omega, dG, dH, dP), u, boundary, forcing)
        return self._forced_solve(omega, self.values(values), names, u, boundary, forcing)

    def _forced_solve(self, omega, p, names, u, boundary, forcing):
        """:meth:`forced_sensitivity` through the solve of :meth:`_matrices` (every value in ``p``)."""
        s, M, Bd, E, Dl, inv, (G, H, P) = self._solved(omega, p)
        x = _apply(inv, _right_side(Bd, E, u, boundary, forcing))  # the states M^-1 r
        dM, dBd, dE = self._derivative_stack(s, p, names, Bd, Dl)
        w = _inputs(dBd, u) - _apply(dM, x)  # (k, n, 2)
        if boundary is not None and dE.any():
            w = w + _apply(dE, boundary[:, :2])
        dy = _apply(P, w)
        for i, nm in enumerate(names):
            if nm in _STATION_NAMES:  # y = V x + R (s x - d) + I x / s: the station moves V and R
                dV, dR, dI = self._station_rows(p, nm)
                d = 0.0 if boundary is None else boundary[:, :2]
                dy[i] = _apply(dV, x) + _apply(dR, s[:, None] * x - d) + _apply(dI, x / s[:, None])
        return ModelResponse(omega, G, H, P, self.outputs), dy

    def _station_rows(self, p, name: str) -> tuple:
        """d(V, R, I)/d(name) of the output rows (:func:`output_rows`) for a sensor's station: the rows are
        affine in it, so their change for a unit step, exactly."""
        at, unit = output_rows(self.outputs, self.U, p), output_rows(self.outputs, self.U, {**p, name: p[name] + 1.0})
        return tuple(b - a for a, b in zip(at, unit))

    def _station_derivative(self, s, inv, Bd, E, p, name: str, nb: int) -> tuple:
        """d(G, H, P)/d(name) for a sensor's station: it enters its output row, not the matrices.

        (G, H, P) are linear in the rows' coefficients, so the derivative is the response of their unit
        change (:meth:`_station_rows`; no integral term, so no boundary column of its own).
        """
        dG, dH, dP = _response_rows(s, inv, Bd, E, self._station_rows(p, name))
        return dG, _padded(dH, nb), dP

    def _solves_matrices(self) -> bool:
        """Whether the response is the solve of :meth:`_matrices` alone (then :meth:`forced_sensitivity` forms
        the outputs' derivatives without the response's; an overridden :meth:`evaluate` or
        :meth:`sensitivity` says otherwise)."""
        return type(self).evaluate is Model.evaluate and type(self).sensitivity is Model.sensitivity

    def _forced_matrices(self, omega, p):
        """s, M, B with input delays, E and the delay factors exp(-s tau), shape (n, n_in) (None: no delays)."""
        s = 1j * omega
        M, B, E = self._matrices(s, p)
        delays = [p[nm] for nm in self._delay_names()]
        if not any(delays):  # no delay (the usual case): factors of one
            return s, M, B, E, None
        Dl = np.exp(-np.outer(s, delays))
        return s, M, B * Dl[:, None, :], E, Dl  # pure input delays

    def _solved(self, omega, p):
        """:meth:`_forced_matrices`, M^-1 and :func:`solve_short_period`'s (G, H, P) for the model's outputs."""
        s, M, Bd, E, Dl = self._forced_matrices(omega, p)
        inv = _inverse(s, M)
        return s, M, Bd, E, Dl, inv, _response_rows(s, inv, Bd, E, output_rows(self.outputs, self.U, p))

    def _derivative_stack(self, s, p, names, Bd, Dl):
        """dM (k, n, 2, 2), d(B with delays) (k, n, 2, n_in) and dE (k, 1, 2, 2), one row per name.

        ``Dl`` holds the delay factors of :meth:`_forced_matrices` (None: no delays).
        """
        n, n_in, k = s.size, Bd.shape[2], len(names)
        dM = np.zeros((k, n, 2, 2), complex)
        dBd = np.zeros((k, n, 2, n_in), complex)
        dE = np.zeros((k, 1, 2, 2))
        roles = [self.parameters[nm].role for nm in names]
        delay_names = self._delay_names()
        # output biases enter the measurement, a sensor's station its output row: neither the matrices
        inside = [nm for nm, r in zip(names, roles) if r not in _NOT_IN_MATRICES and nm not in _STATION_NAMES]
        mats = self._matrix_derivatives(s, p, inside)
        for i, (nm, role) in enumerate(zip(names, roles)):
            if role is Role.DELAY and nm in delay_names:  # an input delay of B
                j = delay_names.index(nm)
                dBd[i, :, :, j] = -s[:, None] * Bd[:, :, j]  # d/dtau exp(-s tau) = -s exp(-s tau)
            elif nm in mats:
                dMi, dBi, dEi = mats[nm]
                dM[i] = dMi
                dBd[i] = dBi if Dl is None else dBi * Dl[:, None, :]
                if dEi is not None:
                    dE[i, 0] = dEi
        return dM, dBd, dE

    def _matrix_derivatives(self, s, p, names):
        """{name: (dM, dB, dE)}: central differences of :meth:`_matrices`.

        Subclasses override this for the parameters they know in closed form
        and call it for the rest.  The matrices are smooth closed forms in the
        parameters; a relative step of 1e-5 gives truncation error near 1e-10
        and rounding error near 1e-11 relative.
        """
        out = {}
        for nm in names:
            (Mp, Bp, Ep), (Mm, Bm, Em), h = _stepped(lambda q: self._matrices(s, q), p, nm, 1e-5, 1e-2)
            dE = (np.asarray(Ep) - np.asarray(Em)) / (2 * h)
            out[nm] = ((Mp - Mm) / (2 * h), (Bp - Bm) / (2 * h), dE if np.any(dE) else None)
        return out

    def _fd_sensitivity(self, omega, p, names):
        """Central differences of :meth:`evaluate` (for models without matrices)."""
        resp = self.evaluate(omega, p)
        d = [np.zeros((len(names),) + x.shape, complex) for x in (resp.G, resp.H, resp.P)]
        for k, nm in enumerate(names):
            rp, rm, h = _stepped(lambda q: self.evaluate(omega, q), p, nm, 1e-5, 1e-2)
            for dx, up, dn in zip(d, (rp.G, rp.H, rp.P), (rm.G, rm.H, rm.P)):
                dx[k] = (up - dn) / (2 * h)
        return (resp, *d)

    def frequency_response(self, omega, values: Mapping[str, float] | None = None) -> np.ndarray:
        """G(j omega, theta), shape (n_y outputs, n_in inputs, n omega) (Eq. 18).

        Outputs are the rows of :attr:`outputs`: alpha (rad), q (rad/s), a_z (g)
        [, theta (rad), qdot (rad/s^2)]; inputs de (rad) and, for a gust model,
        alpha_w (rad).  The layout follows python-control.

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        numpy.ndarray
            Complex response, shape (n_y, n_in, n).

        Raises
        ------
        ParameterError
            If the response is not finite (overflow from extreme values): a
            table of NaN is never returned silently.
        """
        G = np.moveaxis(self.evaluate(omega, values).G, 0, -1)
        if not np.all(np.isfinite(G)):
            k = int(np.argmax(~np.all(np.isfinite(G), axis=(0, 1))))
            raise ParameterError(
                f"{self.describe()}: the frequency response is not finite at {np.ravel(omega)[k]:g} rad/s "
                f"(overflow: check the airspeed U = {self.U:g} m/s and the parameter values)"
            )
        return G

    def biases(self, values: Mapping[str, float] | None = None) -> np.ndarray:
        """Output biases (alpha rad, q rad/s, az g, ...), one per output of :attr:`outputs`.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        numpy.ndarray
            The biases, shape (n_y,).
        """
        p = self.values(values)
        return np.array([p[f"bias_{n}"] for n in self.outputs])

    def with_outputs(self, outputs) -> "Model":
        """This model predicting ``outputs`` too (:func:`fdml.channels.row_space`), with their output biases.

        Parameters
        ----------
        outputs : sequence of str or str
            Output names (``"theta"``, ``"qdot"``; alpha, q and a_z are always predicted).

        Returns
        -------
        Model
            The model; itself when it already predicts exactly these rows.
        """
        rows = _row_space(outputs)
        if rows == self.outputs:
            return self
        return replace(self, outputs=rows, parameters=_rebiased(self.parameters, rows, self.output_bias))

    # --- functional updates --------------------------------------------------------
    def with_parameters(self, parameters: Parameters) -> "Model":
        """Return a copy with a new parameter set.

        Parameters
        ----------
        parameters : Parameters
            The new parameter set.

        Returns
        -------
        Model
            The copy.
        """
        return replace(self, parameters=parameters)

    def with_values(self, values: Mapping[str, float] | None = None, **kw: float) -> "Model":
        """Return a copy with new parameter values.

        Parameters
        ----------
        values : mapping of str to float, optional
            New values by name.
        **kw : float
            More new values by name.

        Returns
        -------
        Model
            The copy.
        """
        return self.with_parameters(self.parameters.with_values(values, **kw))

    def fix(self, names: Sequence[str] | Mapping[str, float]) -> "Model":
        """Return a copy with ``names`` fixed (a mapping also sets values).

        Parameters
        ----------
        names : sequence of str or mapping of str to float
            Parameters to fix (with their values for a mapping).

        Returns
        -------
        Model
            The copy.
        """
        return self.with_parameters(self.parameters.fix(names))

    def free(self, names: Sequence[str]) -> "Model":
        """Return a copy with ``names`` freed.

        Parameters
        ----------
        names : sequence of str
            Parameters to free.

        Returns
        -------
        Model
            The copy.
        """
        return self.with_parameters(self.parameters.free(names))

    def derived_jacobian(self, values: Mapping[str, float], names: Sequence[str]):
        """Jacobian of :meth:`derived` with respect to ``names`` (central differences).

        The alternate-set maps are low-order polynomials in the parameters, so
        a central difference with relative step 1e-6 has truncation error near
        1e-12 and rounding error near 1e-10 relative; ample for a delta-method
        covariance.

        Parameters
        ----------
        values : mapping of str to float
            Parameter values by name (the point of the derivatives).
        names : sequence of str
            Parameters to differentiate with respect to.

        Returns
        -------
        keys : list of str
            The derived quantities, in :meth:`derived`'s order.
        J : numpy.ndarray
            Derivatives d(derived)/d(names), shape (len(keys), len(names)).
        """
        base = self.values(values)
        keys = list(self.derived(base))
        J = np.zeros((len(keys), len(names)))
        for j, n in enumerate(names):
            du, dd, h = _stepped(self.derived, base, n, 1e-6, 1e-3)
            J[:, j] = [(du[k] - dd[k]) / (2 * h) for k in keys]
        return keys, J

    @property
    def parts(self) -> tuple:
        """The effects this model is made of (none for a plain model)."""
        return ()

    def describe(self) -> str:
        """One line naming the model and its options.

        Returns
        -------
        str
            E.g. ``"unsteady model (gust, output biases)"``.
        """
        opts = ["gust" if self.gust else "elevator only"]
        if self.output_bias:
            opts.append("output biases")
        if self.outputs != OUTPUTS:
            opts.append("outputs " + ",".join(self.outputs))
        return f"{self.kind} model ({', '.join(opts)})"


@dataclass(frozen=True, kw_only=True)
class AircraftModel(Model):
    """A model built on an :class:`~fdml.aircraft.Aircraft` (geometry and flight condition), which it requires.

    Parameters
    ----------
    aircraft : Aircraft
        Geometry, mass, flight condition and default constants; its airspeed is the model's U.
    """

    aircraft: Aircraft = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if not isinstance(self.aircraft, Aircraft):
            raise ParameterError(f"the {self.kind} model needs an Aircraft (geometry and flight condition)")
        super().__post_init__()

    @property
    def U(self) -> float:
        return self.aircraft.U


@dataclass(frozen=True, kw_only=True)
class DescriptorModel(Model):
    """A model given by its descriptor ``E x' = A x + B0 u + B1 u'`` over x = [alpha, q] (:class:`Descriptor`).

    Subclasses write the descriptor once, in :meth:`_descriptor`; the frequency
    response (``M = s E - A``, ``B = B0 + s B1``), the sensitivities, the
    realisation (:func:`fdml.models.realization.realize`) and the export
    (:func:`fdml.export.descriptor_matrices`) all read it.  Every entry of
    ``E, A, B0, B1`` is affine in the parameters (jointly), so its derivatives are
    constants of the model, read once from unit steps (:meth:`_jacobian`).

    Parameters
    ----------
    gust, output_bias : bool, optional
        Add the vertical-gust input alpha_w; free the output biases.
    parameters : Parameters, optional
        Overrides the default parameter set.
    outputs : sequence of str, optional
        The outputs predicted (see :class:`Model`).
    """

    def _descriptor(self, p: Mapping[str, float]) -> Descriptor:  # pragma: no cover - abstract
        """The descriptor at parameter values ``p`` (x = [alpha, q]; channels de[, alpha_w] with their delays)."""
        raise NotImplementedError

    def descriptor(self, values: Mapping[str, float] | None = None) -> Descriptor:
        """``E x' = A x + B0 u + B1 u'`` over x = [alpha, q], the model's equations.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        Descriptor
            E, A (2, 2), B0, B1 (2, n_in) and the input channels with their delays.
        """
        return self._descriptor(self.values(values))

    def _channels(self, p: Mapping[str, float]) -> tuple:
        """The input channels with their delays: ``("de", tau_de)`` [, ``("alpha_w", tau_alpha_w)``]."""
        return tuple((sig, p[tau]) for sig, tau in zip(self.inputs, self._delay_names()))

    def _matrices(self, s, p):
        d = self._descriptor(p)
        M, B = _pencil(s, d.E, d.A, d.B0, d.B1)
        if B.ndim == 2:  # constant: one (2, n_in) per frequency, writable (a matrix-level effect may change it)
            B = np.repeat(B[None], s.size, axis=0)
        return M, B, d.E

    def _matrix_derivatives(self, s, p, names):
        """The derivatives of the descriptor, constant: ``(dM, dB, dE)`` per name from :attr:`_jacobian`."""
        out = {}
        for nm in names:
            dE, dA, dB0, dB1 = self._jacobian(nm)
            out[nm] = _pencil(s, dE, dA, dB0, dB1) + (dE if dE.any() else None,)
        return out

    def _jacobian(self, name: str) -> tuple:
        """``d(E, A, B0, B1)/d name``: every entry is affine in the parameters jointly, so a unit step from the
        model's own values gives it exactly (to rounding), once per model."""
        cache = self.__dict__.setdefault("_jacobians", {})  # frozen dataclass: the cache is not a field
        if name not in cache:
            p = self.values()
            hi, lo = self._descriptor({**p, name: p[name] + 0.5}), self._descriptor({**p, name: p[name] - 0.5})
            cache[name] = (hi.E - lo.E, hi.A - lo.A, hi.B0 - lo.B0, hi.B1 - lo.B1)
        return cache[name]


def _pencil(s: np.ndarray, E, A, B0, B1) -> tuple:
    """``(s E - A, B0 + s B1)`` over the frequencies; a constant term stays (2, .) where it does not depend on s."""
    S = s[:, None, None]
    M = S * E - A if E.any() else -A
    return M, (B0 + S * B1 if B1.any() else B0.astype(complex))
