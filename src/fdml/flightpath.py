r"""Data-compatibility check (flight-path reconstruction) of a longitudinal record.

Before identification, flight-test practice checks that the measured angles,
rates and accelerations obey the kinematics that link them, and estimates the
sensor errors that make them disagree (the Braunschweig paper's first key
point: "the influence of sensor dynamics is eliminated by data compatibility
check and off-line correction before identification").  The kinematics hold
whatever the aerodynamics, so this check needs no aircraft model.

Kinematic equations (longitudinal plane, wings level, flat non-rotating
earth; body axes x forward, z down; fdml's signs: alpha, theta, q positive
nose up, specific forces a_x, a_z in g with a_z positive **down**, so that
a_z = -1 g in level flight).  With body inertial velocities u = V cos(alpha),
w = V sin(alpha) and u_dot = g a_x - g sin(theta) - q w,
w_dot = g a_z + g cos(theta) + q u::

    alpha_dot = q + (g / V) [a_z cos(alpha) - a_x sin(alpha) + cos(theta - alpha)]
    theta_dot = q
    V_dot     = g [a_x cos(alpha) + a_z sin(alpha) - sin(theta - alpha)]
    h_dot     = V sin(theta - alpha)

In trim (theta = alpha, a_z cos(alpha) - a_x sin(alpha) = -1) alpha_dot = 0;
linearised about level flight the first equation is docs/theory.md Eq. 5,
Delta a_z = (U/g)(alpha_dot - q).  Without wind V and alpha are both air-
and inertia-relative; wind makes the check fail (see :mod:`fdml.wind`).

Sensor models (measured from true; the correction inverts them)::

    q_m(t)     = K_q q(t) + b_q
    a_z,m(t)   = K_az a_z(t - tau_az) + b_az
    a_x,m(t)   = a_x(t) + b_ax
    alpha_m(t) = K_alpha alpha(t - tau_alpha) + b_alpha
    theta_m(t) = theta(t - tau_theta)
    V_m(t)     = K_V V(t)
    h_m(t)     = h(t)

The rate gyro is the time reference (only relative shifts are observable);
theta's scale is the attitude reference (only K_q / K_theta is observable,
reported as K_q); a theta bias, a V bias and an h bias cannot be told from
the initial states theta(0), V(0), h(0), which are estimated instead.

Which parameters the data determine depends on the channels present:

* ``b_q``, ``K_q``, ``tau_theta`` need theta (else q and a_z biases act on
  alpha alike: ``b_q`` is fixed at 0 and the alpha drift goes to ``b_az``);
* ``b_alpha`` needs the altitude h: only h_dot = V sin(theta - alpha) sees
  the absolute flight-path angle; in V_dot the alpha terms cancel to first
  order (a_z sin(alpha) + sin(alpha) ~ 0), and in alpha_dot an alpha bias is a
  change of alpha(0);
* ``b_ax`` and ``K_V`` need the airspeed V and a_x.

The parameters are estimated by output error: the equations are integrated
from the corrected inputs (q, a_z, a_x) by a fourth-order Runge-Kutta scheme
on the sample grid, the outputs (alpha, theta, V, h, as present) are compared
with the measurements, and bounded least squares (:mod:`fdml.lsq`, scipy's
trust-region reflective solver) minimises the residuals weighted by the
inverse of each output's residual standard deviation, re-estimated until it
settles (maximum likelihood with a diagonal noise covariance).  Standard errors come from the Gauss-Newton information
matrix, corrected for coloured residuals (the residual autocorrelation,
Bartlett-weighted up to a quarter of the record, enters the sandwich
M^-1 (J^T Rvv J) M^-1 of Morelli & Klein); the white-noise bounds are kept
beside them.
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.interpolate import CubicSpline

from .channels import SIGNALS, display_unit
from .constants import G0
from .errors import FdmlError, IdentifiabilityWarning, RecordError
from .jsoncodec import SKIP, Codec, Spec, floats, integer, number_map, texts
from .lsq import RelaxedFit, relaxed_least_squares
from .quality import _resolution
from .record import Record

__all__ = ["check_compatibility", "CompatibilityResult", "ParameterEstimate", "PARAMETERS", "apply_corrections"]

#: Sensor parameters: nominal value, unit, description.
PARAMETERS = {
    "b_q": (0.0, "rad/s", "pitch-rate gyro bias"),
    "K_q": (1.0, "-", "pitch-rate scale factor (relative to theta)"),
    "b_az": (0.0, "g", "normal accelerometer bias"),
    "K_az": (1.0, "-", "normal accelerometer scale factor"),
    "tau_az": (0.0, "s", "a_z time shift relative to q (positive: a_z lags)"),
    "b_ax": (0.0, "g", "longitudinal accelerometer bias"),
    "K_alpha": (1.0, "-", "angle-of-attack scale factor"),
    "b_alpha": (0.0, "rad", "angle-of-attack bias"),
    "tau_alpha": (0.0, "s", "angle-of-attack time shift relative to q (positive: alpha lags)"),
    "tau_theta": (0.0, "s", "pitch-attitude time shift relative to q (positive: theta lags)"),
    "K_V": (1.0, "-", "airspeed scale factor"),
}
_STATE_UNITS = {"alpha0": "rad", "theta0": "rad", "V0": "m/s", "h0": "m"}
#: Largest time shift searched, s (bounds of the tau_* parameters).
DEFAULT_MAX_SHIFT = 0.25
#: Outer passes re-estimating the output weights, and the relative change of
#: the weights at which they count as settled.
_WEIGHT_PASSES = 10
_WEIGHT_TOL = 1e-2
#: A parameter whose estimate lies more than this many standard errors from
#: its nominal value is reported as significant (three sigma: a 0.3 % false
#: alarm rate per parameter for Gaussian errors).
SIGNIFICANT = 3.0
#: An output whose residual RMS exceeds its white-noise level (third-difference
#: estimate) this many times is reported as not closing: integrated input noise
#: alone stays below a few times the output noise over flight-test records.
RESIDUAL_FACTOR = 10.0


@dataclass(frozen=True)
class ParameterEstimate(Codec):
    """One estimated quantity: value, colour-corrected and white standard errors.

    Parameters
    ----------
    name : str
        Parameter or initial state name (``b_q``, ``K_az``, ``alpha0``, ...).
    value : float
        The estimate, in ``unit``.
    stderr : float
        Standard error corrected for coloured residuals, in ``unit``.
    stderr_white : float
        Standard error assuming white residuals, in ``unit``.
    unit : str
        SI unit (``"rad/s"``, ``"s"``, ``""`` for a scale factor, ...).
    description : str
        What the quantity is (``"initial state"`` for a state).
    nominal : float
        Value of an error-free sensor (or the start value of a state), in ``unit``.
    """

    name: str
    value: float
    stderr: float
    stderr_white: float
    unit: str
    description: str
    nominal: float

    json_fields = {"name": SKIP}  # the result files the estimate under its name
    json_source = "parameter estimate"

    @property
    def z(self) -> float:
        """Distance from the nominal value in standard errors."""
        return abs(self.value - self.nominal) / self.stderr if self.stderr > 0 else math.inf

    @classmethod
    def from_dict(cls, d, *, name: str, source: str = "parameter estimate") -> ParameterEstimate:  # type: ignore[override]
        """Inverse of :meth:`to_dict`; a missing or mistyped key raises a one-line FdmlError naming ``source``.

        :meth:`to_dict` leaves the name to the result that files the estimate under it, so it is given here.

        Parameters
        ----------
        d : dict
            As written by :meth:`to_dict`.
        name : str
            The quantity's name (``b_q``, ``alpha0``, ...).
        source : str, optional
            What ``d`` came from, for the message.

        Returns
        -------
        ParameterEstimate
            The estimate.
        """
        return super().from_dict(d, source=source, name=name)


def _shown(value: float, unit: str, fmt: str) -> str:
    """An SI value in the unit it is read in (degrees for angles), with that unit."""
    f, u = display_unit(unit)
    return f"{value * f:{fmt}} {u}"


def _estimates(f, key: str, done: dict) -> dict:
    """``{name: ParameterEstimate}`` from the object ``{name: estimate dict}``."""
    sub = f.sub(key)
    return {k: ParameterEstimate.from_fields(sub.sub(k), name=k) for k in sub.doc}


def _fixed(f, key: str, done: dict) -> dict:
    """``{name: (value, reason)}`` from the object ``{name: {"value", "reason"}}``."""
    sub = f.sub(key)
    return {k: (x.number("value"), x.string("reason")) for k in sub.doc for x in [sub.sub(k)]}


@dataclass(frozen=True)
class CompatibilityResult(Codec):
    """Result of :func:`check_compatibility`.

    Parameters
    ----------
    name : str
        Record name.
    params : dict
        Sensor parameter name -> :class:`ParameterEstimate`.
    states : dict
        Initial states (alpha0, theta0, V0, h0 as present) -> ParameterEstimate.
    fixed : dict
        Parameters not estimated -> (value, reason).
    names : tuple of str
        Estimated quantities (parameters then states), the order of ``corr``.
    corr : ndarray
        Correlation matrix of all estimated quantities, in ``names`` order.
    outputs : tuple of str
        Outputs compared (alpha, theta, V, h as present).
    residual_rms : dict
        Output -> RMS of the final residual (SI units of the signal).
    sigma : dict
        Output -> the weight's standard deviation at convergence.
    n_used : int
        Samples per output in the fit (ends excluded by the time-shift margin).
    converged : bool
        Whether the optimiser converged.
    message : str
        The optimiser's message.
    record : Record or None
        The corrected record, when asked for (``correct=True``).
    findings : tuple of str
        Sentences on significant sensor errors, estimates at a bound and
        outputs whose residual exceeds the noise.
    """

    name: str
    params: dict
    states: dict
    fixed: dict
    names: tuple
    corr: np.ndarray
    outputs: tuple
    residual_rms: dict
    sigma: dict
    n_used: int
    converged: bool
    message: str
    record: Record | None = field(default=None, repr=False, compare=False)
    findings: tuple = ()

    json_fields = {
        "params": Spec(_estimates),
        "states": Spec(_estimates),
        "fixed": Spec(_fixed, write=lambda fixed: {k: {"value": v, "reason": r} for k, (v, r) in fixed.items()}),
        "names": texts(),
        # a non-finite correlation is written as 0
        "corr": Spec(floats("names", "names").read, write=lambda c: np.where(np.isfinite(c), c, 0.0)),
        "outputs": texts(),
        "residual_rms": number_map(),
        "sigma": number_map(),
        "n_used": integer(0),
        "record": SKIP,  # the corrected record is not written: read back, it is None
        "findings": texts(),
    }
    json_source = "compatibility check"

    def values(self) -> dict:
        """All sensor parameters (estimated and fixed) by name.

        Returns
        -------
        dict of str to float
            The values, SI units.
        """
        return {k: v[0] for k, v in self.fixed.items()} | {k: p.value for k, p in self.params.items()}

    def apply(self, record: Record) -> Record:
        """The record corrected with these estimates (see :func:`apply_corrections`).

        Parameters
        ----------
        record : Record
            The record as measured.

        Returns
        -------
        Record
            The corrected copy.
        """
        return apply_corrections(record, self.values())

    def summary(self) -> str:
        """Plain-text table of the estimates.

        Returns
        -------
        str
            The estimates, fixed parameters, residual RMS and findings.
        """
        lines = [
            f"Data compatibility: {self.name}",
            f"  outputs {', '.join(self.outputs)}; {self.n_used} samples each; "
            f"{'converged' if self.converged else 'NOT converged'} ({self.message})",
            "",
            f"  {'parameter':10s} {'estimate':>12s} {'std err':>10s} {'(white)':>10s}  unit     z    description",
        ]
        for p in self.params.values():
            f, u = display_unit(p.unit)
            lines.append(
                f"  {p.name:10s} {p.value * f:12.5g} {p.stderr * f:10.3g} {p.stderr_white * f:10.3g}  "
                f"{u:6s} {p.z:5.1f}  {p.description}"
            )
        if self.fixed:
            lines += ["", "  not estimated:"]
            lines += [f"    {k:10s} = {_shown(v, PARAMETERS[k][1], 'g')}: {why}" for k, (v, why) in self.fixed.items()]
        states = (f"{k} = {_shown(p.value, p.unit, '.5g')}" for k, p in self.states.items())
        rms = (f"{k} {_shown(v, SIGNALS[k], '.3g')}" for k, v in self.residual_rms.items())
        lines += ["", "  initial states: " + ", ".join(states), "  residual RMS: " + ", ".join(rms)]
        big = [
            (a, b, self.corr[i, j])
            for (i, a), (j, b) in itertools.combinations(enumerate(self.names), 2)
            if abs(self.corr[i, j]) > 0.9
        ]
        if big:
            lines.append("  correlations above 0.9: " + ", ".join(f"{a}/{b} {c:+.2f}" for a, b, c in big))
        lines += ["", "Findings:", *(f"  - {f}" for f in self.findings)]
        return "\n".join(lines)


# --- corrections -------------------------------------------------------------------------------
def apply_corrections(record: Record, values: dict) -> Record:
    """Invert the sensor models of :mod:`fdml.flightpath` on a record.

    ``q = (q_m - b_q)/K_q``, ``a_z(t) = (a_z,m(t + tau_az) - b_az)/K_az``,
    ``a_x = a_x,m - b_ax``, ``alpha(t) = (alpha_m(t + tau_alpha) - b_alpha)/K_alpha``,
    ``theta(t) = theta_m(t + tau_theta)``, ``V = V_m/K_V``.  Shifted signals
    are interpolated with cubic splines; beyond the record's ends the end
    values are held.  ``meta["compatibility"]`` records the values applied.

    Parameters
    ----------
    record : Record
        The record as measured.
    values : dict
        Sensor parameters by name (:data:`PARAMETERS`), SI units; the others
        keep their nominal (error-free) values.

    Returns
    -------
    Record
        The corrected copy.
    """
    unknown = set(values) - set(PARAMETERS)
    if unknown:
        raise FdmlError(f"unknown compatibility parameter(s) {sorted(unknown)}; known: {', '.join(PARAMETERS)}")
    v = {k: PARAMETERS[k][0] for k in PARAMETERS} | {k: float(x) for k, x in values.items()}
    t = record.t

    def shifted(x, tau):
        if tau == 0.0:
            return x
        return CubicSpline(t, x)(np.clip(t + tau, t[0], t[-1]))

    new = {
        "q": (record["q"] - v["b_q"]) / v["K_q"],
        "az": (shifted(record["az"], v["tau_az"]) - v["b_az"]) / v["K_az"],
        "alpha": (shifted(record["alpha"], v["tau_alpha"]) - v["b_alpha"]) / v["K_alpha"],
    }
    if record.has("ax"):
        new["ax"] = record["ax"] - v["b_ax"]
    if record.has("theta"):
        new["theta"] = shifted(record["theta"], v["tau_theta"])
    if record.has("V"):
        new["V"] = record["V"] / v["K_V"]
    return replace(
        record, signals={**record.signals, **new}, meta={**record.meta, "compatibility": {k: v[k] for k in PARAMETERS}}
    )


# --- the estimator -------------------------------------------------------------------------------
def _integrate(a, th, V, dt, q, az, ax, Vin):
    """Fourth-order Runge-Kutta integration of the kinematics on the sample grid.

    Inputs are arrays at the samples and the midpoints (index 2k and 2k+1);
    ``ax`` None means a_x = sin(theta) (steady flight), ``Vin`` not None
    means the airspeed is an input rather than a state; h starts at 0.
    Written out in scalars: this loop is the check's whole cost.
    """
    g = G0
    cos, sin = math.cos, math.sin
    n = (len(q) + 1) // 2
    q, az = q.tolist(), az.tolist()
    ax = None if ax is None else ax.tolist()
    Vin = None if Vin is None else Vin.tolist()
    A, TH, VV, HH = [a] * n, [th] * n, [V] * n, [0.0] * n
    h = 0.0
    hdt = 0.5 * dt
    sixth = dt / 6.0
    vstate = Vin is None

    def rates(a, v, th, q, z, x):
        """alpha_dot, V_dot (0 when V is an input) and h_dot of the kinematics at one RK4 stage."""
        ca, sa, gm = cos(a), sin(a), th - a
        return (
            q + g / v * (z * ca - x * sa + cos(gm)),
            (g * (x * ca + z * sa - sin(gm)) if vstate else 0.0),
            v * sin(gm),
        )

    for k in range(n - 1):
        i0 = 2 * k
        q0, q1, q2 = q[i0 : i0 + 3]
        z0, z1, z2 = az[i0 : i0 + 3]
        # theta depends on q only
        t1, t2, t3, t4 = th, th + hdt * q0, th + hdt * q1, th + dt * q1
        if ax is None:
            x0, x1a, x1b, x2 = sin(t1), sin(t2), sin(t3), sin(t4)
        else:
            x0, x1a, x1b, x2 = ax[i0], ax[i0 + 1], ax[i0 + 1], ax[i0 + 2]
        if vstate:
            v1 = V
        else:
            v1, vm, v4 = Vin[i0 : i0 + 3]
        da1, dV1, dh1 = rates(a, v1, t1, q0, z0, x0)
        a2 = a + hdt * da1
        v2 = V + hdt * dV1 if vstate else vm
        da2, dV2, dh2 = rates(a2, v2, t2, q1, z1, x1a)
        a3 = a + hdt * da2
        v3 = V + hdt * dV2 if vstate else vm
        da3, dV3, dh3 = rates(a3, v3, t3, q1, z1, x1b)
        a4 = a + dt * da3
        vv4 = V + dt * dV3 if vstate else v4
        da4, dV4, dh4 = rates(a4, vv4, t4, q2, z2, x2)
        a += sixth * (da1 + 2 * da2 + 2 * da3 + da4)
        th += sixth * (q0 + 4 * q1 + q2)
        V = V + sixth * (dV1 + 2 * dV2 + 2 * dV3 + dV4) if vstate else v4
        h += sixth * (dh1 + 2 * dh2 + 2 * dh3 + dh4)
        if not (-10.0 < a < 10.0 and 0.0 < V < 1e5):
            raise FloatingPointError("kinematic integration diverged")
        A[k + 1], TH[k + 1], VV[k + 1], HH[k + 1] = a, th, V, h
    return np.array(A), np.array(TH), np.array(VV), np.array(HH)


#: The parameters the integration depends on (the others act on its outputs).
_INTEGRATION_INPUTS = ("b_q", "K_q", "tau_az", "b_az", "K_az", "b_ax", "K_V", "alpha0", "theta0", "V0")


class _Run:
    """One integration: time (s), alpha (rad), theta (rad), V (m/s) and h - h0 (m) at the samples.

    ``delayed`` gives alpha or theta a time shift, from a spline built once per run.
    """

    def __init__(self, t, A, TH, VV, HH):
        self.t, self.A, self.TH, self.VV, self.HH = t, A, TH, VV, HH
        self._splines: dict = {}

    def delayed(self, name: str, tau: float) -> np.ndarray:
        """``name`` ("A" or "TH") at t - tau, by cubic interpolation."""
        x = getattr(self, name)
        if tau == 0.0:
            return x
        if name not in self._splines:
            self._splines[name] = CubicSpline(self.t, x)
        return self._splines[name](self.t - tau)


class _Problem:
    """Kinematic simulation and residuals for one record."""

    def __init__(self, record: Record, free: list[str], fixed: dict, max_shift: float, U: float):
        self.rec = record
        self.t = record.t
        self.dt = record.dt
        self.n = record.n
        self.has_theta = record.has("theta")
        self.has_h = record.has("h")
        self.has_ax = record.has("ax")
        self.V_state = record.has("V") and self.has_ax
        self.fixed = fixed
        self.U = U
        present = {"alpha": True, "theta": self.has_theta, "V": self.V_state, "h": self.has_h}
        self.outputs = tuple(k for k, on in present.items() if on)
        self.states = [f"{k}0" for k in self.outputs]  # each output's initial value
        self.names = free + self.states
        m = int(math.ceil(max_shift / self.dt)) + 1
        self.sel = slice(m, self.n - m)
        self.n_used = self.n - 2 * m
        if self.n_used < 10:
            raise RecordError(
                f"record {record.name!r} is too short for a compatibility check with time shifts "
                f"of up to {max_shift:g} s ({self.n} samples)"
            )
        self.meas = {k: record[k] for k in self.outputs}
        self.tt = np.empty(2 * self.n - 1)  # the samples and the midpoints between them
        self.tt[0::2], self.tt[1::2] = self.t, self.t[:-1] + 0.5 * self.dt
        # the inputs' cubic splines (fourth order, like the integrator: linear midpoints would bias
        # slowly varying integrals), and their values at the samples and midpoints; V without a
        # channel is the airspeed given
        inputs = {k: record[k] for k in ("q", "az", "ax", "V") if record.has(k)}
        self.splines = {k: CubicSpline(self.t, x) for k, x in ({"V": np.full(self.n, U)} | inputs).items()}
        self.mid = {k: spline(self.tt) for k, spline in self.splines.items()}
        self._runs: dict = {}

    def unpack(self, x):
        return self.fixed | dict(zip(self.names, x))

    def _run(self, p) -> _Run:
        """The kinematics integrated from the corrected inputs, reusing the last runs.

        The weights do not enter the integration, and K_alpha, b_alpha,
        tau_alpha, tau_theta and h0 act on its outputs only.  Keeping the
        runs of one Jacobian (one per unknown and the point itself), a column
        of one of those five reuses the run (and its splines) at the point,
        and the first Jacobian of a weight pass, at the point where the pass
        before ended, repeats no integration.
        """
        key = tuple(float(p.get(k, 0.0)) for k in _INTEGRATION_INPUTS)
        run = self._runs.pop(key, None) or self._new_run(p)
        self._runs[key] = run  # the most recent last
        if len(self._runs) > len(self.names) + 2:
            del self._runs[next(iter(self._runs))]
        return run

    def _new_run(self, p) -> _Run:
        """One integration from the inputs corrected by the sensor parameters in ``p``."""
        q = (self.mid["q"] - p["b_q"]) / p["K_q"]
        if p["tau_az"] != 0.0:
            az_src = self.splines["az"](np.clip(self.tt + p["tau_az"], self.t[0], self.t[-1]))
        else:
            az_src = self.mid["az"]
        az = (az_src - p["b_az"]) / p["K_az"]
        ax = self.mid["ax"] - p["b_ax"] if self.has_ax else None
        Vin = None if self.V_state else self.mid["V"] / p["K_V"]
        theta0 = p["theta0"] if self.has_theta else p["alpha0"]
        V0 = p["V0"] if Vin is None else Vin[0]
        return _Run(self.t, *_integrate(float(p["alpha0"]), float(theta0), float(V0), self.dt, q, az, ax, Vin))

    def simulate(self, p) -> dict:
        """Integrate the kinematics; returns the simulated outputs (as measured, sensor models applied)."""
        run = self._run(p)
        out = {"alpha": p["K_alpha"] * run.delayed("A", p["tau_alpha"]) + p["b_alpha"]}
        if self.has_theta:
            out["theta"] = run.delayed("TH", p["tau_theta"])
        if self.V_state:
            out["V"] = p["K_V"] * run.VV
        if self.has_h:
            out["h"] = p.get("h0", 0.0) + run.HH
        return out

    def noise_covariance(self, J: np.ndarray, p: dict, sigma: dict) -> np.ndarray:
        """Covariance of the estimates from white noise on the inputs and outputs.

        Output error treats q, a_z and a_x as exact; their noise is integrated
        by the kinematics into random walks of theta, alpha, V and h that a
        residual-based bound cannot see in full (a bias absorbs its trend).
        Linearised, with c = g/U and L the running-integral operator::

            d alpha = L (dq/K_q) + c L (d a_z/K_az),   d theta = L dq/K_q,
            d V = g L d a_x,                          d h = -g L L d a_z/K_az

        and measurement noise adds white noise to each output.  The noise
        levels come from the data (:func:`noise_level`).  Returns
        M^-1 J^T W^(1/2) (R_in + R_meas) W^(1/2) J M^-1.
        """
        n, dt = self.n, self.dt
        Lm = np.tril(np.ones((n, n)), -1) * dt
        c = G0 / self.U
        s_q = noise_level(self.rec["q"]) / p["K_q"]
        s_az = noise_level(self.rec["az"]) / p["K_az"]
        s_ax = noise_level(self.rec["ax"]) if self.has_ax else 0.0
        zero = np.zeros((n, n))
        blocks = []  # per output: sensitivity to (dq, daz, dax), each n x n
        for k in self.outputs:
            if k == "alpha":
                blocks.append((p["K_alpha"] * Lm, p["K_alpha"] * c * Lm, zero))
            elif k == "theta":
                blocks.append((Lm, zero, zero))
            elif k == "V":
                blocks.append((zero, zero, p["K_V"] * G0 * Lm))
            elif k == "h":
                blocks.append((zero, -G0 * (Lm @ Lm), zero))
        Minv = np.linalg.pinv(J.T @ J)
        mid = np.zeros((J.shape[1], J.shape[1]))
        AJ = [np.zeros((n, J.shape[1])) for _ in range(3)]
        for j, k in enumerate(self.outputs):
            Jk = J[j * self.n_used : (j + 1) * self.n_used]
            for i in range(3):
                AJ[i] += blocks[j][i][self.sel].T @ Jk / sigma[k]
            s_meas = noise_level(self.meas[k])
            mid += (s_meas / sigma[k]) ** 2 * (Jk.T @ Jk)
        for i, s2 in enumerate((s_q**2, s_az**2, s_ax**2)):
            mid += s2 * (AJ[i].T @ AJ[i])
        return Minv @ mid @ Minv

    def errors(self, x) -> np.ndarray:
        """Measured minus simulated outputs over the used samples, shape (outputs, n_used)."""
        y = self.simulate(self.unpack(x))
        return np.array([self.meas[k][self.sel] - y[k][self.sel] for k in self.outputs])


def _default_free(record: Record) -> tuple[list[str], dict]:
    """Parameters the record's channels determine, and reasons for the others."""
    free = ["b_az", "K_alpha", "tau_alpha"]
    why: dict = {}
    if record.has("theta"):
        free += ["b_q", "K_q", "tau_theta"]
    else:
        why |= dict.fromkeys(
            ("b_q", "K_q", "tau_theta"),
            "no theta: a q bias and an a_z bias drift alpha alike, and a q scale factor has no "
            "reference; the alpha drift is given to b_az",
        )
    if record.has("h"):
        free.append("b_alpha")
    else:
        why["b_alpha"] = (
            "no altitude: only h_dot = V sin(theta - alpha) sees the absolute flight-path angle; "
            "otherwise an alpha bias is a change of the initial alpha"
        )
    if record.has("ax") and record.has("V"):
        free.append("b_ax")
    else:
        why["b_ax"] = "no airspeed or no a_x: the airspeed equation is not integrated"
    for k in ("K_az", "tau_az", "K_V"):
        cause = "" if k == "K_V" else ": with a_z near -1 g a scale error looks like a bias"
        why[k] = (
            f"not estimated by default{cause} "
            f"(to estimate it: fdml check --compat --estimate {','.join([*free, k])}; Python: estimate=)"
        )
    return free, why


def _checked_airspeed(record: Record, U: float | None) -> float:
    """Refuse a record the check cannot use (trim removed, a_z sign flipped, no airspeed); the airspeed, m/s."""
    if not isinstance(record, Record):
        raise RecordError(f"expected an fdml Record, got {type(record).__name__}")
    az_mean = float(np.mean(record["az"]))
    if 0.4 < az_mean < 1.6:
        raise RecordError(
            f"record {record.name!r}: mean a_z is {az_mean:+.3g} g; in level flight fdml's a_z (body z, "
            "positive down, docs/theory.md Eq. 5) is near -1 g: the sign looks flipped (a normal acceleration "
            "a_n, positive up?). Load it with the sign reversed (--sign az=-1)"
        )
    if not -1.6 < az_mean < -0.4:
        raise RecordError(
            f"record {record.name!r}: mean a_z is {az_mean:.3g} g; the compatibility check needs the record "
            "with trim kept (a_z near -1 g in level flight, body z positive down). Load it without trim= "
            "or add the trim back"
        )
    U = record.meta.get("U") if U is None else U
    if not record.has("V") and (U is None or not U > 0):
        raise RecordError(f"record {record.name!r} has no airspeed V: pass U= (m/s)")
    return float(U) if U is not None else float(np.mean(record["V"]))


def _choose_free(record: Record, estimate, fix) -> tuple[list[str], dict[str, float], dict[str, str]]:
    """Free parameters, values of the fixed ones and why each is not estimated."""
    free, why = _default_free(record)
    if estimate is not None:
        free = list(estimate)
        bad = [k for k in free if k not in PARAMETERS]
        if bad:
            raise FdmlError(f"unknown compatibility parameter(s) {bad}; known: {', '.join(PARAMETERS)}")
        why = {k: "not requested" for k in PARAMETERS if k not in free}
    fixed_vals = {k: PARAMETERS[k][0] for k in PARAMETERS if k not in free}
    for k, v in dict(fix or {}).items():
        if k not in PARAMETERS:
            raise FdmlError(f"unknown compatibility parameter {k!r}; known: {', '.join(PARAMETERS)}")
        if k in free:
            free.remove(k)
        fixed_vals[k] = float(v)
        why[k] = "fixed by the caller"
    return free, fixed_vals, why


def _start(prob: _Problem, free: list[str], max_shift: float):
    """Start (nominal sensors, measured initial states) and bounds of the unknowns."""
    x0 = np.array([PARAMETERS[k][0] for k in free] + [float(prob.rec[k][0]) for k in prob.outputs])
    by_unit = {"s": (-max_shift, max_shift), "-": (0.2, 5.0)}  # time shifts (tau_*), scale factors (K_*)
    bounds = [by_unit.get(PARAMETERS[k][1], (-np.inf, np.inf)) for k in free]
    lo, hi = np.array(bounds + [(-np.inf, np.inf)] * len(prob.outputs)).T
    return x0, lo, hi


def _solve(prob: _Problem, x0, lo, hi) -> RelaxedFit:
    """Least-squares passes, each output weighted by its residual RMS of the pass before (:mod:`fdml.lsq`)."""
    floor = [_sigma_floor(prob.rec[k]) for k in prob.outputs]
    start = np.array([noise_level(prob.rec[k]) for k in prob.outputs])  # each at least its floor
    return relaxed_least_squares(prob.errors, x0, (lo, hi), start, passes=_WEIGHT_PASSES, tol=_WEIGHT_TOL, floor=floor)


def _uncertainty(prob: _Problem, J, r, x, sigma):
    """Standard errors (the largest of white, coloured and noise-propagated), the white ones, and correlations."""
    cov_w, cov_c = _covariances(J, r, len(prob.outputs), prob.n_used)
    cov_n = prob.noise_covariance(J, prob.unpack(x), sigma)
    se_w, se_c, se_n = (np.sqrt(np.clip(np.diag(c), 0, None)) for c in (cov_w, cov_c, cov_n))
    se = np.maximum.reduce([se_w, se_c, se_n])
    cov = cov_n if np.sum(se_n >= se_c) >= np.sum(se_c > se_n) else cov_c
    d = np.sqrt(np.clip(np.diag(cov), 0, None))
    d = np.where(d > 0, d, np.nan)
    return se, se_w, cov / np.outer(d, d)


def check_compatibility(
    record: Record,
    *,
    correct: bool = False,
    estimate=None,
    fix=None,
    max_shift: float = DEFAULT_MAX_SHIFT,
    U: float | None = None,
) -> CompatibilityResult:
    """Estimate sensor biases, scale factors and time shifts from the kinematics.

    Parameters
    ----------
    record : Record
        Needs ``alpha``, ``q``, ``az``; uses ``theta``, ``V``, ``ax`` and ``h``
        where present (module docstring: which parameter needs which channel).
        Trim must **not** be removed (the kinematics involve the absolute
        angles and a_z near -1 g).
    correct : bool, optional
        Also return the corrected record (``result.record``).
    estimate : iterable of str, optional
        Sensor parameters to estimate (default: those the channels determine,
        see the module docstring); names from :data:`PARAMETERS`.
    fix : mapping, optional
        Values for parameters that are not estimated (default: nominal, 0 or 1).
    max_shift : float, optional
        Largest time shift searched, s (default 0.25 s).
    U : float, optional
        Airspeed, m/s, for records without ``V`` (default ``meta["U"]``).

    Returns
    -------
    CompatibilityResult
        The sensor-error estimates, their uncertainty and the fit's residuals.

    Raises
    ------
    RecordError
        If the record looks trimmed (a_z near 0 instead of -1 g), lacks an
        airspeed, or is too short.
    """
    U = _checked_airspeed(record, U)
    free, fixed_vals, why = _choose_free(record, estimate, fix)
    prob = _Problem(record, free, fixed_vals, max_shift, U)
    x0, lo, hi = _start(prob, free, max_shift)
    fit = _solve(prob, x0, lo, hi)
    x, sigma = fit.x, dict(zip(prob.outputs, fit.sigma.tolist()))
    se, se_w, corr = _uncertainty(prob, fit.J, fit.r, x, sigma)
    est = {}
    for i, k in enumerate(prob.names):
        nom, unit, desc = PARAMETERS[k] if k in PARAMETERS else (float(x0[i]), _STATE_UNITS[k], "initial state")
        est[k] = ParameterEstimate(k, float(x[i]), float(se[i]), float(se_w[i]), unit, desc, nom)
    params = {k: est[k] for k in free}
    rms = {k: float(np.sqrt(np.mean(e**2))) for k, e in zip(prob.outputs, prob.errors(x))}
    out = CompatibilityResult(
        name=record.name,
        params=params,
        states={k: est[k] for k in prob.states},
        fixed={k: (fixed_vals[k], why.get(k, "fixed")) for k in PARAMETERS if k not in free},
        corr=corr,
        names=tuple(prob.names),
        outputs=prob.outputs,
        residual_rms=rms,
        sigma=dict(sigma),
        n_used=prob.n_used,
        converged=fit.success and fit.settled,
        message=fit.message if fit.settled else f"output weights still changing after {_WEIGHT_PASSES} passes",
        findings=tuple(_findings(params, free, prob, x, hi, lo, rms)),
    )
    if correct:
        out = replace(out, record=out.apply(record))
    return out


def noise_level(x: np.ndarray) -> float:
    """Standard deviation of the white noise on a sampled channel.

    Third differences of a smooth signal are of order dt^3 times its third
    derivative and vanish at flight-test rates, while white noise of
    variance s^2 gives third differences of variance 20 s^2; the median
    absolute value (divided by 0.6745, the normal MAD) resists the few large
    values at step inputs.  Quantisation noise, step/sqrt(12), is the floor.

    Parameters
    ----------
    x : numpy.ndarray
        The channel's samples, shape (n,).

    Returns
    -------
    float
        The standard deviation, in the channel's unit (0 for fewer than 4 samples).
    """
    d3 = np.diff(np.asarray(x, dtype=float), 3)
    if d3.size == 0:
        return 0.0
    s = float(np.median(np.abs(d3)) / 0.6745 / math.sqrt(20.0))
    return max(s, _sigma_floor(x))


def _sigma_floor(x: np.ndarray) -> float:
    """Smallest credible noise level: the quantisation noise of the channel (step / sqrt 12)."""
    return max(_resolution(x)[0] / math.sqrt(12), 1e-12)


def _covariances(J: np.ndarray, r: np.ndarray, n_out: int, n_used: int):
    """White (M^-1) and coloured (Morelli-Klein sandwich) covariances of the estimates.

    ``J`` and ``r`` are of the weighted residuals (unit variance per output);
    the coloured form replaces J^T J in the middle by sum over outputs of
    sum_l w_l rho(l) (J_k^T S_l J_k), with the residual autocorrelation
    rho(l) of each output block, Bartlett weights w_l = 1 - l/(L+1) and
    L = n/4 lags.
    """
    M = J.T @ J
    try:
        c = np.linalg.cond(M)
    except np.linalg.LinAlgError:
        c = np.inf
    if not np.isfinite(c) or c > 1e14:
        warnings.warn(
            "compatibility check: the information matrix is (nearly) singular; some parameters are "
            "not determined by this record",
            IdentifiabilityWarning,
            stacklevel=3,
        )
    Minv = np.linalg.pinv(M)
    L = max(1, n_used // 4)
    mid = np.zeros_like(M)
    for k in range(n_out):
        Jk = J[k * n_used : (k + 1) * n_used]
        e = r[k * n_used : (k + 1) * n_used]
        var = float(np.mean(e**2))
        mid += Jk.T @ Jk * var
        for lag in range(1, L + 1):
            rho = float(np.mean(e[:-lag] * e[lag:]))
            w = 1.0 - lag / (L + 1)
            C = Jk[:-lag].T @ Jk[lag:]
            mid += w * rho * (C + C.T)
    cov_c = Minv @ mid @ Minv
    # white form, scaled by the residual variance (1 at convergence of the weights)
    s2 = float(np.mean(r**2))
    return Minv * s2, cov_c


def _findings(params, free, prob, x, hi, lo, rms: dict[str, float]) -> list[str]:
    """Significant sensor errors, estimates at a bound, and outputs whose residual RMS exceeds the noise."""
    out = []
    sig = [p for p in params.values() if p.z > SIGNIFICANT]
    for p in sorted(sig, key=lambda p: -p.z):
        f, u = display_unit(p.unit)
        out.append(
            f"{p.description} {p.name} = {p.value * f:.4g} +- {p.stderr * f:.2g} {u}: "
            f"{p.z:.1f} standard errors from {p.nominal * f:g}, significant"
        )
    quiet = [p.name for p in params.values() if p.z <= SIGNIFICANT]
    if quiet:
        out.append(f"consistent with nominal (within {SIGNIFICANT:g} standard errors): {', '.join(quiet)}")
    for i, k in enumerate(free):
        if np.isfinite(hi[i]) and any(abs(x[i] - b) < 1e-6 * (1 + abs(b)) for b in (lo[i], hi[i])):
            out.append(f"{k} sits at its bound ({x[i]:g}): the data push it beyond the searched range")
    if not sig:
        out.insert(0, "the record is kinematically consistent: no sensor error is significant")
    if "b_alpha" in params:
        out.append(
            "b_alpha rests on the altitude channel (h_dot = V sin(theta - alpha)): a static-pressure error of "
            "a barometric altitude, or a steady vertical wind, reads as an alpha bias"
        )
    for k in prob.outputs:
        floor = noise_level(prob.meas[k])
        if rms[k] > RESIDUAL_FACTOR * floor:
            f, u = display_unit(SIGNALS[k])
            out.append(
                f"the kinematics do not close for {k}: residual RMS {rms[k] * f:.3g} {u} is "
                f"{rms[k] / floor:.0f} times its noise level ({floor * f:.2g} {u}); wind, sensor dynamics or "
                "errors outside the sensor models remain"
            )
    return out
