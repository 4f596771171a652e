"""Wells-Keskar models: ``unsteady`` (Eqs. 13-17) and its quasi-steady limit ``steady``.

Parameter vector theta (Eq. 18): CLa_w, CLa_t, deps_da, Cm_de, Cz_de.  The lag
constants y_w, z_w, y_t, z_t, F, G, H, the tail length l_t and the Kussner
length b1 are fixed by default and may be freed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..aero import IndicialFunction, downwash, get_indicial, kussner, lift_lag
from ..aircraft import Aircraft, missing_lag_message
from ..errors import AircraftError, ParameterError
from ..parameters import Parameter, Parameters
from .base import AircraftModel, Model

__all__ = ["UnsteadyModel", "SteadyModel", "alternate_set", "ALTERNATE_NAMES"]

#: The six derivatives of WK Tables 1 and 3, in the tables' order: the keys of :func:`alternate_set`.
ALTERNATE_NAMES = ("Cz_a", "Cz_q", "Cz_de", "Cm_a", "Cm_q", "Cm_de")

_THETA = (
    ("CLa_w", "1/rad", "steady wing lift slope (C_La)_ss,w"),
    ("CLa_t", "1/rad", "steady tail lift slope (C_La)_ss,t"),
    ("deps_da", "-", "steady downwash gradient (d eps/d alpha)_ss"),
    ("Cm_de", "1/rad", "pitching moment per elevator"),
    ("Cz_de", "1/rad", "z force per elevator"),
)


#: The lag constants of Eqs. 1-2 and 17 (fixed by default): name, bounds and description.
_LAG_CONSTANTS = (
    ("y_w", 0.0, 1.0, "wing lift-lag amplitude"),
    ("z_w", 0.0, math.inf, "wing lift-lag rate per semichord"),
    ("y_t", 0.0, 1.0, "tail lift-lag amplitude"),
    ("z_t", 0.0, math.inf, "tail lift-lag rate per semichord"),
    ("F", -math.inf, math.inf, "downwash starting-vortex strength (Eq. 2)"),
    ("G", -math.inf, math.inf, "downwash lag amplitude (Eq. 2)"),
    ("H", 0.0, math.inf, "downwash lag rate (Eq. 2)"),
)


def alternate_set(p: Mapping[str, float], ac: Aircraft) -> dict[str, float]:
    """Quasi-steady derivatives implied by theta, docs/theory.md section 6.

    q-derivatives per ``q c_w / (2U)``.

    Parameters
    ----------
    p : mapping of str to float
        The model's parameter values by name (``CLa_w``, ``CLa_t``, ``deps_da``, ``l_t`` m, ``Cz_de``, ``Cm_de``).
    ac : Aircraft
        The aircraft (wing chord c_w, m; areas S_w, S_t, m^2).

    Returns
    -------
    dict
        Cz_a, Cz_q, Cz_de, Cm_a, Cm_q, Cm_de (1/rad).
    """
    lc = p["l_t"] / ac.c_w
    sr = ac.S_t / ac.S_w
    at, eps = p["CLa_t"], p["deps_da"]
    return {
        "Cz_a": -(p["CLa_w"] + sr * at * (1.0 - eps)),
        "Cz_q": -2.0 * lc * sr * at,
        "Cz_de": p["Cz_de"],
        "Cm_a": -lc * sr * at * (1.0 - eps),
        "Cm_q": -2.0 * lc**2 * sr * at,
        "Cm_de": p["Cm_de"],
    }


#: The constants of theta each quasi-steady derivative of :func:`alternate_set` is built from.
ALTERNATE_INPUTS = {
    "Cz_a": ("CLa_w", "CLa_t", "deps_da"),
    "Cz_q": ("CLa_t",),
    "Cz_de": ("Cz_de",),
    "Cm_a": ("CLa_t", "deps_da"),
    "Cm_q": ("CLa_t",),
    "Cm_de": ("Cm_de",),
}


def placeholder_sources(params: Parameters, ac: Aircraft, inputs: Mapping[str, tuple]) -> dict:
    """(start value, why) of each parameter in ``inputs`` built from a placeholder constant of ``ac``.

    Parameters
    ----------
    params : Parameters
        The model's default parameters (their values are the start values).
    ac : Aircraft
        The aircraft whose :attr:`~fdml.aircraft.Aircraft.placeholders` count.
    inputs : mapping of str to tuple of str
        Parameter -> the aircraft constants it is computed from.

    Returns
    -------
    dict
        Parameter name -> (start value, a note naming the placeholder constants).
    """
    ph = ac.placeholders
    out = {}
    for name, consts in inputs.items():
        bad = [c for c in consts if c in ph]
        if bad and name in params:
            out[name] = (params[name].value, ("" if consts == (name,) else "from ") + ", ".join(ph[c] for c in bad))
    return out


@dataclass(frozen=True, kw_only=True)
class _WKBase(AircraftModel):
    closed_form_parameters = Model.closed_form_parameters | {"CLa_w", "CLa_t", "deps_da", "Cm_de", "Cz_de"}

    def _placeholder_sources(self) -> dict[str, tuple[float, str]]:
        start = self._default_parameters()
        return placeholder_sources(start, self.aircraft, {n: (n,) for n in start.names})

    def _theta_parameters(self) -> list[Parameter]:
        c = self.aircraft.constants
        return [Parameter(n, c[n], free=True, unit=u, description=d) for n, u, d in _THETA]

    def _tail_length_parameter(self) -> Parameter:
        return Parameter(
            "l_t", self.aircraft.l_t, free=False, lower=0.0, unit="m", description="tail length, c.g. to tail a.c."
        )

    def _force_moment(self, s, p, N_w, N_t, E, Kg):
        """Assemble M, B of Eqs. 13-14 from the lift and downwash transfer functions.

        ``Kg`` is ``(K_wing, K_tail)``: the gust transfer to wing and tail lift
        (Kussner lag and tail delay), or None without a gust input.
        """
        ac = self.aircraft
        kz, km = ac.k_z, ac.k_m
        sr = ac.S_t / ac.S_w
        l = p["l_t"]
        U = ac.U
        CLt = N_t * (1.0 - E)  # Eq. 16: C_Lt per alpha = N_t (1 - E)
        n = s.size
        M = np.empty((n, 2, 2), dtype=complex)
        # Eq. 13: s alpha = q - kz{[N_w + (St/Sw) C_Lt] alpha + (l St/(Sw U)) N_t q - Cz_de de}
        M[:, 0, 0] = s + kz * (N_w + sr * CLt)
        M[:, 0, 1] = -1.0 + kz * (l * sr / U) * N_t
        # Eq. 14: s q = km{-(l St/(c Sw)) C_Lt alpha - (l^2 St/(c Sw U)) N_t q + Cm_de de}
        M[:, 1, 0] = km * (l * sr / ac.c_w) * CLt
        M[:, 1, 1] = s + km * (l**2 * sr / (ac.c_w * U)) * N_t
        n_in = 2 if self.gust else 1
        B = np.empty((n, 2, n_in), dtype=complex)
        B[:, 0, 0] = kz * p["Cz_de"]
        B[:, 1, 0] = km * p["Cm_de"]
        if self.gust:
            # docs/theory.md section 8: C_Lw += a_w K alpha_g; eps += eps_ss K D alpha_g;
            # C_Lt += N_t(-eps_ss K D alpha_g) + a_t K D alpha_g, D = exp(-s l/U).
            K_w, K_tD = Kg
            CLt_g = (p["CLa_t"] - N_t * p["deps_da"]) * K_tD
            B[:, 0, 1] = -kz * (p["CLa_w"] * K_w + sr * CLt_g)
            B[:, 1, 1] = -km * (l * sr / ac.c_w) * CLt_g
        return M, B, np.eye(2)

    def _matrices(self, s, p):
        n_w, n_t, e, Kg = self._parts(s, p)
        return self._force_moment(s, p, p["CLa_w"] * n_w, p["CLa_t"] * n_t, p["deps_da"] * e, Kg)

    def _matrix_derivatives(self, s, p, names):
        """Closed forms for theta (Eqs. 13-16 are linear in a_w, a_t, eps_ss, Cm_de, Cz_de
        given the unit-slope transfer functions); central differences for the constants."""
        theta = {"CLa_w", "CLa_t", "deps_da", "Cm_de", "Cz_de"}
        out = super()._matrix_derivatives(s, p, [nm for nm in names if nm not in theta])
        if not theta & set(names):
            return out
        ac = self.aircraft
        kz, km, sr, l, U, c = ac.k_z, ac.k_m, ac.S_t / ac.S_w, p["l_t"], ac.U, ac.c_w
        n_w, n_t, e, Kg = self._parts(s, p)
        a_t, eps = p["CLa_t"], p["deps_da"]
        K_w, K_t = Kg if self.gust else (0.0, 0.0)
        # d/d name of (N_w, N_t in the q terms, C_Lt = a_t n_t (1 - eps e), the tail's gust lift, the wing's)
        partial = {
            "CLa_w": (n_w, 0.0, 0.0, 0.0, K_w),
            "CLa_t": (0.0, n_t, n_t * (1.0 - eps * e), (1.0 - n_t * eps) * K_t, 0.0),
            "deps_da": (0.0, 0.0, -a_t * n_t * e, -a_t * n_t * K_t, 0.0),
        }
        n, n_in = s.size, (2 if self.gust else 1)
        for nm in theta & set(names):
            dM = np.zeros((n, 2, 2), complex)
            dB = np.zeros((n, 2, n_in), complex)
            if nm == "Cz_de":
                dB[:, 0, 0] = kz
            elif nm == "Cm_de":
                dB[:, 1, 0] = km
            else:
                dNw, dNt, dCLt, dCLtg, dKw = partial[nm]
                dM[:, 0, 0] = kz * dNw + kz * sr * dCLt
                dM[:, 0, 1] = kz * (l * sr / U) * dNt
                dM[:, 1, 0] = km * (l * sr / c) * dCLt
                dM[:, 1, 1] = km * (l**2 * sr / (c * U)) * dNt
                if self.gust:
                    dB[:, 0, 1] = -kz * (dKw + sr * dCLtg)
                    dB[:, 1, 1] = -km * (l * sr / c) * dCLtg
            out[nm] = (dM, dB, None)
        return out

    def derived(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        """The alternate set (docs/theory.md section 6) at ``values``."""
        return alternate_set(self.values(values), self.aircraft)


@dataclass(frozen=True, kw_only=True)
class UnsteadyModel(_WKBase):
    """Wells-Keskar unsteady model, docs/theory.md Eqs. 13-17 (and section 8 for the gust).

    Parameters
    ----------
    gust : bool, optional
        Add the vertical-gust input alpha_w with the Kussner lag (BS-12) and
        the tail delay l_t/U.
    output_bias : bool, optional
        Free the output biases.
    parameters : Parameters, optional
        Overrides the default parameter set.
    outputs : sequence of str, optional
        Outputs beyond alpha, q and a_z to predict (``theta``, ``qdot``; :meth:`Model.with_outputs`).
    aircraft : Aircraft
        Geometry, mass, flight condition and default constants.
    tail_lag_chord : {"c_w", "c_t"}, optional
        Chord in the tail lift-lag rate 2 z_t U / c of Eq. 17; the paper prints
        c_w (docs/theory.md section 2, open question), which is the default.
    gust_lag : str, optional
        ``"bs12"`` (first-order Kussner lag with free-able length b1, the
        default) or the name of an :data:`fdml.aero.INDICIAL_PRESETS` entry
        used as a fixed gust indicial function.
    tail_gust_delay : bool, optional
        Delay the gust at the tail (and the wing downwash it causes) by l_t/U
        (BS-8), default True.
    """

    kind = "unsteady"
    tail_lag_chord: str = "c_w"
    gust_lag: str = "bs12"
    tail_gust_delay: bool = True

    def __post_init__(self) -> None:
        if self.tail_lag_chord not in ("c_w", "c_t"):
            raise ParameterError(f"tail_lag_chord must be 'c_w' or 'c_t', got {self.tail_lag_chord!r}")
        if self.gust_lag != "bs12":
            get_indicial(self.gust_lag)  # raises on an unknown name
        if isinstance(self.aircraft, Aircraft) and self.aircraft.lag_status is None:
            # no lag constants and no source named: the generic "no lag" would make this the steady model
            raise AircraftError(missing_lag_message(self.aircraft, self.kind))
        super().__post_init__()

    def _default_parameters(self) -> Parameters:
        c = self.aircraft.constants
        fixed = [
            Parameter(n, c[n], free=False, lower=lo, upper=hi, unit="-", description=what)
            for n, lo, hi, what in _LAG_CONSTANTS
        ] + [self._tail_length_parameter()]
        if self.gust and self.gust_lag == "bs12":
            what = "Kussner lag length, T* = c b1/(2U) (BS-12)"
            fixed.append(Parameter("b1", c["b1"], free=False, lower=0.0, unit="semichords", description=what))
        return Parameters(tuple(self._theta_parameters() + fixed))

    def _gust_lag(self, s, p) -> np.ndarray:
        ac = self.aircraft
        if self.gust_lag == "bs12":
            return kussner(s, p["b1"], ac.U, ac.c_w)
        fn: IndicialFunction = get_indicial(self.gust_lag)
        return fn.transfer(s, ac.U, ac.c_w)

    def _parts(self, s, p):
        """Unit-slope transfer functions (n_w, n_t, e, Kg): N = a n, E = eps_ss e."""
        ac = self.aircraft
        c_tail = ac.c_w if self.tail_lag_chord == "c_w" else ac.c_t
        n_w = lift_lag(s, 1.0, p["y_w"], p["z_w"], ac.U, ac.c_w)  # Eq. 17, wing
        n_t = lift_lag(s, 1.0, p["y_t"], p["z_t"], ac.U, c_tail)  # Eq. 17, tail
        e = downwash(s, 1.0, p["F"], p["G"], p["H"], p["l_t"], ac.U, ac.c_w)  # Eq. 16
        Kg = None
        if self.gust:
            K = self._gust_lag(s, p)
            D = np.exp(-s * p["l_t"] / ac.U) if self.tail_gust_delay else 1.0  # BS-8
            Kg = (K, K * D)
        return n_w, n_t, e, Kg

    def derived(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        """Alternate set plus the G-part alpha-dot derivatives (docs/theory.md section 6).

        ``Cm_adot_G = -(l/c)(St/Sw) a_t eps_ss G/H`` and
        ``Cz_adot_G = -(St/Sw) a_t eps_ss G/H`` (per ``alpha_dot c/(2U)``); the
        F part behaves like ``s ln s`` and has no derivative.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        dict of str to float
            Cz_a, Cz_q, Cz_de, Cm_a, Cm_q, Cm_de (1/rad) and Cz_adot_G, Cm_adot_G (1/rad).
        """
        p = self.values(values)
        out = alternate_set(p, self.aircraft)
        ac = self.aircraft
        sr = ac.S_t / ac.S_w
        gh = p["G"] / p["H"] if p["H"] != 0 else 0.0
        out["Cz_adot_G"] = -sr * p["CLa_t"] * p["deps_da"] * gh
        out["Cm_adot_G"] = -(p["l_t"] / ac.c_w) * sr * p["CLa_t"] * p["deps_da"] * gh
        return out


@dataclass(frozen=True, kw_only=True)
class SteadyModel(_WKBase):
    """Quasi-steady Wells-Keskar model: Eqs. 13-14 with N = a, E = deps_da, K = 1.

    This is the omega -> 0 limit of :class:`UnsteadyModel`: no lift lag, no
    downwash lag, no Kussner lag and no tail gust delay.

    Parameters
    ----------
    gust : bool, optional
        Add the vertical-gust input alpha_w (no Kussner lag, no tail delay).
    output_bias : bool, optional
        Free the output biases.
    parameters : Parameters, optional
        Overrides the default parameter set.
    outputs : sequence of str, optional
        Outputs beyond alpha, q and a_z to predict (``theta``, ``qdot``; :meth:`Model.with_outputs`).
    aircraft : Aircraft
        Geometry, mass, flight condition and default constants.
    """

    kind = "steady"

    def _default_parameters(self) -> Parameters:
        return Parameters(tuple(self._theta_parameters() + [self._tail_length_parameter()]))

    def _parts(self, s, p):
        """Quasi-steady limit: n_w = n_t = e = 1, K = 1, no tail delay."""
        one = np.ones_like(s)
        return one, one, one, ((one, one) if self.gust else None)
