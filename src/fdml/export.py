"""Export fitted models to python-control.

* :func:`to_frd` - a ``control.FrequencyResponseData`` of G(j omega) for every
  model (the unsteady one included), at given frequencies;
* :func:`to_statespace` - a ``control.StateSpace`` for the rational models
  (``steady``, ``derivatives``, ``dimensional``), with named signals:
  outputs ``alpha`` (rad), ``q`` (rad/s), ``az`` (g); inputs ``de`` and, for
  a gust model, ``alpha_w`` (rad); states ``alpha``, ``q``.

The ``unsteady`` model has no finite-state form: the F term of the downwash
(THEORY.md Eq. 2, section 4) behaves like ``s ln s``; use :func:`to_frd`.
Input delays (``tau_de``, ``tau_alpha_w``) are not rational either:
:func:`to_statespace` refuses them unless asked for a Pade approximation.
"""

from __future__ import annotations

import numpy as np

from .constants import G0
from .errors import ParameterError

__all__ = ["to_frd", "to_statespace", "descriptor_matrices"]

_OUTPUTS = ("alpha", "q", "az")
_RATIONAL = ("steady", "derivatives", "dimensional")


def _model_of(obj):
    """The model of a FitResult (at the estimate), or the model itself."""
    from .models.base import Model

    if isinstance(obj, Model):
        return obj
    model = getattr(obj, "model", None)
    if isinstance(model, Model):
        return model
    raise ParameterError(f"expected an fdml FitResult or Model, got {type(obj).__name__}")


def to_frd(result_or_model, omega=None, *, name: str | None = None):
    """G(j omega) of a fitted (or any) model as a ``control.FrequencyResponseData``.

    Parameters
    ----------
    result_or_model : FitResult or Model
        A fit's model is taken at the estimate.
    omega : array_like, optional
        Frequencies, rad/s (positive).  Default for a fit: the frequencies of
        its first record; required for a model.
    name : str, optional
        System name (default ``"fdml <kind>"``).

    Returns
    -------
    control.FrequencyResponseData
        Outputs ``alpha`` (rad), ``q`` (rad/s), ``az`` (g); inputs ``de``
        [, ``alpha_w``] (rad); the response is exactly
        ``model.frequency_response(omega)`` (frequencies sorted ascending, as
        python-control stores them).  Output biases, boundary terms and
        nuisance terms are not part of G.
    """
    import control

    model = _model_of(result_or_model)
    if omega is None:
        spectra = getattr(result_or_model, "spectra", None)
        if not spectra:
            raise ParameterError("to_frd needs omega (rad/s) for a model")
        omega = spectra[0]["omega"]
    omega = np.sort(np.atleast_1d(np.asarray(omega, dtype=float)))
    if omega.size == 0 or not np.all(np.isfinite(omega)) or np.any(omega <= 0):
        raise ParameterError("omega must hold finite positive frequencies (rad/s)")
    G = model.frequency_response(omega)
    return control.FrequencyResponseData(G, omega, inputs=list(model.inputs), outputs=list(_OUTPUTS),
                                         name=name or f"fdml {model.kind}")


def descriptor_matrices(model, values=None):
    """``E, A, B0, B1`` of ``E x' = A x + B0 u + B1 u'`` (x = [alpha, q]) for a rational model.

    Read off the model's own ``M(s) = s E - A`` and ``B(s) = B0 + s B1`` at
    s = 0 and 1, and checked at a third point (so a model whose matrices are
    not affine in s is refused rather than misread).  Input delays are not
    included.

    Parameters
    ----------
    model : Model
        ``steady``, ``derivatives`` or ``dimensional``.
    values : mapping, optional
        Parameter values overriding the model's.

    Returns
    -------
    E, A, B0, B1 : ndarray
        Shapes (2, 2), (2, 2), (2, n_in), (2, n_in).
    """
    if model.kind not in _RATIONAL:
        raise ParameterError(_not_rational(model))
    p = model.values(values)
    s = np.array([0.0, 1.0, -2.5 + 0.7j], dtype=complex)
    M, B, E = model._matrices(s, p)
    A = -M[0]
    E_m = M[1] - M[0]
    B0, B1 = B[0], B[1] - B[0]
    scale = max(np.abs(M).max(), np.abs(B).max(), 1.0)
    if (np.abs(M[2] - (s[2] * E_m - A)).max() > 1e-12 * scale
            or np.abs(B[2] - (B0 + s[2] * B1)).max() > 1e-12 * scale
            or np.abs(np.asarray(E) - E_m).max() > 1e-12 * max(np.abs(E_m).max(), 1.0)):
        raise ParameterError(f"the {model.kind} model's matrices are not affine in s: no state-space form")
    return np.real(E_m), np.real(A), np.real(B0), np.real(B1)


def _not_rational(model) -> str:
    return (f"the {model.kind} model has no finite-state form "
            + ("(the downwash F term of THEORY.md Eq. 2 behaves like s ln s); " if model.kind == "unsteady" else "; ")
            + "use fdml.export.to_frd(result, omega) for its frequency response")


def to_statespace(result_or_model, *, pade: int | None = None, name: str | None = None):
    """A rational model as a ``control.StateSpace`` with named signals.

    The model ``E x' = A x + B0 u + B1 u'`` (x = [alpha, q]; E differs from
    the identity with alpha-dot derivatives, B1 is nonzero only for a gust
    model with them) becomes, with ``x = xi + E^-1 B1 u``,

        xi' = E^-1 A xi + E^-1 (B0 + A E^-1 B1) u
        [alpha, q] = xi + E^-1 B1 u,   a_z = (U/g)(alpha' - q)    (THEORY.md Eq. 5)

    so the states are alpha and q themselves whenever B1 = 0 (then named
    ``alpha``, ``q``; otherwise ``xi_alpha``, ``xi_q``).

    Parameters
    ----------
    result_or_model : FitResult or Model
        ``steady``, ``derivatives`` or ``dimensional``; a fit's model is taken
        at the estimate.
    pade : int, optional
        Order of a Pade approximation of nonzero input delays (``tau_de``,
        ``tau_alpha_w``), placed in series with each delayed input (its
        states are named ``<input>_delay<i>``).  Without it a nonzero delay
        raises.
    name : str, optional
        System name (default ``"fdml <kind>"``).

    Returns
    -------
    control.StateSpace
        Outputs ``alpha`` (rad), ``q`` (rad/s), ``az`` (g); inputs ``de``
        [, ``alpha_w``] (rad).  Its frequency response equals
        ``model.frequency_response`` (to rounding; exactly so only without
        delays).

    Raises
    ------
    ParameterError
        An unsteady model (use :func:`to_frd`); a nonzero delay without
        ``pade``; a gust model with ``Cz_adot != 0``, whose a_z responds to
        the rate of alpha_w (G grows like s: improper).
    """
    import control

    model = _model_of(result_or_model)
    if model.kind not in _RATIONAL:
        raise ParameterError(_not_rational(model))
    E, A, B0, B1 = descriptor_matrices(model)
    Ei = np.linalg.inv(E)
    k = model.U / G0  # Eq. 5
    D12 = Ei @ B1  # x = xi + D12 u
    if np.any(D12[0] != 0.0):
        raise ParameterError(
            "a_z = (U/g)(alpha_dot - q) of this model responds to the rate of alpha_w (Cz_adot != 0 with a "
            "gust input): the system is improper and has no state-space form; use fdml.export.to_frd")
    Ax = Ei @ A
    Bx = Ei @ (B0 + A @ D12)
    C = np.zeros((3, 2))
    D = np.zeros((3, B0.shape[1]))
    C[:2] = np.eye(2)
    D[:2] = D12
    C[2] = k * (Ax[0] - C[1])  # alpha' = xi_alpha' (D12[0] = 0)
    D[2] = k * (Bx[0] - D[1])
    states = ["alpha", "q"] if not np.any(D12) else ["xi_alpha", "xi_q"]
    inputs = list(model.inputs)
    sysname = name or f"fdml {model.kind}"
    sys = control.StateSpace(Ax, Bx, C, D, inputs=inputs, outputs=list(_OUTPUTS), states=states,
                             name=sysname)
    p = model.values()
    delays = {"de": p["tau_de"], "alpha_w": p.get("tau_alpha_w", 0.0)}
    if not any(delays[i] for i in inputs):
        return sys
    if pade is None:
        named = ", ".join(f"tau_{i} = {delays[i]:g} s" for i in inputs if delays[i])
        raise ParameterError(f"the model has input delays ({named}), which are not rational: pass pade=N "
                             "for a Pade approximation of order N, or use fdml.export.to_frd")
    if int(pade) != pade or pade < 1:
        raise ParameterError(f"pade must be a positive integer order, got {pade!r}")
    # delay block: one Pade approximant per delayed input, block-diagonal, states named
    from scipy.linalg import block_diag

    As, Bs, Cs, Ds, names = [], [], [], [], []
    for i in inputs:
        if delays[i]:
            num, den = control.pade(delays[i], int(pade))
            blk = control.ss(control.tf(num, den))
            As.append(blk.A)
            Bs.append(blk.B)
            Cs.append(blk.C)
            Ds.append(blk.D)
            names += [f"{i}_delay{j}" for j in range(blk.nstates)]
        else:
            As.append(np.zeros((0, 0)))
            Bs.append(np.zeros((0, 1)))
            Cs.append(np.zeros((1, 0)))
            Ds.append(np.eye(1))
    delay = control.StateSpace(block_diag(*As), block_diag(*Bs), block_diag(*Cs), block_diag(*Ds),
                               inputs=inputs, outputs=inputs, states=names, name="delays")
    # x' = [sys; delay]: the plant keeps its states first
    na, nd = sys.nstates, delay.nstates
    Af = np.block([[sys.A, sys.B @ delay.C], [np.zeros((nd, na)), delay.A]])
    Bf = np.vstack([sys.B @ delay.D, delay.B])
    Cf = np.hstack([sys.C, sys.D @ delay.C])
    Df = sys.D @ delay.D
    return control.StateSpace(Af, Bf, Cf, Df, inputs=inputs, outputs=list(_OUTPUTS),
                              states=list(sys.state_labels) + names, name=sysname)
