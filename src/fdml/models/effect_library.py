"""The built-in library of candidate effects (registered by :mod:`fdml.models.effects`).

=====================  =========  ============================================================
effect                 channel    augmentation (null in brackets)
=====================  =========  ============================================================
lift_lag               alpha      Wells-Keskar wing lift lag y_w (Eq. 1/17) [0 on a steady
                                  model, the base value on the unsteady one]; Z_alpha times
                                  1 - y s/(s + 2 z U/c) on the derivatives/dimensional models
downwash_lag           q          Wells-Keskar downwash lag amplitude G (Eq. 2/16), or an
                                  alpha-dot moment (Cm_adot, M_adot) [0]
downwash_lag           tail       a share g_dw of the downwash reaches the tail tau_dw late
                                  (nuisance; textbook: g_dw = 1, tau_dw = l_t/U), BS-8 applied
                                  to the downwash [g_dw = 0]; steady/unsteady models
gust_lag               alpha_w    Kussner lag of the measured gust: b1 (BS-12) or a lag
                                  T_gust [0]
gust_lag               tail       delay of the gust at the tail, tau_tail (BS-8) [0]
time_delay             de         pure input delay tau_de [0, one-sided]
time_delay             alpha|q|az pure delay on one output channel [0, two-sided]
actuator_lag           de         recorded -> effective elevator 1/(1 + T_act s) [0]
sensor_offset          az         accelerometer x_az ahead of the c.g.: a_z - x q_dot/g [0]
sensor_offset          alpha      vane x_alpha ahead of the c.g.: alpha - x q/U [0]
structural_mode        q,az       lightly damped mode on q (s w/D) and a_z (s^2/D),
                                  D = s^2 + 2 zeta w s + w^2, residues r_q, r_az [0]
sensor_scale           alpha|q|az gain error 1 + k on one channel [0]
unmeasured_gust        alpha,q,az turbulence sigma_w along the model's gust column
                                  (noise kind; tested on the input-incoherent residual) [0]
=====================  =========  ============================================================

Effect sizes are in physical units (s, m, -, rad/s per rad ...); each
parameter carries a plausible range used by the identifiability screen
(minimum detectable effect) and the plausibility check.

Each effect's validation truth, the time-domain simulation the diagnosis is
checked against, is written independently of the code here, on purpose: see
:data:`fdml.diagnose.truth.TRUTHS`, keyed like the registry (an effect that
frees a model parameter is simulated as that model; the lags of the
dimensional and derivatives models have no truth).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..channels import INPUT, OUTPUTS, STATIONS
from ..errors import ParameterError
from .augment import (
    Effect,
    FreeParameterEffect,
    MatrixEffect,
    OutputEffect,
    Param,
    root_model,
)
from .base import Model
from .realization import (
    _pad_states,
    add_mode,
    delay_output,
    filter_input,
    scale_output,
)
from .wells_keskar import SteadyModel, UnsteadyModel

__all__ = ["Dispatch", "StationEffect", "UnmeasuredGust", "to_unsteady_equivalent", "JONES_Z"]

#: R. T. Jones' one-term lift-lag rate for an AR 6 elliptic wing, per semichord
#: (docs/theory.md section 2, [MEM]); used when the aircraft gives none.
JONES_Z = 0.381
#: Default structural-mode damping ratio during the frequency grid search.
MODE_ZETA = 0.05


class Dispatch(Effect):
    """One library effect implemented differently per base-model kind.

    Parameters
    ----------
    name, channel : str
        Library name and the channel it applies to.
    impls : dict
        Base-model kind (``"unsteady"``, ``"steady"``, ...) -> the :class:`Effect` implementing it there.
    signature : str, optional
        One line on where the effect shows, for reports.
    needs : tuple of str, optional
        Record channels required.
    """

    def __init__(self, name: str, channel: str, impls: dict, *, signature: str = "", needs=()):
        self.impls = dict(impls)
        first = next(iter(self.impls.values()))
        self._describe(name, channel, first.params, needs, signature)
        self.nuisance_grid = first.nuisance_grid

    def impl(self, model: Model):
        """The implementation for ``model``'s base kind (None if the effect does not apply).

        Parameters
        ----------
        model : Model
            A plain or augmented model.

        Returns
        -------
        Effect or None
            The implementation.
        """
        return self.impls.get(root_model(model).kind)

    def applicable(self, model, inputs=(INPUT,), outputs=OUTPUTS):
        imp = self.impl(model)
        if imp is None:
            return f"not defined for the {root_model(model).kind} model"
        return imp.applicable(model, inputs, outputs)

    def param_list(self, model):
        imp = self.impl(model)
        return imp.param_list(model) if imp is not None else self.params

    def nulls(self, model):
        return self.impl(model).nulls(model)

    def augment(self, model):
        return self.impl(model).augment(model)


# --- base-model helpers ----------------------------------------------------------------------


def to_unsteady_equivalent(root: Model) -> Model:
    """The steady Wells-Keskar model rewritten as the unsteady one with every lag off.

    With y_w = y_t = F = G = 0, b1 = 0 (K = 1) and no tail gust delay, Eqs. 13-17
    reduce exactly to the quasi-steady model (docs/theory.md section 6); so the
    lag parameters can be freed one at a time as nested augmentations.

    Parameters
    ----------
    root : Model
        A plain steady or unsteady model.

    Returns
    -------
    Model
        The unsteady model with the same values, the lags off and the same
        free parameters (``root`` itself when unsteady).
    """
    if root.kind == "unsteady":
        return root
    if root.kind != "steady":
        raise ParameterError(f"no unsteady equivalent of the {root.kind} model")
    assert isinstance(root, SteadyModel)  # the "steady" kind (a root model)
    ac = root.aircraft  # its lags are set to zero below: "none" is the source
    ac = ac if ac.lag_status else ac.with_changes(lag_constants="none")
    u = UnsteadyModel(aircraft=ac, gust=root.gust, output_bias=root.output_bias, tail_gust_delay=False)
    vals = {k: v for k, v in root.parameters.values.items() if k in u.parameters}
    vals.update({"y_w": 0.0, "y_t": 0.0, "F": 0.0, "G": 0.0})
    if root.gust:
        vals["b1"] = 0.0
    params = u.parameters.with_values(vals)
    return u.with_parameters(params.only_free([n for n in root.parameters.free_names if n in params]))


def _needs_chord(root: Model) -> str | None:
    return None if getattr(root, "aircraft", None) is not None else "needs the wing chord (give an aircraft)"


def _needs_gust(root: Model) -> str | None:
    return None if root.gust else "needs the measured gust angle alpha_w in the model (--gust)"


def _amplitude(name: str, null: float | None, plausible: float, description: str, upper: float = 1.0) -> Param:
    """A lag's amplitude (a share), -: from 0 to ``upper``, plausible up to ``plausible``."""
    return Param(
        name, null, lower=0.0, upper=upper, plausible=(0.0, plausible), unit="-", start=0.05, description=description
    )


def _seconds(
    name: str, null: float | None = 0.0, *, upper: float, plausible: float, start: float, description: str = ""
):
    """A delay or time constant, s: never negative, plausible up to ``plausible`` s."""
    return Param(
        name, null, lower=0.0, upper=upper, plausible=(0.0, plausible), unit="s", start=start, description=description
    )


# --- lift lag --------------------------------------------------------------------------------


def _lift_lag_constants(p, root):
    """(Z_alpha, lag rate 2 z U / c) of the lift lag on a conventional base model."""
    ac = root.aircraft
    z = float(ac.constants.get("z_w", JONES_Z)) or JONES_Z
    lam = 2.0 * z * root.U / ac.c_w  # Eq. 17 rate 2 z U / c, 1/s
    # Z_alpha = A00 = -M00 at s = 0 (M = sE - A with constant A on these models)
    M0 = root._matrices(np.zeros(1, complex), {k: p[k] for k in root.parameters.names})[0]
    return -M0[0, 0, 0].real, lam


def _lift_lag_matrix(s, p, M, B, E, root):
    Za, lam = _lift_lag_constants(p, root)
    M = M.copy()
    M[:, 0, 0] = M[:, 0, 0] + Za * p["y_lift"] * s / (s + lam)  # A00 -> Z_a (1 - y s/(s + lam))
    return M, B, E


def _lift_lag_realize(d, p, root):
    """Z_a (1 - y s/(s + lam)) alpha = Z_a (1 - y) alpha + Z_a y x_l,  x_l' = lam (alpha - x_l)."""
    Za, lam = _lift_lag_constants(p, root)
    y = p["y_lift"]
    n = d.A.shape[0]
    col = np.zeros(n)
    col[0] = Za * y
    row = np.zeros(n + 1)
    row[0], row[n] = lam, -lam
    d = d.with_state(row, col)
    d.A[0, 0] -= Za * y
    return d


_LIFT_Y = "wing lift-lag amplitude (Eq. 1)"
_WK_LIFT_Y = FreeParameterEffect(
    "lift_lag", "alpha", _amplitude("y_w", None, 0.6, _LIFT_Y), ("unsteady", "steady"), convert=to_unsteady_equivalent
)
_LIFT_Z = MatrixEffect(
    "lift_lag",
    "alpha",
    (_amplitude("y_lift", 0.0, 0.6, _LIFT_Y),),
    _lift_lag_matrix,
    applies=_needs_chord,
    realize=_lift_lag_realize,
)
LIFT_LAG = Dispatch(
    "lift_lag",
    "alpha",
    {"unsteady": _WK_LIFT_Y, "steady": _WK_LIFT_Y, "derivatives": _LIFT_Z, "dimensional": _LIFT_Z},
    signature="lift builds up with a lag: alpha and a_z, magnitude dip and phase lag in the short-period band",
)


# --- downwash lag --------------------------------------------------------------------------


def _adot_matrix(s, p, M, B, E, root):
    M = M.copy()
    M[:, 1, 0] = M[:, 1, 0] - s * p["M_adot"]  # q_dot += M_adot alpha_dot: E[1,0] = -M_adot
    if root.gust:
        B = B.copy()
        B[:, 1, 1] = B[:, 1, 1] + s * p["M_adot"]  # the gust enters as alpha + alpha_w
    return M, B, E


def _adot_realize(d, p, root):
    """q' = ... + M_adot (alpha' [+ alpha_w']): E[1, 0] = -M_adot, B1[1, alpha_w] = M_adot."""
    E, B1 = d.E.copy(), d.B1.copy()
    E[1, 0] -= p["M_adot"]
    if root.gust:
        B1[1, 1] += p["M_adot"]
    return type(d)(E, d.A, d.B0, B1, d.channels)


# On both Wells-Keskar models the downwash lag frees G (the steady model is rewritten as the
# unsteady one with every lag off, docs/theory.md section 6): one effect serves both.
_WK_DOWNWASH_G = FreeParameterEffect(
    "downwash_lag",
    "q",
    _amplitude("G", None, 1.0, "downwash lag amplitude (Eq. 2)"),
    ("unsteady", "steady"),
    convert=to_unsteady_equivalent,
    bounds=(0.0, 1.0),
)

DOWNWASH_LAG = Dispatch(
    "downwash_lag",
    "q",
    {
        "unsteady": _WK_DOWNWASH_G,
        "steady": _WK_DOWNWASH_G,
        "derivatives": FreeParameterEffect(
            "downwash_lag",
            "q",
            Param("Cm_adot", None, plausible=(-20.0, 5.0), unit="1/rad", start=0.5),
            ("derivatives",),
        ),
        "dimensional": MatrixEffect(
            "downwash_lag",
            "q",
            (Param("M_adot", 0.0, plausible=(-5.0, 1.0), unit="1/s", start=0.05),),
            _adot_matrix,
            realize=_adot_realize,
        ),
    },
    signature="tail downwash lags alpha: q (and alpha) in the short-period band, like an alpha-dot moment",
)


# --- downwash lag in its textbook form: the downwash reaches the tail l_t/U late ----------------
#
# The classical origin of Cm_adot: eps(t) = eps_ss alpha(t - l_t/U).  Form chosen with docs/theory.md:
# * the alpha-dot term is only its first order in s; on the steady model that signature is the one the
#   derivatives absorb (M_adot alpha_dot = M_adot (q + Z_a alpha + Z_de de): 99.97 % aliased on the
#   Navion), so what tells a downwash lag from an elevator lag is the second-order part;
# * a lag 1/(1 + s tau) (Eq. 16's G-term with its rate free) has the same first order but twice the
#   delay's second-order term, (s tau)^2 against (s tau)^2/2: it gets exactly that part wrong;
# * so the transport delay itself, as BS-8 delays the gust at the tail: a share g of the quasi-steady
#   downwash arrives tau later, E -> eps_ss [(1 - g) + g exp(-s tau)] (g = 1, tau = l_t/U textbook).
#   g is tested (null 0) with tau a nuisance on a grid, like a structural mode's frequency.
# A delay inside the alpha loop has no finite-state form (a delay-differential equation): the time-domain
# realisation uses an [8/8] Pade approximant of exp(-s tau) (error below 3e-14 for omega tau <= 2,
# 2.5e-11 at omega tau = 3).  On the unsteady model the instantaneous part (1 - G) eps_ss alpha is delayed.

#: Order of the Pade approximant of the downwash delay in the time-domain realisation.
DW_PADE = 8


def _dw_share(p) -> float:
    """g eps_ss (1 - G): the delayed part of the downwash (section 4 finite-state form)."""
    return p["g_dw"] * p["deps_da"] * (1.0 - p.get("G", 0.0))


def _dw_delay_matrix(s, p, M, B, E, root):
    """eps -> eps - g eps_ss (1 - G)(1 - exp(-s tau)) alpha: C_Lt per alpha gains N_t times that."""
    ac = root.aircraft
    _, n_t, _, _ = root._parts(s, p)
    dCLt = p["CLa_t"] * n_t * _dw_share(p) * (1.0 - np.exp(-s * p["tau_dw"]))  # Eq. 16, C_Lt = N_t (1 - E)
    sr = ac.S_t / ac.S_w
    M = M.copy()
    M[:, 0, 0] = M[:, 0, 0] + ac.k_z * sr * dCLt  # Eq. 13
    M[:, 1, 0] = M[:, 1, 0] + ac.k_m * (p["l_t"] * sr / ac.c_w) * dCLt  # Eq. 14
    return M, B, E


def pade_delay(tau: float, n: int = DW_PADE):
    """State space (A, B, C, D) of the [n/n] Pade approximant of exp(-s tau), tau > 0 in s.

    Built in sigma = s tau (coefficients c_k = (2n-k)! n! / ((2n)! k! (n-k)!)) and rescaled, so
    the realisation stays well conditioned for small tau.
    """
    k = np.arange(n + 1)
    f = math.factorial
    c = np.array([f(2 * n - j) * f(n) / (f(2 * n) * f(j) * f(n - j)) for j in k])
    num, den = (c * (-1.0) ** k)[::-1] / c[n], c[::-1] / c[n]  # descending powers of sigma, monic
    # controller canonical form, as scipy.signal.tf2ss builds it (written here because importing
    # scipy.signal costs about 1 s on the fit path, issue 20): D the direct term, A the companion
    # matrix of den, C the strictly proper remainder's numerator
    D = np.array([[num[0]]])
    A = np.eye(n, k=-1)
    A[0, :] = -den[1:]
    B = np.eye(n, 1)
    C = (num[1:] - num[0] * den[1:])[None, :]
    return A / tau, B / tau, C, D


def _dw_delay_system(p):
    """Pade states x_p driven by alpha, alpha_d = C_p x_p + D_p alpha ~ alpha(t - tau), and
    eps += g eps_ss (1 - G)(alpha_d - alpha).

    The downwash perturbation enters the Wells-Keskar system exactly as the F-term's eps_F does
    (columns bF, dF, rF of :class:`fdml.models.realization._System`), so it is added along them.
    """

    def fn(sys):
        tau, k = p["tau_dw"], _dw_share(p)
        if tau <= 0.0 or k == 0.0:
            return sys
        Ap, Bp, Cp, Dp = pade_delay(tau)
        n, m = sys.A.shape[0], Ap.shape[0]
        s2 = _pad_states(sys, m)
        r = np.zeros(n + m)
        r[0], r[n:] = k * (Dp[0, 0] - 1.0), k * Cp[0]  # d eps = k (alpha_d - alpha); x_0 = alpha
        A = s2.A + np.outer(s2.bF, r)
        A[n:, 0], A[n:, n:] = Bp[:, 0], Ap
        C = s2.C + np.outer(sys.dF, r)
        return replace(s2, A=A, C=C, rx=s2.rx + sys.rF * r)

    return fn


def _dw_delay_realize(opts, p, root):
    return {**opts, "system": opts.get("system", ()) + (_dw_delay_system(p),)}


def dw_delay_grid(lo: float, hi: float, n: int = 10) -> np.ndarray:
    """Delays, s, log-spaced from 0.5/hi to 1/lo (``lo``, ``hi`` rad/s: the searched band).

    A delay much shorter than the band's shortest period is an alpha-dot moment (aliased with the
    derivatives); one longer than 1/lo is outside what the band resolves.
    """
    return np.geomspace(0.5 / max(hi, 1e-3), 1.0 / max(lo, 1e-3), n)


_DW_PARAMS = (
    _amplitude("g_dw", 0.0, 1.2, "share of the downwash that arrives late at the tail (1: all of it)", upper=2.0),
    Param(
        "tau_dw",
        0.1,
        lower=1e-3,
        upper=1.0,
        plausible=(0.01, 0.5),
        unit="s",
        nuisance=True,
        description="downwash delay at the tail, about l_t/U",
    ),
)
DOWNWASH_DELAY = Dispatch(
    "downwash_lag",
    "tail",
    {
        kind: MatrixEffect(
            "downwash_lag",
            "tail",
            _DW_PARAMS,
            _dw_delay_matrix,
            realize=_dw_delay_realize,
            nuisance_grid={"tau_dw": dw_delay_grid},
        )
        for kind in ("steady", "unsteady")
    },
    signature="the downwash reaches the tail about l_t/U late: q (and alpha), like an alpha-dot moment",
)


# --- gust lag ---------------------------------------------------------------------------------


def _input_lag(column: int, name: str):
    """The response with input ``column`` (0 de, 1 alpha_w) through ``1/(1 + T s)``, T the parameter ``name``, s."""

    def factors(s, p, root):
        cols = np.ones((s.size, len(root.inputs)), complex)
        cols[:, column] = 1.0 / (1.0 + s * p[name])
        return None, cols, None

    return factors


def _filter_realize(signal_name: str, name: str):
    return lambda sys, p, root: filter_input(sys, signal_name, p[name])


def _tail_realize(opts, p, root):
    """The Wells-Keskar realisation with the tail's gust channel delayed by tau_tail (BS-8)."""
    return {**opts, "tail_tau": p["tau_tail"]}


def _tail_delay_matrix(s, p, M, B, E, root):
    """Delay the tail's share of the gust forcing by tau_tail (BS-8)."""
    ac = root.aircraft
    l_t = p["l_t"]
    B = B.copy()
    tail_m = B[:, 1, 1]  # the moment comes from the tail only (Eq. 7)
    tail_z = tail_m * ac.k_z * ac.c_w / (ac.k_m * l_t)  # its z-force share: -kz (St/Sw) C_Lt_g
    f = np.exp(-s * p["tau_tail"]) - 1.0
    B[:, 1, 1] = B[:, 1, 1] + tail_m * f
    B[:, 0, 1] = B[:, 0, 1] + tail_z * f
    return M, B, E


def _tail_applies(root):
    if getattr(root, "tail_gust_delay", False) and root.gust:
        return "the base model already delays the gust at the tail"
    return _needs_gust(root)


_B1 = Param(
    "b1", None, 0.0, 40.0, plausible=(0.0, 20.0), unit="semichords", start=0.5, description="Kussner lag length (BS-12)"
)
_WK_GUST_B1 = FreeParameterEffect(
    "gust_lag",
    "alpha_w",
    _B1,
    ("unsteady", "steady"),
    convert=to_unsteady_equivalent,
    needs=("alpha_w",),
)
_GUST_T = OutputEffect(
    "gust_lag",
    "alpha_w",
    (_seconds("T_gust", upper=2.0, plausible=0.5, start=0.01),),
    factors=_input_lag(1, "T_gust"),
    needs=("alpha_w",),
    applies=_needs_gust,
    realize=_filter_realize("alpha_w", "T_gust"),
)
GUST_LAG = Dispatch(
    "gust_lag",
    "alpha_w",
    {"unsteady": _WK_GUST_B1, "steady": _WK_GUST_B1, "derivatives": _GUST_T, "dimensional": _GUST_T},
    needs=("alpha_w",),
    signature="gust lift builds up with a lag: alpha and a_z, coherent with alpha_w",
)

_TAIL = (_seconds("tau_tail", upper=1.0, plausible=0.3, start=0.01, description="gust delay at the tail (BS-8)"),)
_GUST_TAIL = MatrixEffect(
    "gust_lag", "tail", _TAIL, _tail_delay_matrix, needs=("alpha_w",), applies=_tail_applies, realize=_tail_realize
)
GUST_TAIL = Dispatch(
    "gust_lag",
    "tail",
    {"unsteady": _GUST_TAIL, "steady": _GUST_TAIL},
    needs=("alpha_w",),
    signature="the gust reaches the tail l_t/U later: q, coherent with alpha_w",
)


# --- time delay ------------------------------------------------------------------------------

TIME_DELAY_DE = FreeParameterEffect(
    "time_delay",
    "de",
    _seconds("tau_de", None, upper=0.5, plausible=0.15, start=0.002, description="elevator time delay"),
    ("unsteady", "steady", "derivatives", "dimensional"),
    signature="alpha, q and a_z respond tau after the recorded elevator (actuator or transport delay): phase "
    "lag growing with frequency on every output",
)


def _spoken(channels) -> str:
    """``alpha and a_z`` for the channels ``("alpha", "az")``."""
    names = [{"az": "a_z", "de": "the elevator"}.get(c, c) for c in channels]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


#: Sensor groups that can lag the others: every output alone and every pair of outputs (the three
#: together lag the elevator: time_delay@de).  A delay is never negative: a channel that leads the
#: others is the others lagging it (q leading alpha and a_z is time_delay@alpha,az).
TIMING_GROUPS = tuple((c,) for c in OUTPUTS) + tuple((a, b) for i, a in enumerate(OUTPUTS) for b in OUTPUTS[i + 1 :])


def _make_output_delay(channels: tuple) -> OutputEffect:
    rows = tuple(OUTPUTS.index(c) for c in channels)
    name = "tau_" + "_".join(channels)
    others = _spoken([c for c in ("de", *OUTPUTS) if c not in channels])

    def factors(s, p, root):
        f = np.ones((s.size, len(root.outputs)), complex)
        f[:, rows] = np.exp(-s * p[name])[:, None]
        return f, None, None

    def realize(sys, p, root):
        for row in rows:
            sys = delay_output(sys, row, p[name])
        return sys

    # plausible up to 0.25 s: air-data systems lag by up to 0.2 s and more (HFB-320's alpha)
    what = f"{_spoken(channels)} recorded this long after {others}"
    return OutputEffect(
        "time_delay",
        ",".join(channels),
        (_seconds(name, upper=0.5, plausible=0.25, start=0.002, description=what),),
        factors=factors,
        signature=f"{_spoken(channels)} recorded tau after {others}: phase lag growing with frequency on "
        + ("it" if len(channels) == 1 else "them"),
        realize=realize,
    )


# --- actuator lag ----------------------------------------------------------------------------


ACTUATOR_LAG = OutputEffect(
    "actuator_lag",
    "de",
    (
        _seconds(
            "T_act",
            upper=1.0,
            plausible=0.15,
            start=0.002,
            description="first-order lag, recorded to effective elevator",
        ),
    ),
    factors=_input_lag(0, "T_act"),
    signature="phase lag and roll-off above 1/T on every output",
    realize=_filter_realize("de", "T_act"),
)


# --- sensor position ---------------------------------------------------------------------------


class StationEffect(MatrixEffect):
    """A sensor's station, m ahead of the c.g.: a term of its output's row (:data:`fdml.channels.OUTPUT_TABLE`).

    The model reads the parameter where it forms its output rows, in the frequency response and in
    the realisation alike, so nothing acts here on the matrices or on a response, and the order of
    the effects does not matter (the sensor sees the true motion).  Evaluated through the model as
    a matrix-level effect is, never applied to a response by itself.

    Parameters
    ----------
    channel : str
        The output (a key of :data:`fdml.channels.STATIONS`).
    param : Param
        Its station, m.
    signature : str
        One line on where the effect shows, for reports.
    """

    acts_on_matrices = False

    def __init__(self, channel: str, param: Param, signature: str):
        super().__init__("sensor_offset", channel, (param,), _unchanged, signature=signature, realize=_as_is)


def _unchanged(s, p, M, B, E, root):
    return M, B, E


def _as_is(target, p, root):
    return target  # the realisation's rows read the station (fdml.models.realization._with_outputs)


def _lever_arm(name: str, sensor: str, plausible: float, why: str) -> Param:
    """A sensor's distance ahead of the c.g., m (null 0; plausible within ``plausible`` m of it)."""
    return Param(
        name,
        0.0,
        lower=-50.0,
        upper=50.0,
        plausible=(-plausible, plausible),
        unit="m",
        start=0.05,
        description=f"{sensor} ahead of the c.g. ({why})",
    )


SENSOR_OFFSET_AZ = StationEffect(
    "az",
    _lever_arm(STATIONS["az"], "accelerometer", 8.0, "an accelerometer package sits within a few metres of the c.g."),
    "a_z picks up -x q_dot/g: phase lead and rising magnitude on a_z",
)
SENSOR_OFFSET_ALPHA = StationEffect(
    "alpha",
    _lever_arm(STATIONS["alpha"], "alpha vane", 25.0, "a nose-boom vane can sit 20 m ahead on a transport aircraft"),
    "alpha picks up -x q/U: phase change on alpha",
)


# --- structural mode -------------------------------------------------------------------------


def _mode(s, p, root):
    w, z = p["omega_s"], p["zeta_s"]
    D = s**2 + 2.0 * z * w * s + w**2
    added = np.zeros((s.size, len(root.outputs), len(root.inputs)), complex)
    added[:, 1, 0] = p["r_q"] * s * w / D  # modal rate: s eta, eta = w^2/D de (unit static gain)
    added[:, 2, 0] = p["r_az"] * s**2 / D  # modal acceleration: s^2 eta / w^2
    return None, None, added


def _mode_realize(sys, p, root):
    return add_mode(sys, p["r_q"], p["r_az"], p["omega_s"], p["zeta_s"])


def mode_grid(lo: float, hi: float, zeta: float = MODE_ZETA) -> np.ndarray:
    """Log-spaced mode frequencies over [lo, hi], one half-power bandwidth apart (ratio 1 + zeta)."""
    lo, hi = max(lo, 1e-3), max(hi, 2e-3)
    n = max(int(math.ceil(math.log(hi / lo) / math.log(1.0 + zeta))) + 1, 2)
    return np.geomspace(lo, hi, n)


STRUCTURAL_MODE = OutputEffect(
    "structural_mode",
    "q,az",
    (
        *(
            Param(
                f"r_{ch}",
                0.0,
                plausible=(-0.5, 0.5),
                unit=unit,
                start=0.01,
                description=f"mode residue on {on} (peak r/(2 zeta))",
            )
            for ch, on, unit in (("q", "q", "rad/s per rad"), ("az", "a_z", "g per rad"))
        ),
        Param("omega_s", 10.0, lower=0.1, upper=1e3, unit="rad/s", nuisance=True, description="mode frequency"),
        Param(
            "zeta_s",
            MODE_ZETA,
            lower=0.005,
            upper=0.5,
            plausible=(0.01, 0.15),
            unit="-",
            nuisance=True,
            description="mode damping (refined within its plausible range: lightly damped)",
        ),
    ),
    factors=_mode,
    nuisance_grid={"omega_s": mode_grid},
    signature="a narrow resonance on q and a_z, coherent with the elevator",
    realize=_mode_realize,
)


# --- sensor scale ----------------------------------------------------------------------------


def _make_scale(ch: str) -> OutputEffect:
    name, row = f"k_{ch}", OUTPUTS.index(ch)

    def factors(s, p, root):
        f = np.ones((s.size, len(root.outputs)))
        f[:, row] = 1.0 + p[name]
        return f, None, None

    def realize(sys, p, root):
        return scale_output(sys, row, 1.0 + p[name])

    param = Param(
        name,
        0.0,
        lower=-0.9,
        upper=2.0,
        plausible=(-0.2, 0.2),
        unit="-",
        start=0.005,
        description=f"gain error of {ch}",
    )
    return OutputEffect(
        "sensor_scale",
        ch,
        (param,),
        factors=factors,
        signature=f"{ch} too large or small at every frequency",
        realize=realize,
    )


# --- unmeasured gust (noise kind) ---------------------------------------------------------------


class UnmeasuredGust(Effect):
    """Turbulence that was not measured: extra residual covariance along the gust column.

    Tested by :mod:`fdml.diagnose.disturbance` on the part of the residual that
    is incoherent with the inputs, after the deterministic effects.
    """

    name = "unmeasured_gust"
    channel = "alpha,q,az"
    kind = "noise"
    params = (
        Param(
            "sigma_w",
            0.0,
            lower=0.0,
            upper=50.0,
            plausible=(0.0, 5.0),
            unit="m/s",
            description="RMS vertical gust velocity (Dryden)",
        ),
    )
    signature = "residuals incoherent with the inputs but correlated across channels like the gust column"

    def augment(self, model):  # the test does not refit the model
        return model


#: The built-in effects, in the order the library lists them.
BUILTINS = (
    LIFT_LAG,
    DOWNWASH_LAG,
    DOWNWASH_DELAY,
    GUST_LAG,
    GUST_TAIL,
    TIME_DELAY_DE,
    *(_make_output_delay(g) for g in TIMING_GROUPS),
    ACTUATOR_LAG,
    SENSOR_OFFSET_AZ,
    SENSOR_OFFSET_ALPHA,
    STRUCTURAL_MODE,
    *(_make_scale(c) for c in OUTPUTS),
    UnmeasuredGust(),
)
