"""Conventional short-period models: ``derivatives`` and ``dimensional``.

``derivatives`` is the six-derivative non-dimensional model that docs/theory.md
section 6 identifies as Wells-Keskar's "steady" column (q per q c/(2U)), with
optional alpha-dot derivatives.  ``dimensional`` is the form SIDPAC and
Jategaonkar fit to records without geometry:

    alpha_dot = Z_a alpha + (1 + Z_q) q + Z_de de
    q_dot     = M_a alpha + M_q q + M_de de
    a_z       = (U/g)(alpha_dot - q)                  (docs/theory.md Eq. 5)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..aircraft import MAX_AIRSPEED, Aircraft
from ..errors import ParameterError
from ..parameters import Parameter, Parameters
from .base import AircraftModel, Descriptor, DescriptorModel, Model
from .wells_keskar import ALTERNATE_INPUTS, ALTERNATE_NAMES, alternate_set, placeholder_sources

__all__ = ["DerivativesModel", "DimensionalModel", "to_dimensional"]

#: Generic dimensional start values for a record without geometry: a stable
#: short period near 3 rad/s; a fit moves them (they are not data).
_GENERIC_DIMENSIONAL = {"Z_a": -1.0, "Z_q": 0.0, "Z_de": -0.1, "M_a": -8.0, "M_q": -2.0, "M_de": -10.0}
#: Units of the dimensional derivatives: the ``dimensional`` model's parameters, the others' derived quantities.
DIMENSIONAL_UNITS = {"Z_a": "1/s", "Z_q": "-", "Z_de": "1/s", "M_a": "1/s^2", "M_q": "1/s", "M_de": "1/s^2"}


def _scales(ac: Aircraft) -> dict[str, tuple]:
    """Per dimensional derivative: its non-dimensional one, k_z or k_m and c/(2U) (1 for a non-q derivative)."""
    kz, km, cu = ac.k_z, ac.k_m, ac.c_w / (2.0 * ac.U)
    return {
        "Z_a": ("Cz_a", kz, 1.0),
        "Z_q": ("Cz_q", kz, cu),
        "Z_de": ("Cz_de", kz, 1.0),
        "M_a": ("Cm_a", km, 1.0),
        "M_q": ("Cm_q", km, cu),
        "M_de": ("Cm_de", km, 1.0),
    }


def to_dimensional(d: Mapping[str, float], ac: Aircraft) -> dict[str, float]:
    """Dimensional derivatives from non-dimensional ones (per q c/(2U)).

    Parameters
    ----------
    d : mapping of str to float
        Cz_a, Cz_q, Cz_de, Cm_a, Cm_q, Cm_de (1/rad; q-derivatives per q c/(2U)).
    ac : Aircraft
        The aircraft (k_z, k_m, chord c_w m, airspeed U m/s).

    Returns
    -------
    dict of str to float
        Z_a (1/s), Z_q (-), Z_de (1/s), M_a (1/s^2), M_q (1/s), M_de (1/s^2).
    """
    return {name: k * d[nd] * cu for name, (nd, k, cu) in _scales(ac).items()}


@dataclass(frozen=True, kw_only=True)
class DerivativesModel(AircraftModel, DescriptorModel):
    """Six non-dimensional derivatives, optionally with Cz_adot and Cm_adot.

    Equations (docs/theory.md section 6, "steady" model), with k_z = rho U S/(2m),
    k_m = rho U^2 S c/(2 Iy) and hat q = q c/(2U)::

        alpha_dot = q + k_z [Cz_a alpha + Cz_q hat q + Cz_de de + Cz_adot hat alpha_dot]
        q_dot     = k_m [Cm_a alpha + Cm_q hat q + Cm_de de + Cm_adot hat alpha_dot]

    A gust alpha_w enters quasi-steadily as aerodynamic angle of attack
    (alpha + alpha_w, and its rate in the alpha-dot terms).

    Parameters
    ----------
    gust, output_bias : bool, optional
        Add the vertical-gust input alpha_w; free the output biases.
    parameters : Parameters, optional
        Overrides the default parameter set.
    outputs : sequence of str, optional
        Outputs beyond alpha, q and a_z to predict (``theta``, ``qdot``; :meth:`Model.with_outputs`).
    aircraft : Aircraft
        Geometry, mass and flight condition (k_z, k_m, chord, airspeed).
    adot : bool, optional
        Free Cz_adot and Cm_adot (present and fixed at zero otherwise).
    """

    kind = "derivatives"
    closed_form_parameters = Model.closed_form_parameters | set(ALTERNATE_NAMES) | {"Cz_adot", "Cm_adot"}
    adot: bool = False

    def _placeholder_sources(self) -> dict[str, tuple[float, str]]:
        return placeholder_sources(self._default_parameters(), self.aircraft, ALTERNATE_INPUTS)

    def _default_parameters(self) -> Parameters:
        c = self.aircraft.constants
        start = alternate_set({**c, "l_t": self.aircraft.l_t}, self.aircraft)
        items = [
            Parameter("Cz_a", start["Cz_a"], unit="1/rad", description="z force per alpha"),
            Parameter("Cz_q", start["Cz_q"], unit="1/rad", description="z force per q c/(2U)"),
            Parameter("Cz_de", start["Cz_de"], unit="1/rad", description="z force per elevator"),
            Parameter("Cm_a", start["Cm_a"], unit="1/rad", description="pitching moment per alpha"),
            Parameter("Cm_q", start["Cm_q"], unit="1/rad", description="pitching moment per q c/(2U)"),
            Parameter("Cm_de", start["Cm_de"], unit="1/rad", description="pitching moment per elevator"),
            Parameter("Cz_adot", 0.0, free=self.adot, unit="1/rad", description="z force per alpha_dot c/(2U)"),
            Parameter("Cm_adot", 0.0, free=self.adot, unit="1/rad", description="moment per alpha_dot c/(2U)"),
        ]
        return Parameters(tuple(items))

    def _descriptor(self, p) -> Descriptor:
        """E, A, B0, B1 of the equations above; the gust enters as aerodynamic angle of attack, and its rate
        in the alpha-dot terms."""
        ac = self.aircraft
        kz, km, cu = ac.k_z, ac.k_m, ac.c_w / (2.0 * ac.U)
        E = np.array([[1.0 - kz * p["Cz_adot"] * cu, 0.0], [-km * p["Cm_adot"] * cu, 1.0]])
        A = np.array([[kz * p["Cz_a"], 1.0 + kz * p["Cz_q"] * cu], [km * p["Cm_a"], km * p["Cm_q"] * cu]])
        B0 = np.array([[kz * p["Cz_de"], kz * p["Cz_a"]], [km * p["Cm_de"], km * p["Cm_a"]]])
        B1 = np.array([[0.0, kz * p["Cz_adot"] * cu], [0.0, km * p["Cm_adot"] * cu]])
        n_in = len(self.inputs)
        return Descriptor(E, A, B0[:, :n_in], B1[:, :n_in], self._channels(p))

    def derived(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        """Dimensional equivalents Z_a, Z_q, Z_de, M_a, M_q, M_de.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        dict of str to float
            Z_a (1/s), Z_q (-), Z_de (1/s), M_a (1/s^2), M_q (1/s), M_de (1/s^2).
        """
        return to_dimensional(self.values(values), self.aircraft)


@dataclass(frozen=True, kw_only=True)
class DimensionalModel(DescriptorModel):
    """Dimensional short-period model (SIDPAC / Jategaonkar form).

    Parameters
    ----------
    gust, output_bias : bool, optional
        Add the vertical-gust input alpha_w; free the output biases.
    parameters : Parameters, optional
        Overrides the default parameter set.
    outputs : sequence of str, optional
        Outputs beyond alpha, q and a_z to predict (``theta``, ``qdot``; :meth:`Model.with_outputs`).
    airspeed : float, optional
        Airspeed U, m/s (needed for a_z, Eq. 5); without it, the
        ``aircraft``'s U.
    aircraft : Aircraft, optional
        When given, supplies U, start values from its constants and the
        non-dimensional derived set.
    """

    kind = "dimensional"
    closed_form_parameters = Model.closed_form_parameters | set(_GENERIC_DIMENSIONAL)
    airspeed: float | None = None
    aircraft: Aircraft | None = None

    def __post_init__(self) -> None:
        if self.aircraft is None and self.airspeed is None:
            raise ParameterError("the dimensional model needs the airspeed U (m/s) or an aircraft")
        if self.airspeed is not None and not (np.isfinite(self.airspeed) and 0 < self.airspeed <= MAX_AIRSPEED):
            raise ParameterError(
                f"airspeed must be positive and at most {MAX_AIRSPEED:g} m/s "
                f"(fdml.aircraft.MAX_AIRSPEED), got {self.airspeed!r}"
            )
        super().__post_init__()

    @property
    def U(self) -> float:
        if self.airspeed is not None:
            return float(self.airspeed)
        assert self.aircraft is not None  # __post_init__ requires the airspeed or an aircraft
        return self.aircraft.U

    def _placeholder_sources(self) -> dict[str, tuple[float, str]]:
        start = self._default_parameters()
        if self.aircraft is None:
            return {n: (start[n].value, "generic start value (no aircraft)") for n in _GENERIC_DIMENSIONAL}
        dimensional = {d: ALTERNATE_INPUTS[nd] for d, (nd, _, _) in _scales(self.aircraft).items()}
        return placeholder_sources(start, self.aircraft, dimensional)

    def _default_parameters(self) -> Parameters:
        if self.aircraft is not None:
            c = self.aircraft.constants
            start = to_dimensional(alternate_set({**c, "l_t": self.aircraft.l_t}, self.aircraft), self.aircraft)
        else:
            start = dict(_GENERIC_DIMENSIONAL)
        return Parameters(tuple(Parameter(k, start[k], unit=DIMENSIONAL_UNITS[k]) for k in _GENERIC_DIMENSIONAL))

    def _descriptor(self, p) -> Descriptor:
        """E = I, A, B0 of the equations above (B1 = 0); the gust enters like alpha."""
        A = np.array([[p["Z_a"], 1.0 + p["Z_q"]], [p["M_a"], p["M_q"]]])
        B0 = np.array([[p["Z_de"], p["Z_a"]], [p["M_de"], p["M_a"]]])[:, : len(self.inputs)]
        return Descriptor(np.eye(2), A, B0, np.zeros_like(B0), self._channels(p))

    def derived(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        """Non-dimensional derivatives when an aircraft is attached, else empty.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values by name overriding the model's own.

        Returns
        -------
        dict of str to float
            Cz_a, Cz_q, Cz_de, Cm_a, Cm_q, Cm_de (1/rad), or empty.
        """
        if self.aircraft is None:
            return {}
        p = self.values(values)
        return {nd: p[name] / (k * cu) for name, (nd, k, cu) in _scales(self.aircraft).items()}
