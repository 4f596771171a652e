"""Validation truths: time-domain records from a base model plus exactly one withheld effect.

Every record comes from fdml's time-domain simulator (:func:`fdml.simulate.simulate`);
the effect is applied in the time domain, where it physically acts:

=========================  ==================================================================
truth                      how it is simulated
=========================  ==================================================================
lift_lag, downwash_lag,    the Wells-Keskar unsteady model with that one lag switched on
gust_lag@alpha_w,          (y_w, G, b1) or the elevator delay tau_de: fdml's simulator
time_delay@de              (finite-state, exact first-order hold)
time_delay@alpha|q|az      the sensor's (or the sensor group's, alpha,az ...) signals delayed,
                           y(t - tau) (cubic interpolation on a grid 16 times finer: a_z and
                           q bend where the elevator does)
downwash_lag@tail          the textbook downwash lag on the steady model: eps(t) = eps_ss
                           alpha(t - tau_dw), a delay-differential equation marched here
                           (first-order hold, dt/8 steps); the library's candidate is a lag
actuator_lag@de            the recorded elevator filtered by 1/(1 + T s) (lsim, first-order
                           hold) drives the simulation, both on a grid 16 times finer; the
                           record keeps the unfiltered one
sensor_offset@az           a_z - x q_dot/g, q_dot from the model's state equations
sensor_offset@alpha        alpha - x q/U
structural_mode@q,az       the modal responses r_q s w/D and r_az s^2/D to the elevator
                           (lsim) added to q and a_z
sensor_scale@ch            (1 + k) times the channel
unmeasured_gust            Dryden turbulence through the gust model; alpha_w not recorded
vane_filter (outside the   alpha through a second-order sensor filter w^2/(s^2 + 2 z w s + w^2)
library)                   on a grid 16 times finer: a vane's own dynamics, which no candidate
                           models
=========================  ==================================================================

Sensor noise (added last): white, or coloured (white plus a first-order
low-pass component whose spectrum at low frequency is 16 times the white
level), with standard deviation a fraction of each clean channel's RMS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import interpolate, signal

from ..channels import OUTPUTS
from ..constants import G0
from ..errors import ParameterError
from ..maneuvers import dryden_gust, make_input, time_vector
from ..models.base import Model
from ..models.effects import get_effect, root_model, with_gust
from ..record import Record, noise_stds
from ..simulate import realize, simulate

__all__ = ["simulate_truth", "truth_model", "sensor_noise", "TRUTHS", "OUT_OF_LIBRARY"]

#: Effects outside the library that the harness can simulate.
OUT_OF_LIBRARY = ("vane_filter",)
#: Low-frequency excess of the coloured sensor noise over its white part (power ratio at omega -> 0).
COLOURED_LF_RATIO = 16.0
#: Corner of the coloured part, rad/s.
COLOURED_CORNER = 0.5
#: Refinement of the grid on which a truth filters a signal that is not linear between samples.
FINE = 16
#: Fade-in/out of a measured gust encounter, s.
GUST_FADE = 2.0
#: Warm-up simulated before a turbulent record (the Dryden filter starts at rest; L/U is about 10 s), s.
WARMUP = 40.0


def truth_model(base, key: str, values: dict):
    """The plain fdml model that is the truth for a free-parameter effect (else the base).

    Parameters
    ----------
    base : Model
        The base model.
    key : str
        Effect key (``"time_delay@q"``).
    values : dict
        Effect parameter values by name, each in its unit.

    Returns
    -------
    Model
        The base model with the effect where it is a plain fdml model, else
        ``base`` (the effect is then simulated in the time domain).
    """
    eff = get_effect(key)
    aug = eff.augment(base).with_values(values)
    if root_model(aug) is aug:
        return aug
    if key not in TRUTHS:
        raise ParameterError(f"no time-domain truth for {key} on the {base.kind} model")
    return base


def _lsim(num, den, u, t):
    _, y, _ = signal.lsim(signal.TransferFunction(num, den), u, t, interp=True)
    return np.asarray(y, float)


def _delay(t, y, tau):
    """y(t - tau) with y = 0 before the start (the record starts from rest, trim removed)."""
    f = interpolate.CubicSpline(t, y)
    ts = t - tau
    out = f(np.clip(ts, t[0], t[-1]))
    out[ts < t[0]] = y[0]
    return out


def _downwash_delay(model, t, inputs, tau: float, sub: int = 8) -> dict:
    """alpha, q, a_z of the steady model whose downwash reaches the tail ``tau`` s late.

    eps(t) = eps_ss alpha(t - tau) instead of eps_ss alpha (docs/theory.md Eq. 9 with a transport delay,
    the textbook origin of Cm_adot).  With d = alpha(t - tau) - alpha(t), the tail lift changes by
    -a_t eps_ss d, so (Eqs. 3-7) alpha' += k_z (St/Sw) a_t eps_ss d, q' += k_m (l St/(c Sw)) a_t
    eps_ss d and a_z += (U/g) k_z (St/Sw) a_t eps_ss d.  Marched on h = dt/sub with an exact
    first-order-hold step for [input, alpha(t - tau)] (the delayed alpha linearly interpolated in
    the stored history; zero before t = 0): second order in h.
    """
    if model.kind != "steady" or model.gust:
        raise ParameterError("the downwash transport-delay truth is defined on the steady model without gust")
    real = realize(model)
    ac, p = model.aircraft, model.parameters.values
    sr = ac.S_t / ac.S_w
    dt = float(t[1] - t[0])
    h = dt / sub
    while h > tau > 0:
        sub *= 2
        h = dt / sub
    b = p["CLa_t"] * p["deps_da"] * np.array([ac.k_z * sr, ac.k_m * p["l_t"] * sr / ac.c_w])
    caz = (ac.U / G0) * ac.k_z * sr * p["CLa_t"] * p["deps_da"]
    A = real.A.copy()
    A[:, 0] -= b  # the -alpha(t) half of d
    Bw = np.column_stack([real.B, b])  # inputs w = [u channels, alpha(t - tau)]
    n, m = A.shape[0], Bw.shape[1]
    from scipy.linalg import expm

    big = np.zeros((n + 2 * m, n + 2 * m))
    big[:n, :n], big[:n, n : n + m], big[n : n + m, n + m :] = A * h, Bw * h, np.eye(m)
    E = expm(big)
    Phi, G1, G2 = E[:n, :n], E[:n, n : n + m], E[:n, n + m :]
    tf = t[0] + h * np.arange((t.size - 1) * sub + 1)
    u = np.column_stack([np.interp(tf - d, t, inputs[nm], left=0.0) for nm, d in real.channels])
    x = np.zeros((tf.size, n))
    ad = np.zeros(tf.size)  # alpha(t - tau) on the fine grid
    k_tau = tau / h
    for k in range(tf.size - 1):
        j = (k + 1) - k_tau  # alpha at t_{k+1} - tau, from the history (j <= k since tau >= h)
        i0 = int(np.floor(j))
        ad[k + 1] = 0.0 if j < 0 else x[i0, 0] + (j - i0) * (x[min(i0 + 1, k), 0] - x[i0, 0])
        w0, w1 = np.append(u[k], ad[k]), np.append(u[k + 1], ad[k + 1])
        x[k + 1] = Phi @ x[k] + G1 @ w0 + G2 @ (w1 - w0)
    ys = real.C @ x.T + real.D @ u.T
    ys[2] += caz * (ad - x[:, 0])
    return {ch: ys[i, ::sub].copy() for i, ch in enumerate(OUTPUTS)}


def _qdot(model, values, t, inputs) -> np.ndarray:
    """q_dot from the model's state equations (finite-state realisation, exact first-order hold)."""
    real = realize(model, values)
    u = np.column_stack([np.interp(t - d, t, inputs[nm], left=0.0) for nm, d in real.channels])
    sys = signal.StateSpace(real.A, real.B, real.C[1:2] @ real.A, real.C[1:2] @ real.B)
    _, y, _ = signal.lsim(sys, u, t, interp=True)
    return np.asarray(y, float).reshape(t.size)


# --- the library's output-level effects in the time domain, independent of their code ---------


@dataclass(frozen=True)
class _Run:
    """One truth simulation: time grid (s), the model, its inputs (rad) and parameter values."""

    t: np.ndarray
    model: Model
    inputs: dict
    values: dict

    def outputs(self, **replaced) -> dict[str, np.ndarray]:
        """alpha, q, a_z from fdml's simulator, with the inputs ``replaced`` (by name)."""
        rec = simulate(self.model, self.t, {**self.inputs, **replaced}, self.values or None)
        return {k: rec[k].copy() for k in OUTPUTS}

    def refined(self) -> _Run:
        """The same run on a grid :data:`FINE` times finer, its inputs (linear between samples) unchanged."""
        t = self.t[0] + (self.t[1] - self.t[0]) / FINE * np.arange((self.t.size - 1) * FINE + 1)
        return replace(self, t=t, inputs={k: np.interp(t, self.t, u) for k, u in self.inputs.items()})


def _on_fine_grid(form):
    """``form`` run on :meth:`_Run.refined`'s grid, its outputs taken at the record's samples.

    For a truth that filters a signal which is not linear between the samples (the lagged elevator, the
    vane's alpha): held linear on the record's own samples, the filtered signal would droop like a
    sampled one, by O((w dt)^2) (0.8 % of the peak q for a 20 ms actuator lag on a 3-2-1-1 at 50 Hz);
    on the finer grid that error is FINE^2 times smaller.  And for a sensor delay: a_z and q bend
    where the elevator does, at the samples, and a cubic spline through the record's samples rings
    there (1.8 % of the peak a_z for a 14 ms delay of a stepped 3-2-1-1); on the finer grid, 2e-6.
    """

    def fine_form(run: _Run, v: dict) -> dict:
        return {k: y[::FINE].copy() for k, y in form(run.refined(), v).items()}

    return fine_form


def _sensor_delay(group: tuple):
    """A sensor group (alpha,az ...) recorded tau late: y(t - tau) on each of its channels."""

    def form(run: _Run, v: dict) -> dict:
        y = run.outputs()
        for ch in group:
            y[ch] = _delay(run.t, y[ch], v["tau_" + "_".join(group)])
        return y

    return form


def _sensor_scale(ch: str):
    """(1 + k) times the channel ``ch``."""

    def form(run: _Run, v: dict) -> dict:
        y = run.outputs()
        y[ch] = (1.0 + v[f"k_{ch}"]) * y[ch]
        return y

    return form


def _actuator_lag(run: _Run, v: dict) -> dict:
    """The recorded elevator filtered by 1/(1 + T s) drives the simulation."""
    return run.outputs(de=_lsim([1.0], [v["T_act"], 1.0], run.inputs["de"], run.t))


def _accelerometer_offset(run: _Run, v: dict) -> dict:
    """a_z - x q_dot/g, q_dot from the model's state equations."""
    y = run.outputs()
    y["az"] = y["az"] - v["x_az"] * _qdot(run.model, run.values or None, run.t, run.inputs) / G0
    return y


def _vane_offset(run: _Run, v: dict) -> dict:
    """alpha - x q/U."""
    y = run.outputs()
    y["alpha"] = y["alpha"] - v["x_alpha"] * y["q"] / run.model.U
    return y


def _structural_mode(run: _Run, v: dict) -> dict:
    """The modal responses r_q s w/D and r_az s^2/D to the elevator added to q and a_z."""
    y = run.outputs()
    w, z = v["omega_s"], v.get("zeta_s", 0.05)
    den = [1.0, 2 * z * w, w * w]
    y["q"] = y["q"] + v["r_q"] * _lsim([w, 0.0], den, run.inputs["de"], run.t)
    y["az"] = y["az"] + v["r_az"] * _lsim([1.0, 0.0, 0.0], den, run.inputs["de"], run.t)
    return y


def _vane_filter(run: _Run, v: dict) -> dict:
    """alpha through a vane's second-order filter w^2/(s^2 + 2 z w s + w^2) (outside the library)."""
    y = run.outputs()
    w, z = v.get("omega_f", 12.0), v.get("zeta_f", 0.3)
    y["alpha"] = _lsim([w * w], [1.0, 2 * z * w, w * w], y["alpha"], run.t)
    return y


#: The time-domain truths of the library's output- and matrix-level effects, by effect key:
#: ``form(run, values) -> {output: samples}`` (the module docstring's table).  Each is written
#: from the physics, independently of the effect's frequency-domain code, on purpose: a truth
#: that shared the candidate's code would confirm the candidate's own mistakes.  An effect that
#: frees a model parameter needs no entry (its truth is the plain model: :func:`truth_model`);
#: a new output-level effect without one cannot be a validation truth.
TRUTHS = {
    **{
        f"time_delay@{','.join(g)}": _on_fine_grid(_sensor_delay(g))
        for g in (("alpha",), ("q",), ("az",), ("alpha", "q"), ("alpha", "az"), ("q", "az"))
    },
    "downwash_lag@tail": lambda run, v: _downwash_delay(run.model, run.t, run.inputs, v["tau_dw"]),
    "actuator_lag@de": _on_fine_grid(_actuator_lag),
    "sensor_offset@az": _on_fine_grid(_accelerometer_offset),  # q_dot holds delayed inputs linear (a base's tau_de)
    "sensor_offset@alpha": _vane_offset,
    "structural_mode@q,az": _structural_mode,
    **{f"sensor_scale@{ch}": _sensor_scale(ch) for ch in OUTPUTS},
    "vane_filter": _on_fine_grid(_vane_filter),
}


def sensor_noise(rng: np.random.Generator, n: int, dt: float, kind: str = "white") -> np.ndarray:
    """Unit-variance-white-part sensor noise of ``n`` samples (white or coloured).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the noise.
    n : int
        Number of samples.
    dt : float
        Sample interval, s.
    kind : {"white", "coloured"}, optional
        White, or white plus an AR(1) part with corner :data:`COLOURED_CORNER`
        rad/s whose low-frequency density is :data:`COLOURED_LF_RATIO` times the white one.

    Returns
    -------
    numpy.ndarray
        Shape (n,), dimensionless (scaled by the caller).
    """
    w = rng.standard_normal(n)
    if kind == "white":
        return w
    if kind != "coloured":
        raise ParameterError(f"noise kind must be 'white' or 'coloured', got {kind!r}")
    a = math.exp(-COLOURED_CORNER * dt)
    e = rng.standard_normal(n) * math.sqrt(1 - a * a)
    e[0] = rng.standard_normal()  # the AR(1) part starts from its stationary distribution
    x = signal.lfilter([1.0], [1.0, -a], e)  # x_i = a x_(i-1) + e_i
    # AR(1) spectrum at low frequency is (1 + a)/(1 - a) times its variance density; scale to the ratio
    c = math.sqrt(COLOURED_LF_RATIO * (1 - a) / (1 + a))
    return w + c * x


def _elevator(maneuver: str, tr: np.ndarray, amp: float, rng: np.random.Generator) -> np.ndarray:
    """The elevator input (rad) of a truth record on its time grid ``tr`` (s)."""
    if maneuver == "multisine":
        # a multisine over the first 3/4 of the record, then the input stops (flight-test practice)
        n1 = int(round(0.75 * (tr.size - 1))) + 1
        u = make_input("multisine", tr[:n1], amp, omega_lo=0.4, omega_hi=12.0, phases="random", rng=rng)
        return np.concatenate([u, np.zeros(tr.size - n1)])
    if maneuver == "3211":
        return make_input("3211", tr, amp, unit=0.4, rise=0.04)
    if maneuver == "doublet":
        return make_input("doublet", tr, amp, width=0.4, rise=0.04)
    raise ParameterError(f"unknown manoeuvre {maneuver!r}; use 3211, doublet or multisine")


def simulate_truth(
    base,
    key: str | None,
    values: dict | None = None,
    *,
    maneuver: str = "3211",
    duration: float = 20.0,
    dt: float = 0.02,
    noise: float = 0.05,
    noise_kind: str = "white",
    seed: int = 0,
    gust_std: float = 0.0,
    amplitude: float | None = None,
    name: str | None = None,
) -> Record:
    """A noisy record of ``base`` plus the effect ``key`` (None: no effect) at ``values``.

    Parameters
    ----------
    base : Model
        The model fitted blind (its values are the truth's base values).
    key : str or None
        Effect key (``"time_delay@q"``), ``"unmeasured_gust"``, an
        out-of-library name (``"vane_filter"``) or None.
    values : dict
        Effect parameter values (e.g. ``{"tau_q": 0.03}``; ``vane_filter``:
        ``{"omega_f": rad/s, "zeta_f": -}``; ``unmeasured_gust``: ``{"sigma_w": m/s}``).
    maneuver : {"3211", "doublet", "multisine"}
        The elevator input.
    duration : float
        Record length, s.
    dt : float
        Sample interval, s.
    noise : float
        Sensor noise standard deviation as a fraction of each clean channel's RMS.
    noise_kind : {"white", "coloured"}
        Kind of sensor noise (:func:`sensor_noise`).
    seed : int
        Seeds the input phases (multisine), the gust and the noise.
    gust_std : float
        Measured Dryden gust (m/s) driving a gust model (``base.gust``).
    amplitude : float, optional
        Elevator amplitude, rad (default 1 deg).
    name : str, optional
        Record name (default ``"<key>-<maneuver>-<seed>"``).

    Returns
    -------
    Record
        The noisy record; ``meta`` holds the truth, its values, the manoeuvre,
        the noise and the seed.
    """
    values = dict(values or {})
    rng = np.random.default_rng(seed)
    gust_key = key == "unmeasured_gust"
    # in turbulence the aircraft is never at rest: simulate a warm-up and keep the last `duration` s
    warm = WARMUP if gust_key else 0.0
    t = time_vector(duration + warm, dt)
    n0 = int(round(warm / dt))
    tr = t[: t.size - n0]  # the kept record's own time axis
    amp = amplitude if amplitude is not None else math.radians(1.0)
    de = np.concatenate([np.zeros(n0), _elevator(maneuver, tr, amp, rng)])
    inputs = {"de": de}
    U = base.U
    if gust_key:
        inputs["alpha_w"] = dryden_gust(t, values["sigma_w"], U, rng=rng, stationary=False)
    elif base.gust:
        # a measured gust encounter: Dryden turbulence faded in and out over GUST_FADE s, so that the
        # gust and the lag states it drives start and end at zero (fdml's boundary terms cover
        # alpha and q only; see the note in the diagnose README section)
        aw = dryden_gust(t, gust_std, U, rng=rng) if gust_std > 0 else np.zeros_like(t)
        inputs["alpha_w"] = aw * signal.windows.tukey(t.size, min(2 * GUST_FADE / t[-1], 1.0))
    model = base
    if gust_key:
        model = with_gust(base)
    elif key is not None and key not in OUT_OF_LIBRARY:
        model = truth_model(base, key, values)
    run = _Run(t, model, inputs, {k: v for k, v in values.items() if k in model.parameters})
    y = TRUTHS[key](run, values) if key in TRUTHS else run.outputs()
    keep = slice(n0, t.size)
    signals = {"de": de[keep], **{k: v[keep] for k, v in y.items()}}
    if base.gust:
        signals["alpha_w"] = inputs["alpha_w"][keep]
    clean = Record(tr, signals, check_units=False)
    stds = noise_stds(clean, noise, relative=True)  # a fraction of each clean channel's RMS
    if any(stds.values()):
        signals.update({ch: clean[ch] + stds[ch] * sensor_noise(rng, tr.size, dt, noise_kind) for ch in OUTPUTS})
    meta = dict(truth=key, values=values, maneuver=maneuver, noise=noise, noise_kind=noise_kind, seed=seed, U=U)
    if "alpha_w" in inputs:
        meta["gust_rms_in_record"] = float(np.std(inputs["alpha_w"][keep]) * U)  # realised sigma_w, m/s
    return Record(tr, signals, name=name or f"{key or 'none'}-{maneuver}-{seed}", meta=meta, check_units=False)
