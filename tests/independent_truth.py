"""An independent time-domain truth for the short-period model: records that no fdml code made.

The linear short-period model in dimensional derivatives (the form of
``fdml.models.conventional``'s docstring and of ``tests/conftest.py``'s ``lsim_dimensional``)::

    alpha_dot = Z_a alpha + (1 + Z_q) q + Z_de de
    q_dot     = M_a alpha + M_q q + M_de de
    a_z       = (U/g)(alpha_dot - q)            (docs/theory.md Eq. 5; g, body z, positive down)

is integrated here with :func:`scipy.integrate.solve_ivp` (DOP853, rtol 1e-10), and the sensors
are applied in the time domain where they physically act.  Nothing of fdml's models, effects,
manoeuvres or simulator is used; :class:`fdml.record.Record` only wraps the arrays.

Why ``solve_ivp`` and not ``scipy.signal.lsim``: lsim sees the input only at its grid points
(zero- or first-order hold), so an elevator step between samples, or a raised-cosine edge, is
seen as the hold's interpolation, and a delayed channel y(t - tau) needs values off the grid.
Here the elevator is a function of continuous time, the integration is split at every edge's
start and end (so a true step is seen at its real time, whatever the sample interval), and the
dense output (DOP853's 7th-order interpolant, accurate to the integration tolerance) gives the
state at any time, in particular at t - tau.  The record then *samples* the physical signals.

Sensor effects (x in metres ahead of the c.g.):

- alpha vane at x_alpha:      alpha_m = alpha - x_alpha q / U
- accelerometer at x_az:      a_z,m  = a_z - x_az q_dot / g   (q_dot from the state equation)
- timing: channel c recorded tau_c late: y_c,m(t) = y_c(t - tau_c) from the continuous solution
- scale: y_c,m = s_c y_c  (s_c the channel's scale factor, 1 = exact)

applied in that order (position, then timing, then scale), then white noise of ``noise`` times
each channel's RMS (a seeded :class:`numpy.random.Generator`).

Before its first sample the aircraft flies free (elevator at trim): for t < 0 the state is the
backward integration from the record's initial state (alpha0, q0), so a delayed channel's first
samples are physical too.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy import integrate

from fdml.record import Record

__all__ = ["NAVION", "U_NAVION", "G", "Manoeuvre", "Sensors", "Trajectory", "solve", "measure", "simulate_record"]

#: The Navion's dimensional derivatives: ``fdml.make_model("dimensional", "navion").parameters.values``
#: (printed at fdml 9264072; full digits so that a fit of the base model has the same truth).
#: Z_a 1/s, Z_q -, Z_de 1/s, M_a 1/s^2, M_q 1/s, M_de 1/s^2.
NAVION = {
    "Z_a": -2.2471065396706367,
    "Z_q": -0.035141176500236605,
    "Z_de": -0.22964299934776009,
    "M_a": -12.870500421417148,
    "M_q": -2.6610748811624054,
    "M_de": -18.275303827334216,
}
#: The Navion's true airspeed, m/s (176 ft/s; ``fdml.make_model("dimensional", "navion").U``).
U_NAVION = 53.6448
#: Standard gravity, m/s^2 (the g of a_z in g).
G = 9.80665
#: Integration tolerances: relative 1e-10 and absolute 1e-13 rad (the states are ~1e-2 rad),
#: so the integration error is some 1e-9 of the signals, far below any noise or fit tolerance.
RTOL, ATOL = 1e-10, 1e-13
#: Free flight simulated before the first sample, s: covers any delay of :class:`Sensors`.
PRE_ROLL = 0.5
CHANNELS = ("alpha", "q", "az")
#: Pulse pattern of each manoeuvre kind: (width in units of ``unit``, sign) per pulse.
PATTERNS = {"3211": ((3, 1), (2, -1), (1, 1), (1, -1)), "doublet": ((1, 1), (1, -1)), "step": ((np.inf, 1),)}
EDGES = ("cosine", "linear", "step")


@dataclass(frozen=True)
class Manoeuvre:
    """An elevator manoeuvre as a function of continuous time (rad, trailing edge down positive).

    Parameters
    ----------
    kind : {"3211", "doublet", "step"}
        Pulse pattern: 3-2-1-1 (3, 2, 1, 1 units, alternating sign), doublet (1, 1), or one
        step held to the end.
    amplitude : float
        Pulse height, rad.
    start : float
        Time of the first edge, s (need not fall on a sample).
    unit : float
        Width of one unit pulse, s.
    edge : {"cosine", "linear", "step"}
        Shape of each edge: raised cosine or linear ramp of ``width`` seconds starting at the
        nominal edge time, or a true step at the edge time.
    width : float
        Edge width, s (ignored for ``"step"``).
    """

    kind: str = "3211"
    amplitude: float = 0.02
    start: float = 1.0
    unit: float = 0.3
    edge: str = "cosine"
    width: float = 0.1

    def __post_init__(self) -> None:
        if self.kind not in PATTERNS:
            raise ValueError(f"manoeuvre kind {self.kind!r} unknown: use one of {sorted(PATTERNS)}")
        if self.edge not in EDGES:
            raise ValueError(f"edge {self.edge!r} unknown: use one of {EDGES}")
        if self.start < 0 or self.unit <= 0 or (self.edge != "step" and not 0 < self.width < self.unit):
            raise ValueError(f"manoeuvre needs start >= 0 and 0 < width < unit, got {self}")

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Nominal edge times (s) and the level change at each (rad)."""
        times, steps, a, level = [], [], self.start, 0.0
        for width, sign in (*PATTERNS[self.kind], (0, 0)):
            if not np.isfinite(a):
                break
            times.append(a)
            steps.append(sign * self.amplitude - level)
            level = sign * self.amplitude
            a += width * self.unit
        return np.array(times), np.array(steps)

    def breakpoints(self) -> np.ndarray:
        """Times where the elevator is not smooth (edge starts and ends), s."""
        times, _ = self.edges()
        if self.edge == "step":
            return times
        return np.sort(np.concatenate([times, times + self.width]))

    def __call__(self, t) -> np.ndarray:
        """The elevator deflection at times ``t`` (s), rad; a step takes its new value at the edge time."""
        t = np.asarray(t, dtype=float)
        de = np.zeros_like(t)
        for a, d in zip(*self.edges()):
            if self.edge == "step":
                de = de + d * (t >= a)
                continue
            r = np.clip((t - a) / self.width, 0.0, 1.0)
            de = de + d * (r if self.edge == "linear" else 0.5 * (1.0 - np.cos(np.pi * r)))
        return de


@dataclass(frozen=True)
class Sensors:
    """Where and when the sensors measure, and their scale factors.

    Parameters
    ----------
    x_alpha : float
        Alpha vane position ahead of the c.g., m.
    x_az : float
        Accelerometer position ahead of the c.g., m.
    delays : mapping of str to float
        Channel (``alpha``, ``q``, ``az``) -> recording delay tau >= 0, s.
    scales : mapping of str to float
        Channel -> scale factor (1 = exact).
    """

    x_alpha: float = 0.0
    x_az: float = 0.0
    delays: Mapping[str, float] = field(default_factory=dict)
    scales: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for what, m in (("delays", self.delays), ("scales", self.scales)):
            bad = sorted(set(m) - set(CHANNELS))
            if bad:
                raise ValueError(f"sensor {what}: unknown channel {bad[0]!r}, use one of {CHANNELS}")
        for ch, tau in self.delays.items():
            if not 0.0 <= tau <= PRE_ROLL:
                raise ValueError(f"sensor delay of {ch} must be in [0, {PRE_ROLL}] s (a causal lag), got {tau}")


@dataclass(frozen=True)
class Trajectory:
    """The continuous solution: state, rates and elevator at any time in [-PRE_ROLL, end].

    Parameters
    ----------
    derivs : mapping of str to float
        The dimensional derivatives (see :data:`NAVION`).
    U : float
        True airspeed, m/s.
    manoeuvre : Manoeuvre
        The elevator.
    pieces : tuple of (float, float, OdeSolution)
        Each integration piece's start and end time, s, and dense output.
    """

    derivs: Mapping[str, float]
    U: float
    manoeuvre: Manoeuvre
    pieces: tuple

    def state(self, t) -> np.ndarray:
        """(alpha rad, q rad/s) at times ``t`` (s), shape (2, n)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = np.full((2, t.size), np.nan)
        for lo, hi, sol in self.pieces:
            m = (t >= min(lo, hi)) & (t <= max(lo, hi))
            if m.any():
                x[:, m] = sol(t[m])
        if np.isnan(x).any():
            raise ValueError(f"times outside the simulated span {self.span()} s")
        return x

    def span(self) -> tuple[float, float]:
        """First and last simulated time, s."""
        ends = [e for lo, hi, _ in self.pieces for e in (lo, hi)]
        return min(ends), max(ends)

    def rates(self, t) -> np.ndarray:
        """(alpha_dot rad/s, q_dot rad/s^2) at times ``t`` (s), from the state equations."""
        return _rhs(self.derivs, self.state(t), self.manoeuvre(t))

    def az(self, t) -> np.ndarray:
        """a_z at the c.g. at times ``t``, g (docs/theory.md Eq. 5: (U/g)(alpha_dot - q))."""
        return self.U / G * (self.rates(t)[0] - self.state(t)[1])


def _rhs(p: Mapping[str, float], x: np.ndarray, de) -> np.ndarray:
    """The state equations: (alpha_dot, q_dot) for states x (2, ...) and elevator de (rad)."""
    a, q = x[0], x[1]
    return np.array(
        [p["Z_a"] * a + (1.0 + p["Z_q"]) * q + p["Z_de"] * de, p["M_a"] * a + p["M_q"] * q + p["M_de"] * de]
    )


def solve(
    manoeuvre: Manoeuvre, end: float, *, derivs: Mapping[str, float] = NAVION, U: float = U_NAVION, x0=(0.0, 0.0)
) -> Trajectory:
    """Integrate the short-period model from (alpha0, q0) at t = 0, forward to ``end`` and back PRE_ROLL.

    Parameters
    ----------
    manoeuvre : Manoeuvre
        The elevator (zero before its start, so the backward piece is free flight).
    end : float
        Last time, s.
    derivs : mapping of str to float, optional
        Z_a, Z_q, Z_de, M_a, M_q, M_de (default the Navion's).
    U : float, optional
        True airspeed, m/s.
    x0 : (float, float), optional
        alpha (rad) and q (rad/s) at t = 0.

    Returns
    -------
    Trajectory
        The dense solution over [-PRE_ROLL, end].
    """

    cuts = manoeuvre.breakpoints()
    knots = np.unique(np.concatenate([[0.0], cuts[(cuts > 0) & (cuts < end)], [end]]))
    x = np.asarray(x0, dtype=float)
    pieces = [(0.0, -PRE_ROLL, _piece(derivs, manoeuvre, 0.0, -PRE_ROLL, x)[0])]
    for lo, hi in zip(knots[:-1], knots[1:]):  # a new piece at every edge: the integrator never steps over one
        sol, x = _piece(derivs, manoeuvre, lo, hi, x)
        pieces.append((lo, hi, sol))
    return Trajectory(derivs=dict(derivs), U=U, manoeuvre=manoeuvre, pieces=tuple(pieces))


def _piece(derivs, manoeuvre: Manoeuvre, lo: float, hi: float, x: np.ndarray):
    """Dense solution from ``lo`` to ``hi`` (s) starting at state ``x``, and the end state.

    With step edges the elevator is constant on a piece (pieces end at the steps): it is
    read at the piece's middle, so that the integrator's stage at an end point does not
    see the next level.
    """
    if manoeuvre.edge == "step":
        de_mid = float(manoeuvre(0.5 * (lo + hi)))

        def f(t, x):
            return _rhs(derivs, x, de_mid)
    else:

        def f(t, x):
            return _rhs(derivs, x, float(manoeuvre(t)))

    sol = integrate.solve_ivp(f, (lo, hi), x, method="DOP853", rtol=RTOL, atol=ATOL, dense_output=True)
    if not sol.success:
        raise RuntimeError(f"integration failed on [{lo}, {hi}] s: {sol.message}")
    return sol.sol, sol.y[:, -1]


def measure(traj: Trajectory, t, sensors: Sensors = Sensors()) -> dict[str, np.ndarray]:
    """The sensors' noise-free readings at times ``t`` (s): alpha rad, q rad/s, az g.

    Parameters
    ----------
    traj : Trajectory
        The continuous solution.
    t : array_like
        Sample times, s.
    sensors : Sensors, optional
        Positions, delays and scale factors.

    Returns
    -------
    dict of str to ndarray
        ``alpha``, ``q``, ``az``.
    """
    t = np.asarray(t, dtype=float)
    out = {}
    for ch in CHANNELS:
        ts = t - sensors.delays.get(ch, 0.0)  # recorded tau late: the value of tau ago
        alpha, q = traj.state(ts)
        if ch == "alpha":
            y = alpha - sensors.x_alpha * q / traj.U
        elif ch == "q":
            y = q
        else:
            y = traj.az(ts) - sensors.x_az * traj.rates(ts)[1] / G
        out[ch] = sensors.scales.get(ch, 1.0) * y
    return out


def simulate_record(
    manoeuvre: Manoeuvre = Manoeuvre(),
    sensors: Sensors = Sensors(),
    *,
    dt: float = 0.02,
    duration: float = 12.0,
    derivs: Mapping[str, float] = NAVION,
    U: float = U_NAVION,
    x0=(0.0, 0.0),
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
    name: str = "independent truth",
) -> tuple[Record, dict]:
    """A sampled record of the independent truth and the truth that made it.

    Parameters
    ----------
    manoeuvre : Manoeuvre, optional
        The elevator (recorded exactly at the sample times).
    sensors : Sensors, optional
        The sensor effects.
    dt : float, optional
        Sample interval, s.
    duration : float, optional
        Record length, s (samples at 0, dt, ..., duration).
    derivs : mapping of str to float, optional
        The true derivatives (default :data:`NAVION`).
    U : float, optional
        True airspeed, m/s.
    x0 : (float, float), optional
        alpha (rad) and q (rad/s) at the first sample: the record starts off trim.
    noise : float, optional
        White noise on alpha, q and az, as a fraction of each clean channel's RMS.
    rng : numpy.random.Generator, optional
        Needed when ``noise > 0``.
    name : str, optional
        The record's name.

    Returns
    -------
    (Record, dict)
        The record (t s, de rad, alpha rad, q rad/s, az g) and the truth: the derivatives, U,
        the sensors, the manoeuvre, x0, dt, noise and the step edges' sampling offsets
        (:func:`_step_offsets`).
    """
    if noise > 0 and rng is None:
        raise ValueError("noise > 0 needs a seeded numpy Generator (rng)")
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    traj = solve(manoeuvre, t[-1], derivs=derivs, U=U, x0=x0)
    y = measure(traj, t, sensors)
    if noise > 0:
        y = {ch: v + noise * np.sqrt(np.mean(v**2)) * rng.standard_normal(n) for ch, v in y.items()}
    rec = Record(t, {"de": manoeuvre(t), **y}, name=name, meta={"U": U, "source": "tests/independent_truth.py"})
    truth = {
        **dict(derivs),
        "U": U,
        "sensors": {**asdict(sensors), "delays": dict(sensors.delays), "scales": dict(sensors.scales)},
        "manoeuvre": asdict(manoeuvre),
        "x0": tuple(float(v) for v in x0),
        "dt": dt,
        "step_offsets": _step_offsets(manoeuvre, t),
        "noise": noise,
    }
    return rec, truth


def _step_offsets(manoeuvre: Manoeuvre, t: np.ndarray) -> list[float]:
    """Per step edge inside the record: true step time less the middle of the sample interval showing it, s.

    A record shows a step between the last sample before it and the first at or after it.  Read as
    a change in mid-interval (linear or cubic interpolation), the recorded elevator leads the true
    one by this much, so a fit sees an input delay of this size (an advance when negative); at most
    dt/2.  Empty for smooth edges.
    """
    if manoeuvre.edge != "step":
        return []
    times = manoeuvre.edges()[0]
    times = times[(times > t[0]) & (times <= t[-1])]
    first = t[np.searchsorted(t, times, side="left")]  # the first sample at or after each step
    return [float(v) for v in times - (first - 0.5 * (t[1] - t[0]))]
