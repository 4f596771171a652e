"""Time-domain simulation of fdml's models, for cross-checking the frequency domain.

Every model is linear; the simulation starts from rest (zero states, zero
input history before the first sample) and returns alpha (rad), q (rad/s) and
``a_z = (U/g)(alpha_dot - q)`` in g (docs/theory.md Eq. 5), plus the output biases.

Two integrators, chosen by the model:

* **Finite-state models** (``dimensional``, ``derivatives``, ``steady`` and
  ``unsteady`` with F = 0): exact discretisation with a first-order hold of
  the sampled inputs (matrix exponential of the augmented system), exact for
  inputs that are piecewise linear between the samples.  The descriptor form
  ``E x' = A x + B0 u + B1 u'`` of the alpha-dot derivatives is reduced to a
  proper state-space system by ``xi = x - E^-1 B1 u``, so no input is
  differentiated to propagate the states.  The unsteady model's lags (docs/theory.md
  section 4), the Kussner gust lag (BS-15/16, or an exponential-sum indicial
  preset) and the tail gust delay (BS-8) are realised as states and delayed
  input channels.
* **Unsteady model with F != 0**: the downwash memory term
  ``eps_F(t) = eps_ss F (c_w/U) PV int_0^t alpha_dot(tau) / (t - tau - T) dtau``,
  ``T = (l_t - c_w)/U`` (docs/theory.md Eqs. 2 and 10, section 4), has no
  finite-state realisation.  The coupled integro-differential system is
  marched on an internal grid ``h = T/m`` (default m = 16, about 1e-4
  relative accuracy) with the trapezoid rule for the states (the inputs,
  linear between their samples, integrated exactly over each step) and a
  trapezoid product rule with singularity subtraction for the principal-value
  memory integral (see :func:`pv_memory`); both are second order in h.  The
  outputs are interpolated back to the samples (cubic Hermite for the states).

Input delays ``tau_de`` and ``tau_alpha_w`` (and the tail gust delay l_t/U)
are applied as ``u(t - tau)`` by linear interpolation, zero before t = 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from scipy import interpolate, linalg, signal

from .aero import get_indicial
from .channels import INPUTS, OUTPUTS, SIGNALS
from .constants import G0
from .errors import ParameterError, RecordError
from .maneuvers import DEFAULT_AMPLITUDE, DRYDEN_L, dryden_gust, make_input, time_vector
from .record import Record, add_noise, uniform_interval

__all__ = [
    "simulate",
    "simulate_maneuver",
    "realize",
    "Realization",
    "pv_memory",
    "pole_steps_for",
    "DEFAULT_POLE_STEPS",
]

#: Default internal steps per pole time T for the F-term (h = T/m); m = 16
#: gives about 1e-4 relative accuracy on the Navion and Sundowner presets (a
#: 10 s, 50 Hz record; see tests/test_theory_checks.py for the convergence).
DEFAULT_POLE_STEPS = 16
#: Relative tolerance on the spacing of the time vector.
_UNIFORM_RTOL = 1e-6
#: F-term models: largest input at t = 0, relative to its peak, treated as starting from zero.
_START_RTOL = 1e-9


# --- the linear system ---------------------------------------------------------------


@dataclass(frozen=True)
class _System:
    """``x' = A x + B u + bF eps_F``, ``y = C x + D u + Dd u' + dF eps_F`` (y = alpha, q, a_z).

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
    #: Pure delays of the output channels (alpha, q, a_z), s: y_i(t) = (C x + D u + ...)_i(t - d_i).
    out_delay: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Descriptor:
    """``E x' = A x + B0 u + B1 u'`` with x = [alpha, q, extra states...] and input channels.

    The form of the conventional models (and of the matrix-level effects that
    act on them, :meth:`fdml.models.effects.MatrixEffect.realize`); the outputs
    are alpha = x_0, q = x_1 and a_z = (U/g)(alpha' - q) (docs/theory.md Eq. 5).
    """

    E: np.ndarray
    A: np.ndarray
    B0: np.ndarray
    B1: np.ndarray
    channels: tuple

    def with_state(self, a_row: np.ndarray, a_col: np.ndarray) -> "Descriptor":
        """One more state ``x_n`` with ``x_n' = a_row . [x, x_n]`` feeding ``A[:, n] = a_col`` (E_nn = 1)."""
        n = self.A.shape[0]
        E = np.eye(n + 1)
        E[:n, :n] = self.E
        A = np.zeros((n + 1, n + 1))
        A[:n, :n] = self.A
        A[:n, n] = a_col
        A[n] = a_row
        pad = np.zeros((1, self.B0.shape[1]))
        return Descriptor(E, A, np.vstack([self.B0, pad]), np.vstack([self.B1, pad]), self.channels)


def _from_descriptor(d: Descriptor, U: float) -> _System:
    """Proper state space of ``E x' = A x + B0 u + B1 u'`` (x_0 = alpha, x_1 = q).

    With ``xi = x - E^-1 B1 u``: ``xi' = E^-1 A xi + E^-1 (B0 + A E^-1 B1) u``,
    so the states never see u' (and are alpha, q themselves when B1 = 0).
    Only a_z = (U/g)(alpha' - q) keeps a direct feedthrough
    ``(U/g) e_alpha^T E^-1 B1 u'`` when B1 has an alpha row.
    """
    E, A, B0, B1 = d.E, d.A, d.B0, d.B1
    Ei = np.linalg.inv(E)
    n, nu = B0.shape
    Ax = Ei @ A
    D12 = Ei @ B1  # x = xi + D12 u
    Bx = Ei @ (B0 + A @ D12)
    k = U / G0  # Eq. 5
    C = np.zeros((3, n))
    D = np.zeros((3, nu))
    Dd = np.zeros((3, nu))
    C[:2] = np.eye(n)[:2]
    D[:2] = D12[:2]
    C[2] = k * (Ax[0] - C[1])
    D[2] = k * (Bx[0] - D[1])
    Dd[2] = k * D12[0]
    zeros = np.zeros(n)
    return _System(Ax, Bx, C, D, Dd, tuple(d.channels), zeros, np.zeros(3), zeros, np.zeros(nu))


def _conventional_system(model, p, matrix_effects=()) -> _System:
    """``dimensional`` and ``derivatives`` models (models/conventional.py), with matrix-level effects."""
    d = _conventional_descriptor(model, p)
    for eff in matrix_effects:
        d = eff.realize(d, p, model)
    return _from_descriptor(d, model.U)


def _conventional_descriptor(model, p) -> Descriptor:
    """E, A, B0, B1 of the ``dimensional`` and ``derivatives`` models (models/conventional.py)."""
    gust = model.gust
    channels = [("de", p["tau_de"])] + ([("alpha_w", p["tau_alpha_w"])] if gust else [])
    nu = len(channels)
    B0 = np.zeros((2, nu))
    B1 = np.zeros((2, nu))
    if model.kind == "dimensional":
        E = np.eye(2)
        A = np.array([[p["Z_a"], 1.0 + p["Z_q"]], [p["M_a"], p["M_q"]]])
        B0[:, 0] = p["Z_de"], p["M_de"]
        if gust:
            B0[:, 1] = p["Z_a"], p["M_a"]
    else:
        ac = model.aircraft
        kz, km, cu = ac.k_z, ac.k_m, ac.c_w / (2.0 * ac.U)
        E = np.array([[1.0 - kz * p["Cz_adot"] * cu, 0.0], [-km * p["Cm_adot"] * cu, 1.0]])
        A = np.array([[kz * p["Cz_a"], 1.0 + kz * p["Cz_q"] * cu], [km * p["Cm_a"], km * p["Cm_q"] * cu]])
        B0[:, 0] = kz * p["Cz_de"], km * p["Cm_de"]
        if gust:  # the gust enters as aerodynamic angle of attack, and its rate in the adot terms
            B0[:, 1] = kz * p["Cz_a"], km * p["Cm_a"]
            B1[:, 1] = kz * p["Cz_adot"] * cu, km * p["Cm_adot"] * cu
    return Descriptor(E, A, B0, B1, tuple(channels))


class _Rows:
    """Linear forms over the vector [states | input channels | eps_F]."""

    def __init__(self, ns: int, nu: int):
        self.ns, self.nu, self.size = ns, nu, ns + nu + 1

    def x(self, i: int) -> np.ndarray:
        r = np.zeros(self.size)
        r[i] = 1.0
        return r

    def u(self, j: int) -> np.ndarray:
        return self.x(self.ns + j)

    def eps(self) -> np.ndarray:
        return self.x(self.size - 1)

    def zero(self) -> np.ndarray:
        return np.zeros(self.size)


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
    steady = model.kind == "steady"
    if steady:
        y_w = y_t = G = F = 0.0
        lam_w = lam_t = lam_G = 0.0
        tail_delay = False
    else:
        y_w, y_t, G, F = p["y_w"], p["y_t"], p["G"], p["F"]
        c_tail = c if model.tail_lag_chord == "c_w" else ac.c_t
        lam_w = 2.0 * p["z_w"] * U / c  # Eq. 17, wing: 2 z_w U / c_w
        lam_t = 2.0 * p["z_t"] * U / c_tail  # Eq. 17, tail (c_w as printed, or c_t)
        lam_G = 2.0 * p["H"] * U / c  # Eq. 16: 2 H U / c_w
        tail_delay = model.tail_gust_delay
    tail_tau = l / U  # BS-8: tau_t = l/U
    opts: dict = {}
    for eff in matrix_effects:  # e.g. gust_lag@tail: {"tail_tau": tau_tail}
        opts = eff.realize(opts, p, model)
    if "tail_tau" in opts:
        tail_delay, tail_tau = True, opts.pop("tail_tau")
    post = opts.pop("system", ())  # e.g. downwash_lag@tail: callables on the finished system
    if opts:
        raise ParameterError(f"the {model.kind} model cannot realise {sorted(opts)}")
    channels = [("de", p["tau_de"])]
    if model.gust:
        channels.append(("alpha_w", p["tau_alpha_w"]))
        if tail_delay:
            channels.append(("alpha_w", p["tau_alpha_w"] + tail_tau))
    # --- states: alpha, q, the lift and downwash lags that are present, gust lags
    names = ["alpha", "q"]
    for name, amp in (("x_w", y_w), ("x_t", y_t), ("x_G", G)):
        if amp != 0.0:
            names.append(name)
    # (feedthrough, [(amplitude, rate)]) of the gust lag K(s); [] without gust input
    gust_terms: tuple[float, list[tuple[float, float]]] | list = []
    if model.gust:
        if steady:
            gust_terms = (1.0, [])
        elif model.gust_lag == "bs12":
            if p["b1"] < 0:
                raise ParameterError(f"Kussner lag length b1 must be >= 0 semichords, got {p['b1']}")
            Ts = c * p["b1"] / (2.0 * U)  # BS-12: T* = c b1 / (2U)
            gust_terms = (1.0, []) if Ts == 0.0 else (0.0, [(1.0, 1.0 / Ts)])
        else:  # K(s) = 1 - sum A_i s/(s + r_i) = (1 - sum A_i) + sum A_i r_i/(s + r_i)
            fn = get_indicial(model.gust_lag)
            rates = [2.0 * b * U / c for b in fn.rates]
            gust_terms = (1.0 - sum(fn.amplitudes), [(A, r) for A, r in zip(fn.amplitudes, rates) if A != 0.0])
        surfaces = ("w", "t") if tail_delay else ("w",)
        for s in surfaces:
            names += [f"g{s}{i}" for i in range(len(gust_terms[1]))]
    ns, nu = len(names), len(channels)
    R = _Rows(ns, nu)
    ix = {n: i for i, n in enumerate(names)}
    X = lambda n: R.x(ix[n]) if n in ix else R.zero()  # noqa: E731
    alpha, q = X("alpha"), X("q")
    dyn = {}
    g_rows = {}
    if model.gust:
        inputs = {"w": R.u(1), "t": R.u(2) if tail_delay else R.u(1)}
        ff, terms = gust_terms
        for s in ("w", "t") if tail_delay else ("w",):
            g = ff * inputs[s]
            for i, (A_i, r_i) in enumerate(terms):  # BS-16: Y' = (alpha_w - Y)/T*
                st = X(f"g{s}{i}")
                g = g + A_i * st
                dyn[f"g{s}{i}"] = r_i * (inputs[s] - st)
            g_rows[s] = g
        g_rows.setdefault("t", g_rows["w"])
    g_w = g_rows.get("w", R.zero())
    g_t = g_rows.get("t", R.zero())
    # Eq. 17 / section 4: C_Lw = a_w[(1 - y_w) alpha + y_w x_w] (+ a_w K alpha_g, section 8)
    CLw = a_w * ((1.0 - y_w) * alpha + y_w * X("x_w")) + a_w * g_w
    # Eq. 16 / section 4: eps = eps_ss[(1 - G) alpha + G x_G] + eps_F (+ eps_ss K D alpha_g)
    eps = eps_ss * ((1.0 - G) * alpha + G * X("x_G")) + eps_ss * g_t + R.eps()
    beta = alpha - eps + (l / U) * q  # Eq. 9: tail angle alpha - eps + l q / U
    CLt = a_t * ((1.0 - y_t) * beta + y_t * X("x_t")) + a_t * g_t
    Cz = -CLw - sr * CLt + p["Cz_de"] * R.u(0)  # Eq. 6
    Cm = -(l * sr / c) * CLt + p["Cm_de"] * R.u(0)  # Eq. 7
    dyn["alpha"] = q + kz * Cz  # Eq. 3
    dyn["q"] = km * Cm  # Eq. 4
    dyn["x_w"] = lam_w * (alpha - X("x_w"))
    dyn["x_t"] = lam_t * (beta - X("x_t"))
    dyn["x_G"] = lam_G * (alpha - X("x_G"))
    rows = np.array([dyn[n] for n in names])
    out = np.array([alpha, q, (U / G0) * kz * Cz])  # Eq. 5: a_z = (U/g)(alpha_dot - q) = (U/g) k_z C_z
    kappa = 0.0
    T = (l - c) / U
    if F != 0.0:
        if T <= 0.0:
            raise ParameterError(
                f"the downwash pole time T = (l_t - c_w)/U = {T:.4g} s must be positive: "
                f"tail length l_t = {l} m must exceed the wing chord c_w = {c} m"
            )
        kappa = eps_ss * F * c / U  # section 4: eps_F = eps_ss F (c_w/U) PV int alpha_dot/(t - tau - T)
    sys = _System(
        A=rows[:, :ns],
        B=rows[:, ns : ns + nu],
        C=out[:, :ns],
        D=out[:, ns : ns + nu],
        Dd=np.zeros((3, nu)),
        channels=tuple(channels),
        bF=rows[:, -1],
        dF=out[:, -1],
        rx=dyn["alpha"][:ns],
        ru=dyn["alpha"][ns : ns + nu],
        rF=float(dyn["alpha"][-1]),
        T=T,
        kappa=kappa,
    )
    for fn in post:
        sys = fn(sys)
    return sys


def _system(model, p) -> _System:
    """The model's state space, composed through its effects (matrix-level, then output-level, in order)."""
    from .models.augment import MatrixEffect, applied_effects, root_model

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


# --- state-space algebra of the output-level effects (docs/theory.md Eq. 5 for a_z) -------------------


def _pad_states(sys: _System, k: int) -> _System:
    """``sys`` with ``k`` more states, all zero (appended after the existing ones)."""
    n, nu = sys.B.shape
    A = np.zeros((n + k, n + k))
    A[:n, :n] = sys.A
    z = np.zeros(k)
    return replace(
        sys,
        A=A,
        B=np.vstack([sys.B, np.zeros((k, nu))]),
        C=np.hstack([sys.C, np.zeros((3, k))]),
        bF=np.concatenate([sys.bF, z]),
        rx=np.concatenate([sys.rx, z]),
    )


def _same_delay(sys: _System, rows, what: str) -> None:
    if len({sys.out_delay[r] for r in rows}) > 1:
        raise ParameterError(
            f"{what}: the channels it combines carry different output delays; list the time_delay effect after it"
        )


def delay_output(sys: _System, row: int, tau: float) -> _System:
    """Output ``row`` delayed by ``tau`` s: y_row(t - tau) (a negative tau is an advance)."""
    d = list(sys.out_delay)
    d[row] += float(tau)
    return replace(sys, out_delay=tuple(d))


def scale_output(sys: _System, row: int, factor: float) -> _System:
    """Output ``row`` times ``factor``."""
    C, D, Dd, dF = sys.C.copy(), sys.D.copy(), sys.Dd.copy(), sys.dF.copy()
    for a in (C, D, Dd, dF):
        a[row] = a[row] * factor
    return replace(sys, C=C, D=D, Dd=Dd, dF=dF)


def mix_output(sys: _System, dst: int, src: int, k: float) -> _System:
    """Output ``dst`` plus ``k`` times output ``src``."""
    _same_delay(sys, (dst, src), "mixing two outputs")
    C, D, Dd, dF = sys.C.copy(), sys.D.copy(), sys.Dd.copy(), sys.dF.copy()
    for a in (C, D, Dd, dF):
        a[dst] = a[dst] + k * a[src]
    return replace(sys, C=C, D=D, Dd=Dd, dF=dF)


def add_output_rate(sys: _System, dst: int, src: int, k: float) -> _System:
    """Output ``dst`` plus ``k`` times the time derivative of output ``src`` (x' = A x + B u + bF eps_F)."""
    _same_delay(sys, (dst, src), "adding an output rate")
    if np.any(sys.Dd[src]) or sys.dF[src] != 0.0:
        raise ParameterError("the rate of this output needs the second derivative of an input: no realisation")
    C, D, Dd, dF = sys.C.copy(), sys.D.copy(), sys.Dd.copy(), sys.dF.copy()
    C[dst] = C[dst] + k * (sys.C[src] @ sys.A)
    D[dst] = D[dst] + k * (sys.C[src] @ sys.B)
    Dd[dst] = Dd[dst] + k * sys.D[src]
    dF[dst] = dF[dst] + k * (sys.C[src] @ sys.bF)
    return replace(sys, C=C, D=D, Dd=Dd, dF=dF)


def filter_input(sys: _System, signal_name: str, T: float) -> _System:
    """Every channel of ``signal_name`` through ``1/(1 + T s)`` (one state per channel; T = 0: unchanged).

    With the filtered input ``v = x_f``, ``x_f' = (u - x_f)/T``, the old input
    column moves onto the new state, and a feedthrough of ``v'`` becomes
    ``(u - x_f)/T``.
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
    """
    if sys.out_delay[1] or sys.out_delay[2]:
        raise ParameterError("a structural mode after a q or a_z delay: list the time_delay effect after it")
    n, nu = sys.B.shape
    s2 = _pad_states(sys, 2)
    B = np.hstack([s2.B, np.zeros((n + 2, 1))])
    A, C = s2.A, s2.C
    A[n, n + 1] = 1.0
    A[n + 1, n] = -(omega**2)
    A[n + 1, n + 1] = -2.0 * zeta * omega
    B[n + 1, nu] = omega**2
    C[1, n + 1] += r_q / omega
    C[2, n] -= r_az
    C[2, n + 1] -= 2.0 * zeta * r_az / omega
    D = np.hstack([sys.D, np.zeros((3, 1))])
    D[2, nu] = r_az
    return replace(
        s2,
        B=B,
        C=C,
        D=D,
        Dd=np.hstack([sys.Dd, np.zeros((3, 1))]),
        ru=np.concatenate([sys.ru, [0.0]]),
        channels=sys.channels + (("de", 0.0),),
    )


@dataclass(frozen=True)
class Realization:
    """Finite-state realisation of a model: ``x' = A x + B u``, ``y = C x + D u + Dd u'``.

    Outputs y are (alpha rad, q rad/s, a_z g); the inputs u are the delayed
    input channels ``(signal, delay s)``, u_i(t) = signal(t - delay), so that
    ``G(s) = [C (sI - A)^-1 B + D + s Dd] diag(exp(-s delay))``.

    Attributes
    ----------
    A, B, C, D, Dd : ndarray
        State-space matrices (Dd is nonzero only for a gust model with
        alpha-dot derivatives, whose a_z feels alpha_w_dot directly).
    channels : tuple of (str, float)
        Input channels: signal name (``de`` or ``alpha_w``) and delay, s.
    output_delays : tuple of float
        Pure delays of the outputs (alpha, q, a_z), s (sensor delays):
        ``G_i(s)`` is multiplied by ``exp(-s d_i)``.
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

    @property
    def states(self) -> int:
        """Number of states of the realization."""
        return self.A.shape[0]

    def frequency_response(self, omega) -> np.ndarray:
        """Transfer matrix per model input (de[, alpha_w]), shape (3, n_in, n omega)."""
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        s = 1j * omega
        I = np.eye(self.states)
        X = np.linalg.solve(s[:, None, None] * I - self.A, np.broadcast_to(self.B, (s.size,) + self.B.shape))
        Gc = self.C @ X + self.D + s[:, None, None] * self.Dd  # (n, 3, channels)
        Gc = Gc * np.exp(-np.outer(s, [d for _, d in self.channels]))[:, None, :]
        Gc = Gc * np.exp(-np.outer(s, self.output_delays))[:, :, None]
        names = list(dict.fromkeys(nm for nm, _ in self.channels))
        G = np.zeros((s.size, 3, len(names)), dtype=complex)
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
    """
    sys = _system(model, model.values(values))
    if sys.kappa != 0.0:
        raise ParameterError(
            "the unsteady model with F != 0 has no finite-state realisation (docs/theory.md section 4)"
        )
    return Realization(sys.A, sys.B, sys.C, sys.D, sys.Dd, sys.channels, tuple(sys.out_delay))


# --- integrators ----------------------------------------------------------------------


def _foh_march(sys: _System, dt: float, u: np.ndarray) -> np.ndarray:
    """States at the samples for inputs linear between samples (exact; x(0) = 0).

    ``expm([[A, B, 0], [0, 0, I], [0, 0, 0]] dt)`` gives Phi, Gamma1, Gamma2 with
    ``x_{k+1} = Phi x_k + Gamma1 u_k + Gamma2 (u_{k+1} - u_k)``.
    """
    ns, nu = sys.B.shape
    n = u.shape[0]
    M = np.zeros((ns + 2 * nu, ns + 2 * nu))
    M[:ns, :ns] = sys.A * dt
    M[:ns, ns : ns + nu] = sys.B * dt
    M[ns : ns + nu, ns + nu :] = np.eye(nu)
    Ex = linalg.expm(M)
    Phi, G1, G2 = Ex[:ns, :ns], Ex[:ns, ns : ns + nu], Ex[:ns, ns + nu :]
    drive = u[:-1] @ (G1 - G2).T + u[1:] @ G2.T
    x = np.zeros((n, ns))
    for k in range(n - 1):  # linear recursion; the work per step is a small matrix product
        x[k + 1] = Phi @ x[k] + drive[k]
    return x


def pole_steps_for(T: float, dt: float, substeps: int | None = None) -> int:
    """Internal steps m per pole time T (h = T/m) for the F-term integrator.

    Parameters
    ----------
    T : float
        Pole time (l_t - c_w)/U, s.
    dt : float
        Output sample interval, s.
    substeps : int, optional
        If given, the smallest m with ``h <= dt / substeps``.  By default the
        larger of :data:`DEFAULT_POLE_STEPS` and the smallest m with h <= dt.

    Returns
    -------
    int
        m >= 2.
    """
    if substeps is None:
        return max(DEFAULT_POLE_STEPS, math.ceil(T / dt * (1.0 - 1e-12)), 2)
    return max(2, math.ceil(substeps * T / dt * (1.0 - 1e-12)))


def _pv_tables(m: int, n: int):
    """Weights of the PV product rule on t_j = j h, T = m h (see :func:`pv_memory`).

    Returns ``k`` (k_j = 1/(j - m), k_m = 0) and ``c`` (c_n, the quadrature
    error of ``PV int_0^{t_n} d sigma/(sigma - T) = ln(|n - m|/m)`` by the same
    trapezoid weights, for n > m; zero otherwise).
    """
    j = np.arange(n, dtype=float)
    k = np.zeros(n)
    off = j != m
    k[off] = 1.0 / (j[off] - m)
    c = np.zeros(n)
    if n > m + 1:
        harm = np.concatenate([[0.0], np.cumsum(1.0 / np.arange(1, n))])  # H_0 .. H_{n-1}
        d = np.arange(1, n - m)  # n - m for n = m+1 .. n-1
        c[m + 1 :] = np.log(d / m) + 0.5 / m - harm[d - 1] + harm[m - 1] - 0.5 / d
    return k, c


def pv_memory(rate, m: int) -> np.ndarray:
    """Principal-value memory integral of docs/theory.md Eq. 10 on a uniform grid.

    Computes ``I(t_n) = PV int_0^{t_n} r(tau) / (t_n - tau - T) dtau`` for
    ``t_n = n h`` with the pole time ``T = m h`` on a grid node, r = 0 before 0.
    With sigma = t_n - tau, the integrand is split (singularity subtraction) as

        [r(t_n - sigma) - r(t_n - T)] / (sigma - T)  +  r(t_n - T) / (sigma - T);

    the first part is smooth (value -r'(t_n - T) at sigma = T, from central
    differences) and is integrated by the trapezoid rule; the second is exact,
    ``r(t_n - T) ln(|t_n - T| / T)``.  The error is O(h^2) for smooth r (and
    r(t) = o(1) as t -> 0; a kink of r at t = 0 costs O(h) near t = T only).  The
    eps_F term of the downwash is ``eps_ss F (c_w/U) I`` (section 4).

    Parameters
    ----------
    rate : array_like, shape (n,)
        r(t_n), e.g. alpha_dot in rad/s, on the grid t_n = n h; ``rate[0]`` must
        be 0 (a step at t = 0 makes the integral infinite at t = T).
    m : int
        Grid steps per pole time (>= 2).

    Returns
    -------
    ndarray, shape (n,)
        I(t_n), in the unit of ``rate``.
    """
    r = np.asarray(rate, dtype=float)
    m = int(m)
    if m < 2:
        raise ParameterError(f"pole steps m = {m}: at least 2 grid steps per pole time are needed")
    if r.ndim != 1:
        raise ParameterError("rate must be one-dimensional")
    scale = np.max(np.abs(r)) if r.size else 0.0
    if r.size and abs(r[0]) > _START_RTOL * scale:
        raise ParameterError("rate[0] must be 0: a step at t = 0 makes the PV memory integral infinite at t = T")
    n = r.size
    k, c = _pv_tables(m, n)
    # trapezoid over j = 0..n (weights 1/2 at both ends; the j = n end multiplies r_0 = 0)
    full = signal.fftconvolve(r, k)[:n] - 0.5 * k[0] * r
    out = full + c * np.concatenate([np.zeros(min(m, n)), r[: max(n - m, 0)]])
    # the smooth part's value at sigma = T: -h r'(t_n - T), weight 1 (n > m) or 1/2 (n = m)
    if n > m + 1:
        idx = np.arange(1, n - m)  # n - m for n = m+1 .. n-1
        out[m + 1 :] -= 0.5 * (r[idx + 1] - r[idx - 1])
    if n > m:
        out[m] -= 0.5 * (r[1] - r[0])
    return out


def _memory_march(sys: _System, h: float, m: int, u: np.ndarray, uint: np.ndarray):
    """Trapezoid march of x' = A x + B u + bF eps_F with the PV memory eps_F (x(0) = 0).

    The memory is ``eps_F,n = kappa I_n`` with ``I_n = -r_n/(2m) + H_n``, where
    ``r = alpha_dot`` and ``H_n`` (from r_1 .. r_{n-1}) is the rest of the
    product rule of :func:`pv_memory`.  Eliminating eps_F,n and r_n leaves, per
    step, a constant linear map of x_{n-1}, u and H: the trapezoid step
    ``(I - h/2 Ae) x_n = x_{n-1} + h/2 (f_{n-1} + Be u_n + bH H_n)``, except
    that the input term ``B u`` is integrated exactly over the step
    (``uint``, the running integral of the piecewise-linear inputs), so the
    kinks of sampled inputs between internal nodes cost no accuracy.

    The history sum ``sum_i k_{n-i} r_i`` is split into blocks: once a block of
    r is complete its contribution to every later step is added with one FFT
    convolution, and only the current block is summed step by step, so the cost
    is about O(N^1.5 log N) rather than O(N^2).

    Returns
    -------
    x, xdot : ndarray, shape (K, ns)
        States and their derivatives on t_k = k h (x[:, 0] is alpha in rad,
        x[:, 1] is q in rad/s).
    eps : ndarray, shape (K,)
        eps_F, rad.
    """
    ns, nu = sys.B.shape
    K = u.shape[0]
    kappa = sys.kappa
    a0 = -0.5 / m  # weight of the current r_n in I_n (trapezoid half weight times k_0 = -1/m)
    den = 1.0 - kappa * a0 * sys.rF
    ex, eu, eH = kappa * a0 * sys.rx / den, kappa * a0 * sys.ru / den, kappa / den  # eps_n in x, u, H
    Ae = sys.A + np.outer(sys.bF, ex)  # f = Ae x + Be u + bH H
    Be = sys.B + np.outer(sys.bF, eu)
    bH = sys.bF * eH
    half_h = 0.5 * h
    Minv = np.linalg.inv(np.eye(ns) - half_h * Ae)
    Q = Minv @ (np.eye(ns) + half_h * Ae)
    uB = u @ Be.T
    ueF = np.outer(u @ eu, sys.bF)  # the part of Be u that comes through eps_F (nodal)
    drive = np.zeros((K, ns))
    drive[1:] = (np.diff(uint, axis=0) @ sys.B.T + half_h * (ueF[:-1] + ueF[1:])) @ Minv.T
    a_prev = half_h * (Minv @ bH)  # H_{n-1} and H_n enter x_n with the same weight
    rr = sys.rx + sys.rF * ex  # r = rr x + ru_e u + rH H
    ru_e = u @ (sys.ru + sys.rF * eu)
    rH = sys.rF * eH
    k, c = _pv_tables(m, K)
    kr = k[::-1].copy()  # kr[K-1-j] = k_j: k_{n-b0} .. k_1 is the contiguous kr[K-1-n+b0 : K-1]
    block = int(min(max(64, 4 * math.isqrt(K)), 4096))
    acc = np.zeros(K)  # contributions of completed blocks of r to later H_n
    x = np.zeros((K, ns))
    r = np.zeros(K)
    H = np.zeros(K)
    r[0] = ru_e[0]  # x_0 = 0 and eps_F(0) = 0 (empty integral); r_0 = 0 is checked by the caller
    b0 = 0  # first index of the current (incomplete) block of r
    xn = x[0]
    for n in range(1, K):
        Hn = acc[n] + float(np.dot(kr[K - 1 - n + b0 : K - 1], r[b0:n]))  # i = b0 .. n-1 (k_{n-i} r_i)
        if n > m:
            Hn += c[n] * r[n - m] - 0.5 * (r[n - m + 1] - r[n - m - 1])
        elif n == m:
            Hn -= 0.5 * (r[1] - r[0])
        xn = Q @ xn + drive[n] + a_prev * (H[n - 1] + Hn)
        x[n] = xn
        H[n] = Hn
        r[n] = rr @ xn + ru_e[n] + rH * Hn
        if n + 1 - b0 == block and n + 1 < K:  # block [b0, n] complete: add it to every later step
            seg = signal.fftconvolve(r[b0 : n + 1], k[: K - b0])
            acc[n + 1 :] += seg[n + 1 - b0 : K - b0]
            b0 = n + 1
    eps = x @ ex + u @ eu + eH * H
    xdot = x @ Ae.T + uB + np.outer(H, bH)
    return x, xdot, eps


# --- validation --------------------------------------------------------------------


def _check_time(t) -> tuple[np.ndarray, float]:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 4:
        raise RecordError(f"simulate: t must be a 1-D time vector with at least 4 samples, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        i = int(np.argmax(~np.isfinite(t)))
        raise RecordError(f"simulate: t has a non-finite value at sample {i}")
    return t, uniform_interval(t, _UNIFORM_RTOL, "simulate", "use a uniform grid, e.g. fdml.maneuvers.time_vector")


def _check_inputs(model, t: np.ndarray, inputs) -> dict[str, np.ndarray]:
    if not isinstance(inputs, Mapping):
        raise RecordError("simulate: inputs must be a mapping such as {'de': array, 'alpha_w': array}")
    needed = INPUTS if model.gust else INPUTS[:1]
    missing = [k for k in needed if k not in inputs]
    if missing:
        extra = " (the model has a gust input; pass alpha_w, rad)" if "alpha_w" in missing else ""
        raise RecordError(f"simulate: missing input(s) {', '.join(missing)}{extra}")
    unknown = [k for k in inputs if k not in needed]
    if unknown:
        hint = " (the model has no gust input; build it with gust=True)" if "alpha_w" in unknown else ""
        raise RecordError(
            f"simulate: unexpected input(s) {', '.join(map(str, unknown))}{hint}; this model takes {', '.join(needed)}"
        )
    out = {}
    for k in needed:
        a = np.asarray(inputs[k], dtype=float)
        if a.shape != t.shape:
            raise RecordError(f"simulate: input {k} has shape {a.shape} but t has {t.shape}")
        bad = ~np.isfinite(a)
        if np.any(bad):
            i = int(np.argmax(bad))
            raise RecordError(f"simulate: input {k} has {int(bad.sum())} non-finite value(s) (first at sample {i})")
        out[k] = a
    return out


def _noise_fraction(noise) -> float | None:
    """``noise`` as a fraction of RMS (a number), or None for a mapping of standard deviations or None."""
    if noise is None or isinstance(noise, Mapping):
        return None
    if isinstance(noise, bool) or not isinstance(noise, (int, float, np.integer, np.floating)):
        raise ParameterError(
            f"noise must be a fraction of each output's RMS (a number such as 0.02) or a "
            f"mapping {{'alpha': rad, 'q': rad/s, 'az': g}} of standard deviations, got {noise!r}"
        )
    if not (math.isfinite(noise) and noise >= 0):
        raise ParameterError(f"noise fraction must be finite and >= 0, got {noise!r}")
    return float(noise)


def _check_noise(noise, rng):
    if noise is None:
        return None
    if not isinstance(noise, Mapping):
        raise ParameterError("noise must be a mapping {'alpha': rad, 'q': rad/s, 'az': g} of standard deviations")
    bad = [k for k in noise if k not in OUTPUTS]
    if bad:
        raise ParameterError(f"unknown noise channel(s) {', '.join(map(str, bad))}; channels: alpha, q, az")
    out = {}
    for k, v in noise.items():
        try:
            s = float(v)
        except (TypeError, ValueError):
            raise ParameterError(f"noise std for {k} must be a number ({SIGNALS[k]}), got {v!r}") from None
        if not (math.isfinite(s) and s >= 0):
            raise ParameterError(f"noise std for {k} must be finite and >= 0 ({SIGNALS[k]}), got {v!r}")
        out[k] = s
    if rng is None or not isinstance(rng, np.random.Generator):
        raise ParameterError("noise needs rng, a numpy Generator (np.random.default_rng(seed))")
    return out


# --- public API ---------------------------------------------------------------------------


def simulate(
    model, t, inputs, values=None, *, noise=None, rng=None, substeps=None, pole_steps=None, name: str = "simulated"
) -> Record:
    """Simulate a model's response to elevator (and gust) inputs from rest.

    Parameters
    ----------
    model : fdml.models.Model
        A model from :func:`fdml.models.make_model` (any kind).
    t : array_like, shape (n,)
        Uniform time, s; the aircraft is at rest, with zero input history,
        before ``t[0]``.
    inputs : mapping
        ``{"de": array}`` (rad), plus ``"alpha_w"`` (gust angle w_g/U, rad) if
        and only if ``model.gust``; each of shape (n,).  Inputs are taken as
        linear between samples.
    values : mapping, optional
        Parameter values overriding the model's (``model.values(values)``).
    noise : mapping, optional
        White Gaussian measurement noise standard deviations by output:
        ``{"alpha": rad, "q": rad/s, "az": g}``; needs ``rng``.
    rng : numpy.random.Generator, optional
        Noise source (the global RNG is never used).
    substeps : int, optional
        F-term models only: internal steps h <= dt/substeps (see
        :func:`pole_steps_for`); finite-state models are discretised exactly and
        ignore it.
    pole_steps : int, optional
        F-term models only: the internal step as h = T/pole_steps directly
        (overrides ``substeps``; >= 2).
    name : str, optional
        Record name.

    Returns
    -------
    Record
        Signals de, alpha (rad), q (rad/s), az (g, positive down) and alpha_w
        for a gust model, with output biases and noise added.  ``meta`` holds
        ``model`` (kind), ``values`` (all parameters), ``noise``, ``U`` (m/s) and
        ``integration`` (method and internal step).

    Raises
    ------
    RecordError
        Bad time vector or inputs (length, NaN, missing or unexpected alpha_w).
    ParameterError
        Unknown parameter, negative delay, noise without rng, or an F-term
        model whose alpha_dot would step at t = 0.
    """
    t, dt = _check_time(t)
    sig = _check_inputs(model, t, inputs)
    if substeps is not None and (isinstance(substeps, bool) or int(substeps) != substeps or substeps < 1):
        raise ParameterError(f"substeps must be a positive integer, got {substeps!r}")
    if pole_steps is not None and (isinstance(pole_steps, bool) or int(pole_steps) != pole_steps or pole_steps < 2):
        raise ParameterError(f"pole_steps must be an integer >= 2, got {pole_steps!r}")
    noise = _check_noise(noise, rng)
    p = model.values(values)
    for key in ("tau_de", "tau_alpha_w"):
        if key in p and not (math.isfinite(p[key]) and p[key] >= 0):
            raise ParameterError(f"{key} must be a delay >= 0 s, got {p[key]}")
    sys = _system(model, p)
    tau = t - t[0]
    if sys.kappa == 0.0:
        u = np.column_stack([_delayed(tau, sig[nm], d, tau) for nm, d in sys.channels])
        x = _foh_march(sys, dt, u)
        y = x @ sys.C.T + u @ sys.D.T
        if np.any(sys.Dd):  # a_z feedthrough of alpha_w_dot (alpha-dot derivatives with a gust)
            y += np.gradient(u, dt, axis=0) @ sys.Dd.T
        integration = {"method": "exact first-order-hold discretisation (matrix exponential)"}
    else:
        y, integration = _simulate_memory(sys, tau, dt, sig, substeps, pole_steps)
    y = _delay_outputs(y, tau, sys.out_delay)
    y = y + np.array([p[f"bias_{k}"] for k in OUTPUTS])
    if noise:
        for i, k in enumerate(OUTPUTS):  # fixed channel order: reproducible for a given seed
            if k in noise:
                y[:, i] += noise[k] * rng.standard_normal(t.size)
    signals = {"de": sig["de"], "alpha": y[:, 0], "q": y[:, 1], "az": y[:, 2]}
    if model.gust:
        signals["alpha_w"] = sig["alpha_w"]
    meta = {"model": model.kind, "values": p, "noise": noise, "U": model.U, "integration": integration}
    return Record(t, signals, name=name, meta=meta, check_units=False)


def _delay_outputs(y: np.ndarray, tau: np.ndarray, delays) -> np.ndarray:
    """Each output column y_i(t - d_i) by a cubic spline (interpolation error O(dt^4)).

    Zero before the start (the simulation starts from rest), held after the end
    (a negative delay, an advance, reaches past the last sample).
    """
    y = y.copy()
    for i, d in enumerate(delays):
        if d:
            ts = tau - d
            yi = interpolate.CubicSpline(tau, y[:, i])(np.clip(ts, tau[0], tau[-1]))
            yi[ts < tau[0]] = 0.0
            y[:, i] = yi
    return y


def _delayed(tau_out, u, delay: float, tau_in) -> np.ndarray:
    """u(t - delay) by linear interpolation, zero before t = 0, held after the end."""
    return np.interp(tau_out - delay, tau_in, u, left=0.0, right=u[-1])


def _delayed_integral(tau_out, u, delay: float, tau_in) -> np.ndarray:
    """Exact ``int_0^t u(s - delay) ds`` of the input linear between samples (as :func:`_delayed`)."""
    x = np.asarray(tau_out, dtype=float) - delay
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (u[1:] + u[:-1]) * np.diff(tau_in))])
    i = np.clip(np.searchsorted(tau_in, x, side="right") - 1, 0, tau_in.size - 2)
    dx = x - tau_in[i]
    slope = (u[i + 1] - u[i]) / (tau_in[i + 1] - tau_in[i])
    out = cum[i] + dx * (u[i] + 0.5 * dx * slope)
    after = x > tau_in[-1]
    out[after] = cum[-1] + (x[after] - tau_in[-1]) * u[-1]
    out[x <= tau_in[0]] = 0.0
    return out


def _simulate_memory(sys: _System, tau, dt, sig, substeps, pole_steps):
    """F-term model: march on h = T/m, then interpolate to the output samples."""
    m = int(pole_steps) if pole_steps is not None else pole_steps_for(sys.T, dt, substeps)
    for j, (nm, _d) in enumerate(sys.channels):
        # a start below 1e-9 of the peak is a negligible step (its log-singular eps_F is that small)
        if sys.ru[j] != 0.0 and abs(sig[nm][0]) > _START_RTOL * np.max(np.abs(sig[nm])):
            raise ParameterError(
                f"input {nm} starts at {sig[nm][0]:.4g} rad, a step at t = 0 that the F-term of "
                "docs/theory.md Eq. 2 turns into an infinite downwash at t = T; start the input from zero "
                "(e.g. a later start, rise > 0, or multisine(zero_start=True))"
            )
    h = sys.T / m
    K = int(math.ceil(tau[-1] / h * (1.0 - 1e-12))) + 1
    tk = np.arange(K) * h
    u = np.column_stack([_delayed(tk, sig[nm], d, tau) for nm, d in sys.channels])
    uint = np.column_stack([_delayed_integral(tk, sig[nm], d, tau) for nm, d in sys.channels])
    x, xdot, eps = _memory_march(sys, h, m, u, uint)
    # Outputs at the samples: states by cubic Hermite interpolation (their derivatives are known),
    # eps_F by a cubic spline, and the direct input feedthrough of a_z from the inputs themselves,
    # whose kinks at the samples would otherwise be smeared over an internal step.
    xs = interpolate.CubicHermiteSpline(tk, x, xdot, axis=0)(tau)
    eps_s = interpolate.CubicSpline(tk, eps)(tau)
    u_s = np.column_stack([_delayed(tau, sig[nm], d, tau) for nm, d in sys.channels])
    y = xs @ sys.C.T + u_s @ sys.D.T + np.outer(eps_s, sys.dF)
    integration = {"method": "trapezoid + PV memory by singularity subtraction", "h": h, "pole_steps": m, "T": sys.T}
    return y, integration


def simulate_maneuver(
    model,
    maneuver: str = "3211",
    *,
    duration: float = 10.0,
    dt: float = 0.02,
    amplitude: float = DEFAULT_AMPLITUDE,
    gust_std: float = 0.0,
    gust_length: float = DRYDEN_L,
    noise=None,
    seed=None,
    values=None,
    **input_kw,
) -> Record:
    """Simulate a standard manoeuvre, optionally in Dryden turbulence, with noise.

    Parameters
    ----------
    model : fdml.models.Model
    maneuver : {"doublet", "3211", "multisine"}, optional
        Elevator input (:func:`fdml.maneuvers.make_input`).
    duration : float, optional
        Record length, s.
    dt : float, optional
        Sample interval, s.
    amplitude : float, optional
        Elevator amplitude (pulse height or multisine peak), rad.
    gust_std : float, optional
        RMS of the vertical gust velocity w_g, m/s; > 0 needs a gust model.
    gust_length : float, optional
        Dryden scale length L, m.
    noise : float or mapping, optional
        Measurement noise.  A number is a fraction of each output's RMS about
        its mean in the noise-free record (``fdml simulate --noise 0.02``;
        :func:`fdml.record.add_noise` with ``relative=True``); a mapping gives
        standard deviations by output (see :func:`simulate`).
    seed : int, optional
        Seed of ``np.random.default_rng`` for the gust and the noise.
    values : mapping, optional
        Parameter values overriding the model's.
    **input_kw
        Options of the input generator (``start``, ``width``, ``unit``,
        ``rise``, ``omega_lo``, ``omega_hi``, ``n_components``, ...).

    Returns
    -------
    Record
        As :func:`simulate`; ``meta`` also holds ``maneuver`` and ``seed``.
    """
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise ParameterError(f"seed must be None or an integer >= 0 (numpy seeds cannot be negative), got {seed!r}")
    rng = np.random.default_rng(seed)
    t = time_vector(duration, dt)
    if maneuver == "multisine" and "rng" not in input_kw and input_kw.get("phases") == "random":
        input_kw = {**input_kw, "rng": rng}
    de = make_input(maneuver, t, amplitude, **input_kw)
    inputs = {"de": de}
    if gust_std < 0 or not math.isfinite(gust_std):
        raise ParameterError(f"gust_std must be >= 0 m/s, got {gust_std}")
    if model.gust:
        inputs["alpha_w"] = (
            dryden_gust(t, gust_std, model.U, gust_length, rng=rng) if gust_std > 0 else np.zeros_like(t)
        )
    elif gust_std > 0:
        raise ParameterError("gust_std > 0 needs a model with a gust input (make_model(..., gust=True))")
    fraction = _noise_fraction(noise)
    absolute = None if fraction is not None else noise
    rec = simulate(
        model, t, inputs, values, noise=absolute, rng=rng if absolute else None, name=f"{maneuver} simulation"
    )
    meta = {**rec.meta, "maneuver": maneuver, "seed": seed, "gust_std": gust_std}
    if fraction is not None:
        rec = add_noise(rec, fraction, rng, relative=True)
        meta.update(noise=rec.meta["noise_std"], noise_fraction=fraction)
    return Record(rec.t, rec.signals, name=rec.name, meta=meta, check_units=False)
