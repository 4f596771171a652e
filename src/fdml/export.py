"""Export fitted models to python-control.

* :func:`to_frd` - a ``control.FrequencyResponseData`` of G(j omega) for every
  model (the unsteady one and every effect included; delays exact), at given
  frequencies;
* :func:`to_statespace` - a ``control.StateSpace`` of the model's own
  finite-state realisation (:func:`fdml.models.realize`, composed through
  its effects), with named signals: outputs ``alpha`` (rad), ``q`` (rad/s),
  ``az`` (g); inputs ``de`` and, for a gust model, ``alpha_w`` (rad);
* :func:`to_control` - either, with a record of how delays were treated
  (exact in a frequency response, or a Pade approximation of a given order).

The ``unsteady`` model with F != 0 has no finite-state form: the F term of the
downwash (docs/theory.md Eq. 2, section 4) behaves like ``s ln s``; use :func:`to_frd`.
Pure delays (``tau_de``, ``tau_alpha_w``, sensor delays) are not rational either:
:func:`to_statespace` refuses them unless asked for a Pade approximation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ParameterError
from .models.base import DescriptorModel, Model
from .models.realization import realize

__all__ = ["to_frd", "to_statespace", "to_control", "ControlExport", "descriptor_matrices"]

_RATIONAL = ("steady", "derivatives", "dimensional")


def _model_of(obj):
    """The model of a FitResult (at the estimate), or the model itself."""
    for candidate in (obj, getattr(obj, "model", None)):
        if isinstance(candidate, Model):
            return candidate
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
        omega = spectra[0].omega
    omega = np.sort(np.atleast_1d(np.asarray(omega, dtype=float)))
    if omega.size == 0 or not np.all(np.isfinite(omega)) or np.any(omega <= 0):
        raise ParameterError("omega must hold finite positive frequencies (rad/s)")
    G = model.frequency_response(omega)
    return control.FrequencyResponseData(
        G, omega, inputs=list(model.inputs), outputs=list(model.outputs), name=name or f"fdml {model.kind}"
    )


def descriptor_matrices(model, values=None):
    """``E, A, B0, B1`` of ``E x' = A x + B0 u + B1 u'`` (x = [alpha, q]) for a rational model.

    A descriptor model's own descriptor (:meth:`fdml.models.base.DescriptorModel.descriptor`);
    for the ``steady`` model its finite-state form ``x' = A x + B u`` (E = I,
    :func:`fdml.models.realize`).  Input delays are not included.

    Parameters
    ----------
    model : Model
        ``steady``, ``derivatives`` or ``dimensional``.
    values : mapping, optional
        Parameter values overriding the model's.

    Returns
    -------
    E : ndarray
        Shape (2, 2).
    A : ndarray
        Shape (2, 2).
    B0 : ndarray
        Shape (2, n_in).
    B1 : ndarray
        Shape (2, n_in).
    """
    if model.kind not in _RATIONAL:
        raise ParameterError(_not_rational(model))
    if isinstance(model, DescriptorModel):
        d = model.descriptor(values)
        return d.E, d.A, d.B0, d.B1
    real = realize(model.with_outputs(()), values)  # the steady model: x = [alpha, q], no input rates
    return np.eye(2), real.A, real.B, np.zeros_like(real.B)


def _not_rational(model) -> str:
    return (
        f"the {model.kind} model has no finite-state form "
        + ("(the downwash F term of docs/theory.md Eq. 2 behaves like s ln s); " if model.kind == "unsteady" else "; ")
        + "use fdml.export.to_frd(result, omega) for its frequency response"
    )


def to_statespace(result_or_model, *, pade: int | None = None, name: str | None = None):
    """A model as a ``control.StateSpace`` with named signals, from :func:`fdml.models.realize`.

    The realisation is the one :func:`fdml.simulate.simulate` integrates,
    composed through the model's effects: for the conventional models the
    descriptor form ``E x' = A x + B0 u + B1 u'`` with ``x = xi + E^-1 B1 u``,

        xi' = E^-1 A xi + E^-1 (B0 + A E^-1 B1) u
        [alpha, q] = xi + E^-1 B1 u,   a_z = (U/g)(alpha' - q)    (docs/theory.md Eq. 5)

    so the states are alpha and q themselves whenever B1 = 0 (then named
    ``alpha``, ``q``; otherwise ``xi_alpha``, ``xi_q``); effects and lags add
    states ``x2``, ``x3``, ...

    Parameters
    ----------
    result_or_model : FitResult or Model
        A finite-state model (every kind except ``unsteady`` with F != 0); a
        fit's model is taken at the estimate.
    pade : int, optional
        Order of a Pade approximation of the pure delays (input delays
        ``tau_de``, ``tau_alpha_w``, the tail gust delay, sensor delays of an
        effect), placed in series with each delayed input or output (states
        ``<signal>_delay<i>``).  Without it a nonzero delay raises.
    name : str, optional
        System name (default ``"fdml <kind>"``).

    Returns
    -------
    control.StateSpace
        Outputs ``alpha`` (rad), ``q`` (rad/s), ``az`` (g); inputs ``de``
        [, ``alpha_w``] (rad).  Its frequency response equals
        ``model.frequency_response`` (to rounding; exactly so only without
        delays).  :func:`to_control` also says whether delays were approximated.

    Raises
    ------
    ParameterError
        No finite-state form (use :func:`to_frd`); a nonzero delay without
        ``pade``; an improper response (a gust model with ``Cz_adot != 0``,
        whose a_z responds to the rate of alpha_w).
    """
    import control

    model = _model_of(result_or_model)
    try:
        real = realize(model)
    except ParameterError as exc:
        if "finite-state" in str(exc):
            raise ParameterError(_not_rational(model)) from None
        raise
    if np.any(real.Dd):
        raise ParameterError(
            "a_z = (U/g)(alpha_dot - q) of this model responds to the rate of alpha_w (Cz_adot != 0 with a "
            "gust input): the system is improper and has no state-space form; use fdml.export.to_frd"
        )
    inputs = list(model.inputs)
    plain = np.array_equal(real.C[:2, :2], np.eye(2)) and not np.any(real.D[:2])  # the states are alpha and q
    states = (["alpha", "q"] if plain else ["xi_alpha", "xi_q"]) + [f"x{i}" for i in range(2, real.states)]
    sysname = name or f"fdml {model.kind}"
    chans = [f"u{j}" for j in range(len(real.channels))]
    plant = control.StateSpace(
        real.A, real.B, real.C, real.D, inputs=chans, outputs=list(real.outputs), states=states, name=sysname
    )
    delays = [d for _, d in real.channels] + list(real.output_delays)
    if any(delays) and pade is None:
        raise ParameterError(
            "the model has pure delays (input or sensor), which are not rational: pass pade=N "
            "for a Pade approximation of order N, or use fdml.export.to_frd"
        )
    if pade is not None and (int(pade) != pade or pade < 1):
        raise ParameterError(f"pade must be a positive integer order, got {pade!r}")
    # inputs -> channels: each channel is its signal through its delay (identity when undelayed)
    spread = np.array([[1.0 if nm == sig else 0.0 for sig in inputs] for nm, _ in real.channels])
    ind = _delay_block([d for _, d in real.channels], [f"{nm}_delay" for nm, _ in real.channels], pade)
    outd = _delay_block(list(real.output_delays), [f"{o}_delay" for o in real.outputs], pade)
    A, B, C, D, names = _series(ind, (plant.A, plant.B, plant.C, plant.D, states), outd)
    return control.StateSpace(
        A, B @ spread, C, D @ spread, inputs=inputs, outputs=list(real.outputs), states=names, name=sysname
    )


def _delay_block(delays, labels, pade):
    """Block-diagonal Pade approximants of ``delays`` (identity where zero): (A, B, C, D, state names)."""
    import control
    from scipy.linalg import block_diag

    blocks, names = [], []  # (A, B, C, D) of each signal's block
    for d, lab in zip(delays, labels):
        if d:
            blk = control.ss(control.tf(*control.pade(d, int(pade))))
            blocks.append((blk.A, blk.B, blk.C, blk.D))
            names += [f"{lab}{j}" for j in range(blk.nstates)]
        else:
            blocks.append((np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.eye(1)))
    A, B, C, D = (block_diag(*(b[i] for b in blocks)) for i in range(4))
    return A, B, C, D, names


def _series(first, second, third):
    """State space of ``third(second(first(u)))``; the plant's (second) states come first."""
    A1, B1, C1, D1, n1 = first
    A2, B2, C2, D2, n2 = second
    A3, B3, C3, D3, n3 = third
    k1, k2, k3 = A1.shape[0], A2.shape[0], A3.shape[0]
    A = np.zeros((k1 + k2 + k3,) * 2)
    A[:k2, :k2] = A2
    A[:k2, k2 : k2 + k1] = B2 @ C1
    A[k2 : k2 + k1, k2 : k2 + k1] = A1
    A[k2 + k1 :, :k2] = B3 @ C2
    A[k2 + k1 :, k2 : k2 + k1] = B3 @ D2 @ C1
    A[k2 + k1 :, k2 + k1 :] = A3
    B = np.vstack([B2 @ D1, B1, B3 @ D2 @ D1])
    C = np.hstack([D3 @ C2, D3 @ D2 @ C1, C3])
    D = D3 @ D2 @ D1
    return A, B, C, D, list(n2) + list(n1) + list(n3)


@dataclass(frozen=True)
class ControlExport:
    """A python-control system and how its delays were treated.

    Parameters
    ----------
    system : control.FrequencyResponseData or control.StateSpace
        The exported system (input de rad; outputs alpha rad, q rad/s, a_z g).
    form : {"frd", "statespace"}
        Which of the two it is.
    delays : {"none", "exact", "pade"}
        ``"exact"``: a frequency response holds every delay exactly;
        ``"pade"``: the state space approximates them (order ``pade_order``).
    pade_order : int or None
        Order of the Pade approximation, when one was used.
    """

    system: object
    form: str
    delays: str
    pade_order: int | None = None


def to_control(
    result_or_model, *, form: str = "frd", omega=None, pade: int | None = None, name: str | None = None
) -> ControlExport:
    """Export to python-control, saying how delays were treated (see :class:`ControlExport`).

    Parameters
    ----------
    result_or_model : FitResult or Model
        A fit's model is taken at the estimate.
    form : {"frd", "statespace"}
        A frequency response (delays exact; needs ``omega`` for a model) or a
        state space (delays by a Pade approximation of order ``pade``).
    omega : array_like, optional
        Frequencies of the frequency response, rad/s (as :func:`to_frd`).
    pade : int, optional
        Order of the Pade approximation of the delays of a state space (as
        :func:`to_statespace`); required when the model has delays.
    name : str, optional
        System name (default ``"fdml <kind>"``).

    Returns
    -------
    ControlExport
        The system, its form and how its delays were treated.
    """
    model = _model_of(result_or_model)
    if form not in ("frd", "statespace"):
        raise ParameterError(f"form must be 'frd' or 'statespace', got {form!r}")
    has = _has_delays(model)
    if form == "frd":
        return ControlExport(to_frd(result_or_model, omega, name=name), "frd", "exact" if has else "none")
    sys = to_statespace(result_or_model, pade=pade if has else None, name=name)
    # with delays, to_statespace has refused pade=None
    return ControlExport(sys, "statespace", "pade" if has else "none", int(pade) if has and pade is not None else None)


def _has_delays(model) -> bool:
    try:
        real = realize(model)
    except ParameterError:
        return True  # no finite-state form (the F term): only the exact frequency response exists
    return any(d for _, d in real.channels) or any(real.output_delays)
