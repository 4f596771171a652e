"""Time-domain simulation of fdml's models, for cross-checking the frequency domain.

Every model is linear; the simulation starts from rest (zero states, zero
input history before the first sample) and returns the model's outputs
(:data:`fdml.channels.OUTPUT_TABLE`): alpha (rad), q (rad/s) and
``a_z = (U/g)(alpha_dot - q)`` in g (docs/theory.md Eq. 5), and theta (rad) and
q_dot (rad/s^2) for a model asked for them (:meth:`fdml.models.Model.with_outputs`),
plus the output biases.

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
are applied as ``u(t - tau)`` of the input linear between its samples, zero
before t = 0.  The finite-state march stays exact with them: a delay that is
not a whole number of samples moves the input's kinks off the samples, and
each sample interval is stepped in pieces between the kinks.  An output
recorded late (a sensor delay) is read where it was, at t - d: the march
stops there too (the F-term path reads its interpolant there).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy import interpolate, linalg, signal

from .errors import ParameterError, RecordError
from .maneuvers import DEFAULT_AMPLITUDE, DRYDEN_L, dryden_gust, make_input, time_vector
from .models.realization import Realization, _System, _system, realize
from .record import Record, add_noise, check_noise, uniform_interval

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
#: A delayed input's kink closer than this fraction of dt to a sample counts as on it.
_KINK_RTOL = 1e-9
#: Relative tolerance on the spacing of the time vector.
_UNIFORM_RTOL = 1e-6
#: F-term models: largest input at t = 0, relative to its peak, treated as starting from zero.
_START_RTOL = 1e-9


# --- integrators ----------------------------------------------------------------------


def _foh_steps(sys: _System, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phi, Gamma1, Gamma2 of a step h for an input linear over it: ``expm([[A, B, 0], [0, 0, I], [0, 0, 0]] h)``.

    ``x(t + h) = Phi x(t) + Gamma1 u(t) + Gamma2 (u(t + h) - u(t))``.
    """
    ns, nu = sys.B.shape
    M = np.zeros((ns + 2 * nu, ns + 2 * nu))
    M[:ns, :ns] = sys.A * h
    M[:ns, ns : ns + nu] = sys.B * h
    M[ns : ns + nu, ns + nu :] = np.eye(nu)
    Ex = linalg.expm(M)
    return Ex[:ns, :ns], Ex[:ns, ns : ns + nu], Ex[:ns, ns + nu :]


def _pieces(sys: _System, dt: float) -> np.ndarray:
    """Where the march stops in a sample interval [0, dt]: its ends, the delayed inputs' kinks, the outputs' reads.

    An input u(t - d) bends at ``d mod dt`` after each sample; an output recorded d late is read at
    ``t_k - d``, ``-d mod dt`` after a sample.
    """
    at = [d % dt for _, d in sys.channels] + [-d % dt for d in sys.out_delay]
    inside = [f for f in at if _KINK_RTOL * dt < f < (1.0 - _KINK_RTOL) * dt]
    return np.unique(np.r_[0.0, inside, dt])


def _foh_march(sys: _System, dt: float, tau: np.ndarray, sig: Mapping[str, np.ndarray]):
    """States of inputs linear between their samples, each delayed by its channel's d: exact (x(0) = 0).

    A delayed input ``u(t - d)`` is linear between its kinks at ``t_k + d``, so each sample interval
    is stepped in pieces (:func:`_pieces`), one exact first-order-hold step (:func:`_foh_steps`)
    each.  Sampling the delayed input and holding it linear between the samples instead would
    smooth it like a short lag.

    Returns
    -------
    pieces : numpy.ndarray
        Where the pieces start in a sample interval, s, and its end dt, shape (p + 1,).
    x : numpy.ndarray
        The states at the samples, shape (n, ns).
    partial : list of tuple
        Per piece, ``(Phi, drive)``: the state at ``t_k + pieces[j]`` is ``Phi x_k + drive[k]``.
    """
    s = _pieces(sys, dt)
    ns = sys.A.shape[0]
    # each piece's input at its start, and just before its end: an input that does not start at 0 steps
    # up from rest at t = d, where the piece that ends there still holds 0
    at = [np.column_stack([_delayed(tau[:-1] + sj, sig[nm], d, tau) for nm, d in sys.channels]) for sj in s]
    before = [np.column_stack([_delayed(tau[:-1] + sj, sig[nm], d, tau, True) for nm, d in sys.channels]) for sj in s]
    Phi, drive = np.eye(ns), np.zeros((tau.size - 1, ns))
    partial = []
    for j in range(s.size - 1):  # the pieces in turn: drive_k <- Phi_j drive_k + its own forcing
        partial.append((Phi, drive))
        P, G1, G2 = _foh_steps(sys, s[j + 1] - s[j])
        drive = drive @ P.T + at[j] @ (G1 - G2).T + before[j + 1] @ G2.T
        Phi = P @ Phi
    x = np.zeros((tau.size, ns))
    for k in range(tau.size - 1):  # linear recursion; the work per step is a small matrix product
        x[k + 1] = Phi @ x[k] + drive[k]
    return s, x, partial


def _simulate_foh(sys: _System, tau: np.ndarray, dt: float, sig: Mapping[str, np.ndarray]) -> np.ndarray:
    """Every output at its own delay, ``y_i(t - d_i)``, for inputs linear between their samples: exact.

    An output recorded d late is read where it was, at ``t_k - d``: one of the march's stops
    (:func:`_foh_march`).  Before the start the outputs are zero (rest); an advance past the end
    holds the last value.  The rate feedthrough (``Dd``, a_z of alpha_w_dot) takes central
    differences of the delayed inputs.
    """
    s, x, partial = _foh_march(sys, dt, tau, sig)
    u = np.column_stack([_delayed(tau, sig[nm], d, tau) for nm, d in sys.channels])
    rates = np.gradient(u, dt, axis=0)
    y = x @ sys.C.T + u @ sys.D.T + rates @ sys.Dd.T
    for i, d in enumerate(sys.out_delay):
        if d != 0.0:
            read = np.clip(tau - d, tau[0], tau[-1])
            ui = np.column_stack([_delayed(read, sig[nm], dc, tau) for nm, dc in sys.channels])
            ri = np.column_stack([np.interp(read, tau, r) for r in rates.T])
            delayed = _states_at(read, d, s, x, partial, dt) @ sys.C[i] + ui @ sys.D[i] + ri @ sys.Dd[i]
            delayed[tau - d > tau[-1]] = y[-1, i]
            delayed[tau - d < tau[0] - _KINK_RTOL * dt] = 0.0
            y[:, i] = delayed
    return y


def _states_at(read: np.ndarray, d: float, s: np.ndarray, x: np.ndarray, partial: list, dt: float) -> np.ndarray:
    """The states at the times ``read`` of an output recorded ``d`` late: stops of :func:`_foh_march`.

    Each read time is ``t_k - d``: a sample plus ``r = -d mod dt`` (0 when d is whole samples).
    """
    r = -d % dt
    r = 0.0 if min(r, dt - r) <= _KINK_RTOL * dt else r
    k = np.clip(np.round((read - r) / dt).astype(int), 0, x.shape[0] - 1)
    if r == 0.0:
        return x[k]
    Phi, drive = partial[int(np.argmin(np.abs(s - r)))]
    k = np.minimum(k, x.shape[0] - 2)
    return x[k] @ Phi.T + drive[k]


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
        The number of steps m, at least 2.
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
        The rate r(t_n), e.g. alpha_dot in rad/s, on the grid t_n = n h; ``rate[0]`` must
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
    needed = model.inputs
    missing = [k for k in needed if k not in inputs]
    if missing:
        extra = " (the model has a gust input; pass alpha_w, rad)" if "alpha_w" in missing else ""
        raise RecordError(f"simulate: missing input(s) {', '.join(missing)}{extra}")
    unknown = [k for k in inputs if k not in needed]
    if unknown:
        hint = " (the model has no gust input; build it with --gust, Python: gust=True)" if "alpha_w" in unknown else ""
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


def _check_noise(noise, rng, outputs):
    """simulate's absolute noise: a mapping of standard deviations (:func:`fdml.record.check_noise`) of
    the model's outputs, and a generator."""
    if noise is None:
        return None
    if not isinstance(noise, Mapping):
        raise ParameterError("noise must be a mapping {'alpha': rad, 'q': rad/s, 'az': g} of standard deviations")
    out = check_noise(noise)
    bad = [k for k in out if k not in outputs]
    if bad:
        raise ParameterError(
            f"unknown noise channel(s) {', '.join(map(str, bad))}; channels of this model: {', '.join(outputs)}"
        )
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
        ``{"alpha": rad, "q": rad/s, "az": g}`` (and ``theta``, ``qdot`` of a model
        that predicts them); needs ``rng``.
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
        Signals de, alpha (rad), q (rad/s), az (g, positive down), the model's
        other outputs (theta rad, qdot rad/s^2) and alpha_w for a gust model,
        with output biases and noise added.  ``meta`` holds
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
    noise = _check_noise(noise, rng, model.outputs)
    p = model.values(values)
    for key in ("tau_de", "tau_alpha_w"):
        if key in p and not (math.isfinite(p[key]) and p[key] >= 0):
            raise ParameterError(f"{key} must be a delay >= 0 s, got {p[key]}")
    sys = _system(model, p)
    tau = t - t[0]
    if sys.kappa == 0.0:
        y = _simulate_foh(sys, tau, dt, sig)
        integration = {"method": "exact first-order-hold discretisation (matrix exponential)"}
    else:
        y, integration = _simulate_memory(sys, tau, dt, sig, substeps, pole_steps)
    y = y + np.array([p[f"bias_{k}"] for k in sys.outputs])
    if noise:
        for i, k in enumerate(sys.outputs):  # fixed channel order: reproducible for a given seed
            if k in noise:
                y[:, i] += noise[k] * rng.standard_normal(t.size)
    signals = {"de": sig["de"], **{k: y[:, i] for i, k in enumerate(sys.outputs)}}
    if model.gust:
        signals["alpha_w"] = sig["alpha_w"]
    meta = {"model": model.kind, "values": p, "noise": noise, "U": model.U, "integration": integration}
    return Record(t, signals, name=name, meta=meta, check_units=False)


def _delayed(tau_out, u, delay: float, tau_in, left_limit: bool = False) -> np.ndarray:
    """u(t - delay) by linear interpolation, zero before t = 0, held after the end.

    ``left_limit``: the value just before each time, 0 at t - delay = 0 itself (where an input that
    does not start at 0 steps up from rest).
    """
    x = np.asarray(tau_out, dtype=float) - delay
    out = np.interp(x, tau_in, u, left=0.0, right=u[-1])
    if left_limit:
        out[x <= tau_in[0] + _KINK_RTOL * (tau_in[1] - tau_in[0])] = 0.0
    return out


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
    states, eps_F = interpolate.CubicHermiteSpline(tk, x, xdot, axis=0), interpolate.CubicSpline(tk, eps)
    y = np.zeros((tau.size, len(sys.outputs)))
    for i, d in enumerate(sys.out_delay):  # each output read d_i late: zero before the start, held after the end
        read = np.clip(tau - d, tau[0], tau[-1])
        u_s = np.column_stack([_delayed(read, sig[nm], dc, tau) for nm, dc in sys.channels])
        y[:, i] = states(read) @ sys.C[i] + u_s @ sys.D[i] + eps_F(read) * sys.dF[i]
        y[tau - d < tau[0] - _KINK_RTOL * dt, i] = 0.0
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
        The model to simulate.
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
    level = None if noise is None else check_noise(noise)
    fraction = None if isinstance(level, dict) else level  # a number is a fraction of each output's RMS
    absolute = level if isinstance(level, dict) else None
    rec = simulate(
        model, t, inputs, values, noise=absolute, rng=rng if absolute else None, name=f"{maneuver} simulation"
    )
    meta = {**rec.meta, "maneuver": maneuver, "seed": seed, "gust_std": gust_std}
    if fraction is not None:
        rec = add_noise(rec, fraction, rng, relative=True)
        meta.update(noise=rec.meta["noise_std"], noise_fraction=fraction)
    return Record(rec.t, rec.signals, name=rec.name, meta=meta, check_units=False)
