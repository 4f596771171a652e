"""Unsteady aerodynamics: indicial functions and their transforms.

Time-domain indicial responses and their frequency-domain transfer functions,
as pure functions of ``s = j omega`` (rad/s) vectorised over frequency:

* Eq. 1 / Eq. 17, the Wells-Keskar lift lag ``N(s)`` with constants (y, z);
* Eq. 2 / Eq. 16, the tail downwash ``E(s)`` with constants F, G, H and the
  principal-branch exponential integral;
* BS-12 / BS-17, the Kussner gust lag ``K(s)`` with weights summing to one;
* R. T. Jones-type Wagner and Kussner approximations as named presets.

References are to ``docs/theory.md`` (equation and section numbers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ParameterError

__all__ = [
    "lift_lag",
    "downwash",
    "downwash_pole_time",
    "kussner",
    "lift_indicial",
    "downwash_indicial",
    "kussner_indicial",
    "IndicialFunction",
    "INDICIAL_PRESETS",
    "get_indicial",
]


def lift_lag(s, a: float, y: float, z: float, U: float, c: float):
    """Wells-Keskar lift transfer function N(s), docs/theory.md Eq. 17.

    ``N(s) = a [1 - s y / (s + 2 z U / c)]``, the transform ``s L{C_La(t)}``
    of the indicial lift of Eq. 1.

    Parameters
    ----------
    s : array_like of complex
        Laplace variable, usually ``1j * omega`` with omega in rad/s.
    a : float
        Steady lift slope (C_La)_ss, 1/rad.
    y, z : float
        Lag amplitude (-) and rate per semichord travelled (-).
    U : float
        Airspeed, m/s.
    c : float
        Reference chord, m (the wing root chord in the paper's Eq. 17).

    Returns
    -------
    ndarray of complex
        N(s), 1/rad.
    """
    s = np.asarray(s, dtype=complex)
    lam = 2.0 * z * U / c  # Eq. 17: rate 2zU/c, 1/s
    return a * (1.0 - s * y / (s + lam))


def downwash_pole_time(l: float, U: float, c: float) -> float:
    """Time T = (l - c)/U of the starting-vortex pole of Eq. 2, s.

    Parameters
    ----------
    l : float
        Tail length, m.
    U : float
        Airspeed, m/s.
    c : float
        Wing reference chord, m.

    Returns
    -------
    float
        The pole time T, s (positive when the tail is longer than the chord).
    """
    return (l - c) / U


def positive_pole_time(l: float, U: float, c: float) -> float:
    """:func:`downwash_pole_time`, s, where the F-term needs it: a pole time that is not positive is an error."""
    T = downwash_pole_time(l, U, c)
    if T <= 0.0:
        raise ParameterError(
            f"the downwash pole time T = (l_t - c_w)/U = {T:.4g} s must be positive: "
            f"tail length l_t = {l} m must exceed the wing chord c_w = {c} m"
        )
    return T


def downwash(s, eps_ss: float, F: float, G: float, H: float, l: float, U: float, c: float):
    """Wells-Keskar tail downwash transfer function E(s), docs/theory.md Eq. 16.

    ``E(s) = eps_ss [1 - s G/(s + 2HU/c) - (s c F/U) Ei(s T) exp(-s T)]`` with
    ``T = (l - c)/U`` and Ei the principal-branch exponential integral
    (``scipy.special.expi`` on complex arguments; docs/theory.md section 5 shows that
    ``-exp1(-z)`` drops a ``j pi`` and is wrong).  ``E(0) = eps_ss``: the
    ``s Ei(sT)`` term vanishes like ``s ln s`` and is set to its limit at s = 0.

    Parameters
    ----------
    s : array_like of complex
        Laplace variable, rad/s.
    eps_ss : float
        Steady downwash gradient (d eps/d alpha)_ss, -.
    F, G, H : float
        Eq. 2 constants (starting-vortex pole strength, lag amplitude, lag rate).
    l : float
        Tail length, m; must exceed ``c`` when F != 0.
    U : float
        Airspeed, m/s.
    c : float
        Wing reference chord, m.

    Returns
    -------
    ndarray of complex
        E(s), -.
    """
    s = np.asarray(s, dtype=complex)
    lam_g = 2.0 * H * U / c  # G-lag rate 2HU/c_w, 1/s (Eq. 16)
    bracket = 1.0 - s * G / (s + lam_g)
    if F != 0.0:
        T = positive_pole_time(l, U, c)
        from scipy import special  # imported here: only the F term needs it

        nz = s != 0
        fterm = np.zeros_like(s)
        sz = s[nz]
        # Eq. 16: principal-branch Ei (scipy expi), exp(-sT) with the minus sign restored
        fterm[nz] = (sz * c * F / U) * special.expi(sz * T) * np.exp(-sz * T)
        bracket = bracket - fterm
    return eps_ss * bracket


def kussner(s, b, U: float, c: float, weights=None):
    """Kussner gust-lift lag K(s) of Braunschweig Eq. BS-12.

    ``K(s) = sum_i a_i / (T_i s + 1)``, ``T_i = c b_i / (2 U)``, weights
    ``a_i`` summing to one so that K(0) = 1 (docs/theory.md section 8 caveat: the
    printed BS-12 has unit weights, which would give a steady gain N).

    Parameters
    ----------
    s : array_like of complex
        Laplace variable, rad/s.
    b : float or sequence of float
        Lag lengths b_i in semichords (BS Table 1: b1 about 6-8).
    U : float
        Airspeed, m/s.
    c : float
        Mean chord, m.
    weights : sequence of float, optional
        Weights a_i (default equal); they must sum to one.

    Returns
    -------
    ndarray of complex
        K(s), -.
    """
    s = np.asarray(s, dtype=complex)
    b = np.atleast_1d(np.asarray(b, dtype=float))
    weights = np.full(b.shape, 1.0 / b.size) if weights is None else np.asarray(weights, dtype=float)
    if weights.shape != b.shape:
        raise ParameterError("Kussner weights and lag lengths must have the same length")
    if abs(weights.sum() - 1.0) > 1e-9:
        raise ParameterError(f"Kussner weights must sum to one (K(0) = 1), they sum to {weights.sum():.6g}")
    if np.any(b < 0):
        raise ParameterError("Kussner lag lengths b_i must be non-negative")
    T = c * b / (2.0 * U)  # BS-12: T_i = c b_i / (2V), s
    return np.sum(weights[:, None] / (np.multiply.outer(T, s.ravel()) + 1.0), axis=0).reshape(s.shape)


# --- time domain ---------------------------------------------------------------


def lift_indicial(t, y: float, z: float, U: float, c: float):
    """Normalised indicial lift of Eq. 1, ``1 - y exp(-2 z U t / c)`` for t >= 0.

    Parameters
    ----------
    t : array_like
        Time since the step, s.
    y, z : float
        Lag amplitude (-) and rate per semichord travelled (-).
    U : float
        Airspeed, m/s.
    c : float
        Reference chord, m.

    Returns
    -------
    numpy.ndarray
        The indicial lift C_La(t)/(C_La)_ss, -, same shape as ``t`` (0 for t < 0).
    """
    t = np.asarray(t, dtype=float)
    return np.where(t >= 0, 1.0 - y * np.exp(-2.0 * z * U * np.maximum(t, 0.0) / c), 0.0)


def downwash_indicial(t, F: float, G: float, H: float, l: float, U: float, c: float):
    """Normalised indicial downwash of Eq. 2 (divide out (d eps/d alpha)_ss).

    ``1 + F [1 - (l - U t)/c]^(-1) - G exp(-2 H U t / c)`` for t >= 0; the F term
    equals ``F c / (U (t - T))`` and has a simple pole at ``T = (l - c)/U``,
    where this function returns ``inf`` (the Duhamel integral of Eq. 10 is a
    Cauchy principal value there).

    Parameters
    ----------
    t : array_like
        Time since the step, s.
    F, G, H : float
        Eq. 2 constants (starting-vortex pole strength, lag amplitude, lag rate).
    l : float
        Tail length, m.
    U : float
        Airspeed, m/s.
    c : float
        Wing reference chord, m.

    Returns
    -------
    numpy.ndarray
        The normalised indicial downwash, -, same shape as ``t`` (0 for t < 0).
    """
    t = np.asarray(t, dtype=float)
    T = downwash_pole_time(l, U, c)
    with np.errstate(divide="ignore"):
        fterm = np.where(t == T, np.inf, F * c / (U * (t - T)))
    val = 1.0 + fterm - G * np.exp(-2.0 * H * U * np.maximum(t, 0.0) / c)
    return np.where(t >= 0, val, 0.0)


def kussner_indicial(tau, b, weights=None):
    """Indicial gust lift of BS-17 in semichords tau: ``1 - sum a_i exp(-tau / b_i)``.

    Parameters
    ----------
    tau : array_like
        Distance travelled since the gust front, semichords.
    b : float or sequence of float
        Lag lengths b_i, semichords.
    weights : sequence of float, optional
        Weights a_i (default equal).

    Returns
    -------
    numpy.ndarray
        The normalised indicial gust lift, -, same shape as ``tau`` (0 for tau < 0).
    """
    b = np.atleast_1d(np.asarray(b, dtype=float))
    w = np.full(b.shape, 1.0 / b.size) if weights is None else np.asarray(weights, float)
    return IndicialFunction("kussner", tuple(w), tuple(1.0 / b)).step(tau)  # rates 1/b_i per semichord


@dataclass(frozen=True)
class IndicialFunction:
    """An exponential-sum indicial function ``phi(tau) = 1 - sum A_i exp(-beta_i tau)``.

    ``tau = 2 U t / c`` is the distance travelled in semichords.  Its transfer
    function (``s`` times the Laplace transform of ``phi(2Ut/c)``) is
    ``1 - sum A_i s / (s + 2 beta_i U / c)``.

    Parameters
    ----------
    name : str
        The preset's name.
    amplitudes : tuple of float
        Amplitudes A_i, -.
    rates : tuple of float
        Rates beta_i, per semichord.
    source : str
        Citation, with [MEM] where it is quoted from memory.
    """

    name: str
    amplitudes: tuple
    rates: tuple
    source: str = ""

    def step(self, tau):
        """The normalised indicial response phi(tau), tau in semichords.

        Parameters
        ----------
        tau : array_like
            Distance travelled, semichords.

        Returns
        -------
        numpy.ndarray
            The response phi, -, same shape as ``tau`` (0 for tau < 0).
        """
        tau = np.asarray(tau, dtype=float)
        A = np.asarray(self.amplitudes)[:, None]
        b = np.asarray(self.rates)[:, None]
        val = 1.0 - np.sum(A * np.exp(-b * np.maximum(tau, 0).ravel()), axis=0)
        return np.where(tau >= 0, val.reshape(tau.shape), 0.0)

    def transfer(self, s, U: float, c: float):
        """Transfer function ``1 - sum A_i s/(s + 2 beta_i U/c)`` at s (rad/s).

        Parameters
        ----------
        s : array_like of complex
            Laplace variable, rad/s.
        U : float
            Airspeed, m/s.
        c : float
            Reference chord, m.

        Returns
        -------
        numpy.ndarray
            The transfer function, complex, -, same shape as ``s``.
        """
        s = np.asarray(s, dtype=complex)
        out = np.ones_like(s)
        for A, b in zip(self.amplitudes, self.rates):  # a few terms, not frequencies
            out = out - A * s / (s + 2.0 * b * U / c)
        return out

    @property
    def mean_lag(self) -> float:
        """Integral of (1 - phi) over tau from 0 to infinity, semichords."""
        return float(sum(A / b for A, b in zip(self.amplitudes, self.rates)))


#: Named R. T. Jones-type approximations (docs/theory.md sections 2 and 8).
INDICIAL_PRESETS = {
    "wagner_jones_2d": IndicialFunction(
        "wagner_jones_2d",
        (0.165, 0.335),
        (0.0455, 0.3),
        "R. T. Jones 2-D Wagner approximation (found in stored code, docs/theory.md 8)",
    ),
    "kussner_jones_2d": IndicialFunction(
        "kussner_jones_2d",
        (0.5, 0.5),
        (0.13, 1.0),
        "Sears-Sparks/Jones 2-D Kussner approximation (AeroSandbox kussners_function, docs/theory.md 8)",
    ),
    "wagner_jones_ar6": IndicialFunction(
        "wagner_jones_ar6",
        (0.361,),
        (0.381,),
        "R. T. Jones, NACA Rep. 681, elliptic wing AR 6 [MEM] (docs/theory.md 2)",
    ),
    "wagner_jones_ar3": IndicialFunction(
        "wagner_jones_ar3",
        (0.283,),
        (0.540,),
        "R. T. Jones, NACA Rep. 681, elliptic wing AR 3 [MEM] (docs/theory.md 2)",
    ),
    "kussner_jones_ar6": IndicialFunction(
        "kussner_jones_ar6",
        (0.448, 0.272, 0.193),
        (0.29, 0.725, 3.0),
        "R. T. Jones finite-wing gust function AR 6 [MEM, unverified] (docs/theory.md 8)",
    ),
}


def get_indicial(name: str) -> IndicialFunction:
    """Return a named :class:`IndicialFunction` preset.

    Parameters
    ----------
    name : str
        A key of :data:`INDICIAL_PRESETS`.

    Returns
    -------
    IndicialFunction
        The preset.
    """
    try:
        return INDICIAL_PRESETS[name]
    except KeyError:
        raise ParameterError(f"unknown indicial preset {name!r}; presets: {', '.join(INDICIAL_PRESETS)}") from None
