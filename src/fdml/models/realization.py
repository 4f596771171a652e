"""Finite-state realisation of a model, composed through its effects.

The state space every model kind and effect builds (:class:`Realization`,
:func:`realize`): the base model's (the descriptor a
:class:`~fdml.models.base.DescriptorModel` gives, the Wells-Keskar finite-state form
of docs/theory.md section 4 with the gust lags of section 8), the matrix-level
effects inside it, the output rows of :data:`fdml.channels.OUTPUT_TABLE` (an
integrator state per integral output, theta), then the output-level effects by the
state-space algebra below.  It lives in the model layer, below
:mod:`fdml.models.effects` and :mod:`fdml.simulate` (the time-domain simulator
that integrates it), so that the effects and the models reach it without
importing upward.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..aero import get_indicial, positive_pole_time
from ..channels import OUTPUTS
from ..errors import ParameterError
from .augment import MatrixEffect, applied_effects, root_model
from .base import Descriptor, output_rows

__all__ = [
    "Descriptor",
    "Realization",
    "realize",
    "add_mode",
    "delay_output",
    "filter_input",
    "scale_output",
]


# --- the linear system ---------------------------------------------------------------


@dataclass(frozen=True)
class _System:
    """``x' = A x + B u + bF eps_F``, ``y = C x + D u + Dd u' + dF eps_F`` (y: the rows ``outputs``).

    ``u`` are the input channels ``(signal name, delay s)``.  When ``kappa`` is
    nonzero, ``eps_F = kappa PV int alpha_dot(tau)/(t - tau - T) dtau`` with
    ``alpha_dot = rx x + ru u + rF eps_F``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    Dd: np.ndarray
    channels: tuple
    bF: np.ndarray
    dF: np.ndarray
    rx: np.ndarray
    ru: np.ndarray
    rF: float = 0.0
    T: float = 0.0
    kappa: float = 0.0
    #: Pure delays of the outputs, s: y_i(t) = (C x + D u + ...)_i(t - d_i).
    out_delay: tuple = (0.0, 0.0, 0.0)
    #: The output rows, in order.
    outputs: tuple = OUTPUTS


def _with_outputs(A, B, bF, value, rate, rows, U, p) -> dict:
    """The output rows of ``rows`` (:func:`fdml.models.base.output_rows`) on ``x' = A x + B u + bF eps_F``.

    ``value`` and ``rate`` (2, ns + 2 nu + 1) are the linear forms of (alpha, q) and
    of (alpha', q') over [x | u | u' | eps_F].  Each integral row gets a state
    ``z' = i . (alpha, q)`` from rest, appended after the others.  Returns the
    ``_System`` fields A, B, bF, C, D, Dd, dF, out_delay, outputs.
    """
    ns, nu = B.shape
    V, R, I = output_rows(rows, U, p)
    Y = V @ value + R @ rate
    own = np.flatnonzero(I.any(axis=1))
    Z = I[own] @ value  # the integrators' derivatives, over [x | u | u' | eps_F] (no u', no eps_F)
    k = own.size
    A2 = np.pad(A, (0, k))
    A2[ns:, :ns] = Z[:, :ns]
    Cz = np.zeros((len(rows), k))
    Cz[own, np.arange(k)] = 1.0
    return dict(
        A=A2,
        B=np.vstack([B, Z[:, ns : ns + nu]]),
        bF=np.concatenate([bF, np.zeros(k)]),
        C=np.hstack([Y[:, :ns], Cz]),
        D=Y[:, ns : ns + nu],
        Dd=Y[:, ns + nu : ns + 2 * nu],
        dF=Y[:, -1],
        out_delay=(0.0,) * len(rows),
        outputs=tuple(rows),
    )


def _from_descriptor(d: Descriptor, model, p) -> _System:
    """Proper state space of ``E x' = A x + B0 u + B1 u'`` (x_0 = alpha, x_1 = q) with ``model``'s outputs.

    With ``xi = x - E^-1 B1 u``: ``xi' = E^-1 A xi + E^-1 (B0 + A E^-1 B1) u``,
    so the states never see u' (and are alpha, q themselves when B1 = 0).  Only
    an output of the states' rates (a_z, q_dot) keeps a direct feedthrough of u'
    when B1 is nonzero.
    """
    E, A, B0, B1 = d.E, d.A, d.B0, d.B1
    Ei = np.linalg.inv(E)
    n, nu = B0.shape
    Ax = Ei @ A
    D12 = Ei @ B1  # x = xi + D12 u
    Bx = Ei @ (B0 + A @ D12)
    value = np.hstack([np.eye(n)[:2], D12[:2], np.zeros((2, nu + 1))])
    rate = np.hstack([Ax[:2], Bx[:2], D12[:2], np.zeros((2, 1))])
    out = _with_outputs(Ax, Bx, np.zeros(n), value, rate, model.outputs, model.U, p)
    return _System(channels=tuple(d.channels), rx=np.zeros(out["A"].shape[0]), ru=np.zeros(nu), **out)


def _conventional_system(model, p, matrix_effects=()) -> _System:
    """A :class:`~fdml.models.base.DescriptorModel`'s own descriptor, with matrix-level effects."""
    d = model._descriptor(p)
    for eff in matrix_effects:
        d = eff.realize(d, p, model)
    return _from_descriptor(d, model, p)


def _wells_keskar_system(model, p, matrix_effects=()) -> _System:
    """``unsteady`` (docs/theory.md section 4 finite-state form, section 8 gust) and ``steady``.

    Mirrors models/wells_keskar.py term by term:
    C_Lw = N_w alpha + a_w K alpha_g;  eps = E alpha + eps_ss K D alpha_g;
    C_Lt = N_t (alpha - eps + (l/U) q) + a_t K D alpha_g,  D = exp(-s l/U).
    """
    ac = model.aircraft
    U, c = ac.U, ac.c_w
    kz, km = ac.k_z, ac.k_m
    sr = ac.S_t / ac.S_w
    l = p["l_t"]
    a_w, a_t, eps_ss = p["CLa_w"], p["CLa_t"], p["deps_da"]
    y_w, y_t, G, F, lam_w, lam_t, lam_G = _lags(model, p)
    tail_delay, tail_tau, post = _tail_gust_delay(model, p, matrix_effects)
    channels = [("de", p["tau_de"])]
    if model.gust:
        channels.append(("alpha_w", p["tau_alpha_w"]))
        if tail_delay:
            channels.append(("alpha_w", p["tau_alpha_w"] + tail_tau))
    # --- states: alpha, q, the lift and downwash lags that are present, gust lags
    names = ["alpha", "q"] + [name for name, amp in (("x_w", y_w), ("x_t", y_t), ("x_G", G)) if amp != 0.0]
    gust_terms = _gust_terms(model, p) if model.gust else (1.0, [])  # (unused without gust input)
    if model.gust:
        for s in ("w", "t") if tail_delay else ("w",):
            names += [f"g{s}{i}" for i in range(len(gust_terms[1]))]
    ns, nu = len(names), len(channels)
    # linear forms over the vector [states | input channels | eps_F]: rows of the identity, a state not present zero
    unit, zero = np.eye(ns + nu + 1), np.zeros(ns + nu + 1)
    ix = {n: i for i, n in enumerate(names)}
    X = lambda n: unit[ix[n]] if n in ix else zero  # noqa: E731
    alpha, q = X("alpha"), X("q")
    dyn: dict = {}
    g_w, g_t = _gust_rows(unit[ns:], X, gust_terms, tail_delay, dyn) if model.gust else (zero, zero)
    # Eq. 17 / section 4: C_Lw = a_w[(1 - y_w) alpha + y_w x_w] (+ a_w K alpha_g, section 8)
    CLw = a_w * ((1.0 - y_w) * alpha + y_w * X("x_w")) + a_w * g_w
    # Eq. 16 / section 4: eps = eps_ss[(1 - G) alpha + G x_G] + eps_F (+ eps_ss K D alpha_g)
    eps = eps_ss * ((1.0 - G) * alpha + G * X("x_G")) + eps_ss * g_t + unit[-1]
    beta = alpha - eps + (l / U) * q  # Eq. 9: tail angle alpha - eps + l q / U
    CLt = a_t * ((1.0 - y_t) * beta + y_t * X("x_t")) + a_t * g_t
    Cz = -CLw - sr * CLt + p["Cz_de"] * unit[ns]  # Eq. 6
    Cm = -(l * sr / c) * CLt + p["Cm_de"] * unit[ns]  # Eq. 7
    dyn["alpha"] = q + kz * Cz  # Eq. 3
    dyn["q"] = km * Cm  # Eq. 4
    dyn["x_w"] = lam_w * (alpha - X("x_w"))
    dyn["x_t"] = lam_t * (beta - X("x_t"))
    dyn["x_G"] = lam_G * (alpha - X("x_G"))
    rows = np.array([dyn[n] for n in names])
    T, kappa = _downwash_pole(l, c, U, eps_ss, F)
    # (alpha, q) and their rates over [x | u | u' | eps_F]: no input rates in this form
    value, rate = (np.insert(f, [ns + nu] * nu, 0.0, axis=1) for f in (np.array([alpha, q]), rows[:2]))
    out = _with_outputs(rows[:, :ns], rows[:, ns : ns + nu], rows[:, -1], value, rate, model.outputs, U, p)
    rx = np.zeros(out["A"].shape[0])
    rx[:ns] = dyn["alpha"][:ns]
    sys = _System(
        channels=tuple(channels),
        rx=rx,
        ru=dyn["alpha"][ns : ns + nu],
        rF=float(dyn["alpha"][-1]),
        T=T,
        kappa=kappa,
        **out,
    )
    for fn in post:
        sys = fn(sys)
    return sys


def _lags(model, p) -> tuple[float, ...]:
    """(y_w, y_t, G, F, lam_w, lam_t, lam_G): the lag amplitudes and rates, all zero for ``steady``."""
    if model.kind == "steady":
        return (0.0,) * 7
    U, c = model.aircraft.U, model.aircraft.c_w
    c_tail = c if model.tail_lag_chord == "c_w" else model.aircraft.c_t
    lam_w = 2.0 * p["z_w"] * U / c  # Eq. 17, wing: 2 z_w U / c_w
    lam_t = 2.0 * p["z_t"] * U / c_tail  # Eq. 17, tail (c_w as printed, or c_t)
    lam_G = 2.0 * p["H"] * U / c  # Eq. 16: 2 H U / c_w
    return p["y_w"], p["y_t"], p["G"], p["F"], lam_w, lam_t, lam_G


def _tail_gust_delay(model, p, matrix_effects) -> tuple[bool, float, tuple]:
    """(the tail sees the gust delayed, its delay s, callables on the finished system) after the matrix effects."""
    tail_delay = model.kind != "steady" and model.tail_gust_delay
    tail_tau = p["l_t"] / model.aircraft.U  # BS-8: tau_t = l/U
    opts: dict = {}
    for eff in matrix_effects:  # e.g. gust_lag@tail: {"tail_tau": tau_tail}
        opts = eff.realize(opts, p, model)
    if "tail_tau" in opts:
        tail_delay, tail_tau = True, opts.pop("tail_tau")
    post = opts.pop("system", ())  # e.g. downwash_lag@tail: callables on the finished system
    if opts:
        raise ParameterError(f"the {model.kind} model cannot realise {sorted(opts)}")
    return tail_delay, tail_tau, post


def _gust_terms(model, p) -> tuple[float, list[tuple[float, float]]]:
    """(feedthrough, [(amplitude, rate)]) of the gust lag K(s)."""
    U, c = model.aircraft.U, model.aircraft.c_w
    if model.kind == "steady":
        return (1.0, [])
    if model.gust_lag == "bs12":
        if p["b1"] < 0:
            raise ParameterError(f"Kussner lag length b1 must be >= 0 semichords, got {p['b1']}")
        Ts = c * p["b1"] / (2.0 * U)  # BS-12: T* = c b1 / (2U)
        return (1.0, []) if Ts == 0.0 else (0.0, [(1.0, 1.0 / Ts)])
    # K(s) = 1 - sum A_i s/(s + r_i) = (1 - sum A_i) + sum A_i r_i/(s + r_i)
    fn = get_indicial(model.gust_lag)
    rates = [2.0 * b * U / c for b in fn.rates]
    return (1.0 - sum(fn.amplitudes), [(A, r) for A, r in zip(fn.amplitudes, rates) if A != 0.0])


def _gust_rows(u, X, gust_terms, tail_delay: bool, dyn: dict) -> tuple:
    """Rows of K alpha_g at the wing and the tail (``u``: the input channels' forms); the gust lag states' rows
    go into ``dyn``."""
    inputs = {"w": u[1], "t": u[2] if tail_delay else u[1]}
    ff, terms = gust_terms
    g_rows = {}
    for s in ("w", "t") if tail_delay else ("w",):
        g = ff * inputs[s]
        for i, (A_i, r_i) in enumerate(terms):  # BS-16: Y' = (alpha_w - Y)/T*
            st = X(f"g{s}{i}")
            g = g + A_i * st
            dyn[f"g{s}{i}"] = r_i * (inputs[s] - st)
        g_rows[s] = g
    return g_rows["w"], g_rows.get("t", g_rows["w"])


def _downwash_pole(l: float, c: float, U: float, eps_ss: float, F: float) -> tuple[float, float]:
    """(T, kappa) of the downwash pole term eps_F (zero kappa without it)."""
    if F == 0.0:
        return (l - c) / U, 0.0
    return positive_pole_time(
        l, U, c
    ), eps_ss * F * c / U  # section 4: eps_F = eps_ss F (c_w/U) PV int alpha_dot/(t - tau - T)


def _system(model, p) -> _System:
    """The model's state space, composed through its effects (matrix-level, then output-level, in order)."""
    root, effects = root_model(model), applied_effects(model)
    matrix = [e for e in effects if isinstance(e, MatrixEffect)]
    kind = getattr(root, "kind", None)
    if kind in ("dimensional", "derivatives"):
        sys = _conventional_system(root, p, matrix)
    elif kind in ("unsteady", "steady"):
        sys = _wells_keskar_system(root, p, matrix)
    else:
        raise ParameterError(
            f"cannot simulate a {kind!r} model; simulate supports dimensional, derivatives, steady and unsteady"
        )
    for eff in effects:
        if not isinstance(eff, MatrixEffect):
            sys = eff.realize(sys, p, root)
    return sys


# --- state-space algebra of the output-level effects ---------------------------------------------


def _pad_states(sys: _System, k: int) -> _System:
    """``sys`` with ``k`` more states, all zero (appended after the existing ones)."""
    return replace(
        sys,
        A=np.pad(sys.A, (0, k)),  # zeros after each axis
        B=np.pad(sys.B, ((0, k), (0, 0))),
        C=np.pad(sys.C, ((0, 0), (0, k))),
        bF=np.pad(sys.bF, (0, k)),
        rx=np.pad(sys.rx, (0, k)),
    )


def delay_output(sys: _System, row: int, tau: float) -> _System:
    """Output ``row`` delayed by ``tau`` s: y_row(t - tau) (a negative tau is an advance).

    Parameters
    ----------
    sys : _System
        The finite-state system.
    row : int
        Output index (0 alpha, 1 q, 2 a_z, ... in ``sys.outputs``).
    tau : float
        Delay, s.

    Returns
    -------
    _System
        The changed copy.
    """
    d = list(sys.out_delay)
    d[row] += float(tau)
    return replace(sys, out_delay=tuple(d))


def scale_output(sys: _System, row: int, factor: float) -> _System:
    """Output ``row`` times ``factor``.

    Parameters
    ----------
    sys : _System
        The finite-state system.
    row : int
        Output index (0 alpha, 1 q, 2 a_z, ... in ``sys.outputs``).
    factor : float
        Scale factor, dimensionless.

    Returns
    -------
    _System
        The changed copy.
    """
    C, D, Dd, dF = sys.C.copy(), sys.D.copy(), sys.Dd.copy(), sys.dF.copy()
    for a in (C, D, Dd, dF):
        a[row] = a[row] * factor
    return replace(sys, C=C, D=D, Dd=Dd, dF=dF)


def filter_input(sys: _System, signal_name: str, T: float) -> _System:
    """Every channel of ``signal_name`` through ``1/(1 + T s)`` (one state per channel; T = 0: unchanged).

    With the filtered input ``v = x_f``, ``x_f' = (u - x_f)/T``, the old input
    column moves onto the new state, and a feedthrough of ``v'`` becomes
    ``(u - x_f)/T``.

    Parameters
    ----------
    sys : _System
        The finite-state system.
    signal_name : str
        The input signal (``de`` or ``alpha_w``).
    T : float
        Time constant, s.

    Returns
    -------
    _System
        The changed copy.
    """
    if T == 0.0:
        return sys
    for j, (nm, _d) in enumerate(sys.channels):
        if nm != signal_name:
            continue
        n = sys.A.shape[0]
        s2 = _pad_states(sys, 1)
        A, B, C, D, Dd = s2.A, s2.B.copy(), s2.C.copy(), sys.D.copy(), sys.Dd.copy()
        rx, ru = s2.rx.copy(), sys.ru.copy()
        A[:n, n] = sys.B[:, j]
        A[n, n] = -1.0 / T
        B[:, j] = 0.0
        B[n, j] = 1.0 / T
        C[:, n] = sys.D[:, j] - sys.Dd[:, j] / T
        D[:, j] = sys.Dd[:, j] / T
        Dd[:, j] = 0.0
        rx[n], ru[j] = sys.ru[j], 0.0
        sys = replace(s2, A=A, B=B, C=C, D=D, Dd=Dd, rx=rx, ru=ru)
    return sys


def add_mode(sys: _System, r_q: float, r_az: float, omega: float, zeta: float) -> _System:
    """A structural mode driven by the undelayed elevator: q += r_q s w/D, a_z += r_az s^2/D.

    D = s^2 + 2 zeta w s + w^2; states eta and eta' of eta = w^2/D de.

    Parameters
    ----------
    sys : _System
        The finite-state system.
    r_q : float
        Gain of the mode in q, rad/s per rad of elevator.
    r_az : float
        Gain of the mode in a_z, g per rad of elevator.
    omega : float
        Mode frequency w, rad/s.
    zeta : float
        Mode damping ratio, dimensionless.

    Returns
    -------
    _System
        The system with two more states.
    """
    if sys.out_delay[1] or sys.out_delay[2]:
        raise ParameterError("a structural mode after a q or a_z delay: list the time_delay effect after it")
    n, nu = sys.B.shape
    s2 = _pad_states(sys, 2)
    one_more = ((0, 0), (0, 1))  # a column for the undelayed elevator channel
    A, B, C, D = s2.A, np.pad(s2.B, one_more), s2.C, np.pad(sys.D, one_more)
    A[n, n + 1] = 1.0
    A[n + 1, n] = -(omega**2)
    A[n + 1, n + 1] = -2.0 * zeta * omega
    B[n + 1, nu] = omega**2
    C[1, n + 1] += r_q / omega
    C[2, n] -= r_az
    C[2, n + 1] -= 2.0 * zeta * r_az / omega
    D[2, nu] = r_az
    channels = sys.channels + (("de", 0.0),)
    return replace(s2, B=B, C=C, D=D, Dd=np.pad(sys.Dd, one_more), ru=np.append(sys.ru, 0.0), channels=channels)


@dataclass(frozen=True)
class Realization:
    """Finite-state realisation of a model: ``x' = A x + B u``, ``y = C x + D u + Dd u'``.

    Outputs y are the rows ``outputs`` (alpha rad, q rad/s, a_z g[, theta rad,
    qdot rad/s^2]); an integral output (theta) has its own integrator state,
    from rest.  The inputs u are the delayed
    input channels ``(signal, delay s)``, u_i(t) = signal(t - delay), so that
    ``G(s) = [C (sI - A)^-1 B + D + s Dd] diag(exp(-s delay))``.

    Parameters
    ----------
    A, B, C, D, Dd : ndarray
        State-space matrices (Dd is nonzero only for a gust model with
        alpha-dot derivatives, whose a_z feels alpha_w_dot directly).
    channels : tuple of (str, float)
        Input channels: signal name (``de`` or ``alpha_w``) and delay, s.
    output_delays : tuple of float
        Pure delays of the outputs, s (sensor delays): ``G_i(s)`` is
        multiplied by ``exp(-s d_i)``.
    outputs : tuple of str
        The output rows, in order.

    Attributes
    ----------
    states : int
        Number of states.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    Dd: np.ndarray
    channels: tuple
    output_delays: tuple = (0.0, 0.0, 0.0)
    outputs: tuple = OUTPUTS

    @property
    def states(self) -> int:
        """Number of states of the realization."""
        return self.A.shape[0]

    def frequency_response(self, omega) -> np.ndarray:
        """Transfer matrix per model input (de[, alpha_w]), shape (n_y, n_in, n omega).

        Parameters
        ----------
        omega : array_like
            Frequencies, rad/s.

        Returns
        -------
        numpy.ndarray
            Complex, shape (n_y, n_in, n omega): the outputs (alpha rad, q rad/s,
            a_z g, ...) per rad of elevator (or per rad of gust angle alpha_w).
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        s = 1j * omega
        I = np.eye(self.states)
        X = np.linalg.solve(s[:, None, None] * I - self.A, np.broadcast_to(self.B, (s.size,) + self.B.shape))
        Gc = self.C @ X + self.D + s[:, None, None] * self.Dd  # (n, n_y, channels)
        Gc = Gc * np.exp(-np.outer(s, [d for _, d in self.channels]))[:, None, :]
        Gc = Gc * np.exp(-np.outer(s, self.output_delays))[:, :, None]
        names = list(dict.fromkeys(nm for nm, _ in self.channels))
        G = np.zeros((s.size, len(self.outputs), len(names)), dtype=complex)
        for j, (nm, _d) in enumerate(self.channels):
            G[:, :, names.index(nm)] += Gc[:, :, j]
        return np.moveaxis(G, 0, -1)


def realize(model, values=None) -> Realization:
    """Finite-state realisation of a model (the one :func:`simulate` integrates).

    Parameters
    ----------
    model : fdml.models.Model
        Any kind except ``unsteady`` with F != 0, whose downwash memory has no
        finite-state form (docs/theory.md section 4).
    values : mapping, optional
        Parameter values overriding the model's.

    Returns
    -------
    Realization
        The state-space matrices, input channels and output delays.
    """
    sys = _system(model, model.values(values))
    if sys.kappa != 0.0:
        raise ParameterError(
            "the unsteady model with F != 0 has no finite-state realisation (docs/theory.md section 4)"
        )
    return Realization(sys.A, sys.B, sys.C, sys.D, sys.Dd, sys.channels, tuple(sys.out_delay), sys.outputs)
