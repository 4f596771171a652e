"""The forward measurement model of every fit, written once.

The output spectra of one record are modelled as (docs/theory.md Eqs. 18-19, with
Klein's boundary terms of section 7)

    y(w) = G(w) u(w) + H(w) d(w) + b 1(w) + P(w) f 1(w) + G_de(w) [b_de 1(w) + e(w)],
    d(w) = x(0) - x(T) exp(-j w T),        x = [alpha, q (, theta)],
    e(w) = -sum_k s_k tau_k exp(-j w t_k)  (section 7a),

with ``G``, ``H``, ``P`` a :class:`~fdml.models.base.ModelResponse`, ``u`` the
input spectra, ``1(w)`` the transform of a unit constant over the record
(``FrequencyData.ones``), ``b`` the output biases (alpha rad, q rad/s, a_z g, one per
output of the response's rows),
``f`` the state-equation biases (constants added to the alpha_dot and q_dot
equations, rad/s and rad/s^2), ``b_de`` an elevator offset (rad), ``e`` the
timing terms of the elevator's steps between samples (a step ``s_k`` rad that the
transform puts mid-interval at ``t_k`` happened ``tau_k`` s later; :func:`edge_basis`) and ``d`` the
boundary vector of the states and of each integral output (theta,
:func:`fdml.channels.boundary_channels`).  The measured spectra are ``z = y + v`` (Eq. 19).

Every nuisance quantity enters linearly, so its sensitivity is exact:
:func:`nuisance_columns` gives ``dy/d eta`` for the per-record nuisance
values ``eta`` in the order of :func:`nuisance_names` (:data:`NUISANCE_NAMES` for the
three outputs alpha, q, a_z: ten values), and :func:`predict`
with ``biases=None`` is linear in the response, so the sensitivity of ``y`` to
a model parameter is ``predict`` of the response's derivative.  The estimator
(:class:`fdml.estimate.Problem`), the saved result
(:meth:`fdml.results.FitResult.fitted_spectra`) and the time-domain view
(:func:`fdml.plotting.simulate_fit`, through :meth:`FitResult.nuisance_values`) all
use this module; none keeps its own formula.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..channels import OUTPUTS, STATES, boundary_channels

__all__ = [
    "BOUNDARY_NAMES",
    "INPUT_BIAS_NAME",
    "NUISANCE_NAMES",
    "OUTPUT_BIAS_NAMES",
    "STATE_BIAS_NAMES",
    "Nuisance",
    "boundary_vector",
    "edge_basis",
    "edge_names",
    "end_shift",
    "nuisance_columns",
    "nuisance_names",
    "predict",
]

#: State-equation biases f: alpha_dot (rad/s) and q_dot (rad/s^2) equations.
STATE_BIAS_NAMES = tuple(f"bias_{x}_dot" for x in STATES)
#: Elevator offset b_de (rad).
INPUT_BIAS_NAME = "bias_de"


def nuisance_names(rows=OUTPUTS) -> tuple[str, ...]:
    """The per-record nuisance values of outputs ``rows``, in the column order of :func:`nuisance_columns`.

    Parameters
    ----------
    rows : sequence of str, optional
        The output rows (default alpha, q, a_z).

    Returns
    -------
    tuple of str
        Output biases ``bias_<output>``, boundary values ``x0_<channel>`` then ``xT_<channel>``
        (:func:`fdml.channels.boundary_channels`), :data:`STATE_BIAS_NAMES`, :data:`INPUT_BIAS_NAME`.
    """
    bounds = boundary_channels(rows)
    ends = tuple(f"{end}_{c}" for end in ("x0", "xT") for c in bounds)
    return tuple(f"bias_{o}" for o in rows) + ends + STATE_BIAS_NAMES + (INPUT_BIAS_NAME,)


def edge_names(count: int) -> tuple[str, ...]:
    """Names of the timing terms of a record's ``count`` elevator steps between samples: ``edge_de_1``, ...

    Parameters
    ----------
    count : int
        The record's step edges (:attr:`fdml.spectral.FrequencyData.edges`).

    Returns
    -------
    tuple of str
        One name per edge, in time order; they follow :func:`nuisance_names` in a record's nuisance vector.
    """
    return tuple(f"edge_de_{k + 1}" for k in range(count))


def edge_basis(omega: np.ndarray, edges: np.ndarray, steps: np.ndarray, mode: str = "estimated") -> np.ndarray:
    """The elevator spectrum per second of timing of each step edge: ``-s_k exp(-j w t_k)`` (section 7a).

    A step ``s_k`` at ``t_k + tau_k`` has the transform ``s_k exp(-j w (t_k + tau_k)) / (j w)``; the
    interpolating transform of the samples puts it at the interval's middle ``t_k``, so the true
    elevator spectrum is the measured one plus ``-s_k tau_k exp(-j w t_k)`` to first order in
    ``w tau_k`` (|tau_k| <= dt/2).

    Parameters
    ----------
    omega : numpy.ndarray
        Frequencies, rad/s, shape (m,).
    edges : numpy.ndarray
        Middles of the intervals holding a step, s from the first sample, shape (K,).
    steps : numpy.ndarray
        The elevator's change across each, rad, shape (K,).
    mode : {"estimated", "none"}, optional
        Every step's timing (K columns) or none (0: the record's transform taken as it is).

    Returns
    -------
    numpy.ndarray
        Complex, rad, shape (m, K), or (m, 0).
    """
    B = -np.asarray(steps, float)[None, :] * np.exp(-1j * np.outer(omega, np.asarray(edges, float)))
    return B if mode == "estimated" else B[:, :0]


#: Per-record nuisance values of alpha, q and a_z, in the column order of :func:`nuisance_columns`.
NUISANCE_NAMES = nuisance_names()
#: Output biases b: alpha (rad), q (rad/s), a_z (g).
OUTPUT_BIAS_NAMES = NUISANCE_NAMES[: len(OUTPUTS)]
#: Boundary values of section 7: x(0) and x(T) of alpha (rad) and q (rad/s).
BOUNDARY_NAMES = NUISANCE_NAMES[len(OUTPUTS) : len(OUTPUTS) + 2 * len(STATES)]


class Nuisance(NamedTuple):
    """The nuisance values of one record, as arrays (immutable; a tuple, cheap in the fit's inner loop).

    Parameters
    ----------
    biases : ndarray, shape (n_y,)
        Output biases b (alpha rad, q rad/s, a_z g, ...).
    x0, xT : ndarray, shape (n_b,), or None, optional
        Boundary values x(0), x(T) of [alpha rad, q rad/s (, theta rad)]; None
        without boundary terms (``boundary="none"``).
    state_biases : ndarray, shape (2,), or None, optional
        State-equation biases f (rad/s, rad/s^2); None when not in the model.
    input_bias : float or None, optional
        Elevator offset b_de (rad); None when not in the model.
    edges : ndarray, shape (K,), or None, optional
        Timing tau_k of the elevator's steps between samples (s, later than mid-interval
        positive; :func:`edge_basis`); None when not estimated.
    """

    biases: np.ndarray
    x0: np.ndarray | None = None
    xT: np.ndarray | None = None
    state_biases: np.ndarray | None = None
    input_bias: float | None = None
    edges: np.ndarray | None = None

    @classmethod
    def from_vector(
        cls, eta: np.ndarray, *, boundary: bool, state_biases: bool, input_bias: bool, rows=OUTPUTS, edges: int = 0
    ) -> Nuisance:
        """From the values ``eta`` in :func:`nuisance_names` order; flags say which terms are on.

        Parameters
        ----------
        eta : numpy.ndarray
            The nuisance values of ``rows``, each in its unit (ten for alpha, q, a_z).
        boundary : bool
            Keep the boundary values x(0), x(T).
        state_biases : bool
            Keep the state-equation biases.
        input_bias : bool
            Keep the elevator offset.
        rows : sequence of str, optional
            The output rows (default alpha, q, a_z).
        edges : int, optional
            The step edges' timing terms that follow (:func:`edge_names`); 0: none.

        Returns
        -------
        Nuisance
            The values, None for the terms that are off.
        """
        eta = np.asarray(eta, float)
        ny, nb = len(rows), len(boundary_channels(rows))
        b = ny + 2 * nb  # first state bias
        return cls(
            biases=eta[:ny],
            x0=eta[ny : ny + nb] if boundary else None,
            xT=eta[ny + nb : b] if boundary else None,
            state_biases=eta[b : b + 2] if state_biases else None,
            input_bias=float(eta[b + 2]) if input_bias else None,
            edges=eta[b + 3 : b + 3 + edges] if edges else None,
        )

    def elevator(self, ones: np.ndarray, basis: np.ndarray) -> np.ndarray | None:
        """What the nuisance terms add to the elevator's spectrum: ``b_de 1(w) + e(w)``, or None.

        Parameters
        ----------
        ones : numpy.ndarray
            Transform of a unit constant over the record, s, shape (m,).
        basis : numpy.ndarray
            The record's :func:`edge_basis`, shape (m, K).

        Returns
        -------
        numpy.ndarray or None
            Complex, rad s, shape (m,); None when neither term is on.
        """
        out = None if self.input_bias is None else self.input_bias * ones
        if self.edges is not None and self.edges.size:
            e = basis @ self.edges
            out = e if out is None else out + e
        return out

    def boundary(self, shift: np.ndarray) -> np.ndarray | None:
        """The boundary vector d(w) (:func:`boundary_vector`), or None without boundary terms.

        Parameters
        ----------
        shift : numpy.ndarray
            ``exp(-j w T)``, complex, shape (m,) (:func:`end_shift`).

        Returns
        -------
        numpy.ndarray or None
            The boundary vector, complex, shape (m, n_b).
        """
        return None if self.x0 is None or self.xT is None else boundary_vector(self.x0, self.xT, shift)


def end_shift(omega: np.ndarray, T: float) -> np.ndarray:
    """``exp(-j w T)``, shape (m,): the factor of x(T) in the transform of a record of length T, s.

    Parameters
    ----------
    omega : numpy.ndarray
        Frequencies, rad/s, shape (m,).
    T : float
        Record length, s.

    Returns
    -------
    numpy.ndarray
        The complex factors, shape (m,).
    """
    return np.exp(-1j * np.asarray(omega, float) * T)


def boundary_vector(x0: np.ndarray, xT: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Klein's boundary vector ``d(w) = x(0) - x(T) exp(-j w T)`` (docs/theory.md section 7).

    Parameters
    ----------
    x0, xT : ndarray, shape (n_b,)
        The boundary channels alpha (rad), q (rad/s)[, theta (rad)] at t = 0 and t = T.
    shift : ndarray, complex, shape (m,)
        ``exp(-j w T)`` (:func:`end_shift`).

    Returns
    -------
    ndarray, complex, shape (m, n_b)
        The boundary vector per frequency, in the channels' units.
    """
    return x0[None, :] - xT[None, :] * shift[:, None]


def predict(
    response,
    u: np.ndarray,
    ones: np.ndarray,
    boundary: np.ndarray | None = None,
    biases: np.ndarray | None = None,
    state_biases: np.ndarray | None = None,
    elevator: np.ndarray | None = None,
) -> np.ndarray:
    """Model output spectra ``y = G u + H d + b 1 + P f 1 + G_de (b_de 1 + e)`` (Eqs. 18-19, sections 7, 7a).

    Parameters
    ----------
    response : ModelResponse or any object with ``G``, ``H``, ``P``
        ``G`` of shape (..., m, n_y, n_in), ``H`` (..., m, n_y, n_b) and ``P`` (..., m, n_y, 2); any
        leading axes (e.g. one per parameter for derivatives of the response)
        broadcast.  ``H`` is read only with ``boundary``, ``P`` only with
        ``state_biases``.
    u : ndarray, complex, shape (m, n_in)
        Input spectra (elevator rad s, gust angle rad s).
    ones : ndarray, complex, shape (m,)
        Transform of a unit constant over the record, s.
    boundary : ndarray, complex, shape (m, n_b), optional
        Boundary vector d (:func:`boundary_vector`); None for no boundary terms.
    biases : ndarray, shape (n_y,), optional
        Output biases (alpha rad, q rad/s, a_z g, ...).  Leave None for the
        derivative of ``y`` with respect to a model parameter: the result is
        then linear in ``response``.
    state_biases : ndarray, shape (2,), optional
        Constants f added to the alpha_dot (rad/s) and q_dot (rad/s^2)
        equations: a constant forcing, whose transform is ``f 1(w)``.
    elevator : ndarray, complex, shape (m,), optional
        What the nuisance terms add to the elevator's spectrum (an offset, the step
        edges' timing: :meth:`Nuisance.elevator`), rad s, entering through G's elevator column.

    Returns
    -------
    ndarray, complex, shape (..., m, n_y)
        The output spectra alpha (rad s), q (rad), a_z (g s), ...
    """
    G = response.G
    y = (G @ u[:, :, None])[..., 0]
    if boundary is not None:
        y = y + (response.H @ boundary[:, :, None])[..., 0]
    if biases is not None:
        y = y + ones[:, None] * biases[None, :]
    if state_biases is not None:
        y = y + (response.P @ state_biases) * ones[:, None]  # f~ = f 1(w)
    if elevator is not None:
        y = y + G[..., 0] * elevator[:, None]  # elevator de + b_de 1 + e
    return y


def nuisance_columns(response, shift: np.ndarray, ones: np.ndarray, basis: np.ndarray | None = None) -> np.ndarray:
    """Exact sensitivities ``dy/d eta`` of :func:`predict` to the nuisance values.

    Columns in :func:`nuisance_names` order of the response's rows: output biases ``e_k 1(w)``;
    x(0): ``H``; x(T): ``-H exp(-j w T)`` (from ``d = x(0) - x(T) exp(-j w T)``);
    state-equation biases ``P 1(w)``; elevator offset ``G_de 1(w)``; then, with ``basis``,
    the step edges' timing terms ``G_de basis_k`` (:func:`edge_names` order).  Every
    term is linear in its value, so ``predict`` with nuisance values ``eta``
    equals ``predict`` with none plus ``nuisance_columns @ eta``.

    Parameters
    ----------
    response : ModelResponse
        ``G`` (m, n_y, n_in), ``H`` (m, n_y, n_b) and ``P`` (m, n_y, 2).
    shift : ndarray, complex, shape (m,)
        ``exp(-j w T)`` (:func:`end_shift`).
    ones : ndarray, complex, shape (m,)
        Transform of a unit constant, s.
    basis : ndarray, complex, shape (m, K), optional
        The record's :func:`edge_basis` (rad per s of timing).

    Returns
    -------
    ndarray, complex, shape (m, n_y, n_y + 2 n_b + 3 + K)
        Per frequency and output, the derivative with respect to each nuisance value.
    """
    m = shift.size
    ny, nb = response.H.shape[1:]
    b = ny + 2 * nb  # first state bias
    C = np.zeros((m, ny, b + 3), complex)
    k = np.arange(ny)
    C[:, k, k] = ones[:, None]
    C[:, :, ny : ny + nb] = response.H
    C[:, :, ny + nb : b] = -response.H * shift[:, None, None]
    C[:, :, b : b + 2] = response.P * ones[:, None, None]
    C[:, :, b + 2] = response.G[:, :, 0] * ones[:, None]
    if basis is not None and basis.shape[1]:  # the step edges' timing terms (section 7a)
        C = np.concatenate([C, response.G[:, :, :1] * basis[:, None, :]], axis=2)
    return C
