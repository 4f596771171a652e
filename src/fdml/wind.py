r"""Wind and the vertical gust angle from inertial and air data (Braunschweig Eq. 13).

The wind cannot be measured directly from an aircraft; it is the difference
between the inertial (ground-relative) velocity V_k and the air-relative
velocity V ([BS] Eq. 13)::

    V_w = V_k - V

In the longitudinal plane, wings level, with theta the pitch attitude,
alpha the air-data angle of attack and V the true airspeed, the air-relative
velocity has the flight-path angle gamma_a = theta - alpha::

    V   = V  [cos(gamma_a), sin(gamma_a)]          (forward, up)
    V_k = [x_dot, h_dot]                            (inertial)

so the vertical wind (positive up) and the inertial flight-path angle are::

    w_w     = h_dot - V sin(theta - alpha)
    gamma_k = atan2(h_dot, V cos(gamma_a) + u_w)    (u_w: along-track horizontal wind)

The inertial ("kinematic") angle of attack is alpha_k = theta - gamma_k and
the vertical gust angle, positive for an up-gust (it raises the angle of
attack, docs/theory.md section 8's alpha_g = w_g/U)::

    alpha_w = alpha - alpha_k = gamma_k - gamma_a  ~  w_w / V

**Channels needed** (all in the record, SI): ``alpha`` (air data, rad),
``V`` (true airspeed, m/s), ``theta`` (rad), and an inertial vertical speed:
``hdot`` (m/s, positive up, from an INS or GPS) -- or, as a weaker
substitute, an altitude ``h`` (m) differentiated here (a barometric
altitude is quantised, lags, and is not inertial, so the result only holds
at low frequencies and carries the differentiation noise; the estimate
says so).  The along-track horizontal wind u_w needs the inertial ground
speed and track, which fdml records do not carry: it is an argument
(default 0); its effect on alpha_w is of order gamma u_w / V, negligible in
level flight.

Corrections to alpha (noseboom position, upwash, vane lag) must be applied
first, e.g. with :func:`fdml.flightpath.check_compatibility` (``correct=True``):
any alpha error appears one-for-one in alpha_w.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import FdmlError, RecordError
from .jsoncodec import SKIP, Codec, floats, text, texts
from .record import Record

__all__ = ["gust_angle", "GustEstimate", "DEFAULT_SMOOTH"]

#: -3 dB frequency of a quadratic Savitzky-Golay differentiator of N points,
#: relative to an ideal one, as a fraction of fs / N (computed from its
#: coefficients: 0.583, 0.579, 0.578 for N = 11, 25, 51).
SG_CUTOFF = 0.58
#: Default Savitzky-Golay window for differentiating altitude, s: 0.4 s puts
#: the differentiator's -3 dB point at 0.58/0.4 = 1.45 Hz, the top of the
#: short-period band of the records here (0.1-1.5 Hz); a longer window
#: lowers the noise (its white-noise gain falls as N^-3/2) and the bandwidth.
DEFAULT_SMOOTH = 0.4


@dataclass(frozen=True)
class GustEstimate(Codec):
    """The vertical wind and gust angle along a record.

    Parameters
    ----------
    t : ndarray
        Time, s.
    alpha_w : ndarray
        Vertical gust angle, rad (positive up-gust).
    w_wind : ndarray
        Vertical wind, m/s, positive up.
    gamma_k, gamma_a : ndarray
        Inertial and air-relative flight-path angles, rad.
    source : str
        ``"hdot"`` (an inertial vertical speed) or ``"altitude"`` (h differentiated).
    channels : tuple of str
        Channels used.
    cutoff_hz : float or None
        For ``"altitude"``: the -3 dB frequency of the differentiator, Hz.
    hdot_noise : float
        Standard deviation of the vertical-speed noise (estimated), m/s;
        divided by V it is the noise floor of alpha_w in rad.
    notes : tuple of str
        What the estimate can and cannot be trusted for.
    _record : Record or None
        The record the estimate was made from (internal: for :attr:`record`).
    """

    t: np.ndarray
    alpha_w: np.ndarray
    w_wind: np.ndarray
    gamma_k: np.ndarray
    gamma_a: np.ndarray
    source: str
    channels: tuple
    cutoff_hz: float | None
    hdot_noise: float
    notes: tuple = ()
    _record: Record | None = field(default=None, repr=False, compare=False)

    json_fields = {
        "t": floats(None),
        **{k: floats("t") for k in ("alpha_w", "w_wind", "gamma_k", "gamma_a")},
        "source": text(("hdot", "altitude")),
        "channels": texts(),
        "notes": texts(),
        "_record": SKIP,  # the input record is not written: :attr:`record` of an estimate read back refuses
    }
    json_source = "gust estimate"

    @property
    def record(self) -> Record:
        """The input record with ``alpha_w`` added (meta ``gust`` says how it was made)."""
        r = self._record
        if r is None:  # gust_angle always keeps its record; from_dict cannot
            raise FdmlError("this gust estimate was read back from its dict, which does not keep the record")
        return replace(
            r,
            signals={**r.signals, "alpha_w": self.alpha_w},
            meta={
                **r.meta,
                "gust": {
                    "source": self.source,
                    "channels": list(self.channels),
                    "cutoff_hz": self.cutoff_hz,
                    "hdot_noise": self.hdot_noise,
                },
            },
        )

    def summary(self) -> str:
        """A few lines: source channels, gust angle and wind statistics, noise level.

        Returns
        -------
        str
            The lines, angles in degrees.
        """
        lines = [
            f"Vertical gust angle from {self.source} ({', '.join(self.channels)})",
            f"  alpha_w: mean {math.degrees(np.mean(self.alpha_w)):.3g} deg, RMS about the mean "
            f"{math.degrees(np.std(self.alpha_w)):.3g} deg; vertical wind RMS {np.std(self.w_wind):.3g} m/s",
            f"  vertical-speed noise about {self.hdot_noise:.3g} m/s"
            + (f"; differentiator -3 dB at {self.cutoff_hz:.3g} Hz" if self.cutoff_hz else ""),
        ]
        lines += [f"  - {n}" for n in self.notes]
        return "\n".join(lines)


def gust_angle(
    record: Record, *, source: str = "auto", smooth: float = DEFAULT_SMOOTH, horizontal_wind: float = 0.0
) -> GustEstimate:
    """Derive the vertical wind and the gust angle alpha_w from inertial and air data.

    Parameters
    ----------
    record : Record
        Needs ``alpha``, ``V``, ``theta`` and either ``hdot`` (inertial
        vertical speed, m/s, positive up) or ``h`` (altitude, m); see the
        module docstring.
    source : {"auto", "hdot", "altitude"}
        ``auto``: ``hdot`` if the record has it, else the altitude.
    smooth : float, optional
        Savitzky-Golay window for differentiating the altitude, s (default
        0.4 s, :data:`DEFAULT_SMOOTH`; ignored for ``hdot``).
    horizontal_wind : float, optional
        Along-track horizontal wind u_w, m/s (tailwind positive), if known.

    Returns
    -------
    GustEstimate
        ``.alpha_w`` (rad) and ``.record`` (the record with ``alpha_w``).

    Raises
    ------
    RecordError
        Naming the channels the record lacks.
    """
    if not isinstance(record, Record):
        raise RecordError(f"expected an fdml Record, got {type(record).__name__}")
    if source not in ("auto", "hdot", "altitude"):
        raise RecordError(f"unknown gust source {source!r}; use 'auto', 'hdot' or 'altitude'")
    need = [k for k in ("alpha", "V", "theta") if not record.has(k)]
    if source == "auto":
        source = "hdot" if record.has("hdot") else "altitude"
    vert = "hdot" if source == "hdot" else "h"
    if not record.has(vert):
        need.append(vert if source == "hdot" else "h (or hdot)")
    if need:
        raise RecordError(
            f"record {record.name!r} lacks {', '.join(need)} for the gust angle: it needs air-data alpha and "
            "true airspeed V, pitch attitude theta, and an inertial vertical speed hdot (or an altitude h to "
            f"differentiate); it has {', '.join(record.signals)}"
        )
    alpha, V, theta = record["alpha"], record["V"], record["theta"]
    if np.any(V <= 0):
        raise RecordError(f"record {record.name!r}: airspeed V must be positive")
    from .flightpath import noise_level

    notes = []
    dt = record.dt
    cutoff = None
    if source == "hdot":
        hdot = record["hdot"]
        noise = noise_level(hdot)
    else:
        from scipy.signal import savgol_coeffs, savgol_filter

        n_win = min(max(5, int(round(smooth / dt)) | 1), record.n if record.n % 2 else record.n - 1)
        hdot = savgol_filter(record["h"], n_win, 2, deriv=1, delta=dt, mode="interp")
        cutoff = SG_CUTOFF * (1.0 / dt) / n_win
        # white noise on h through the differentiator: root sum of squared weights
        noise = noise_level(record["h"]) * float(np.sqrt(np.sum(savgol_coeffs(n_win, 2, deriv=1, delta=dt) ** 2)))
        notes.append(
            f"vertical speed differentiated from the altitude over {n_win * dt:.3g} s windows: alpha_w "
            f"is valid only below about {cutoff:.2g} Hz, and a barometric altitude is not inertial "
            "(static-pressure lag and position error enter alpha_w)"
        )
    gamma_a = theta - alpha
    w_wind = hdot - V * np.sin(gamma_a)
    gamma_k = np.arctan2(hdot, V * np.cos(gamma_a) + horizontal_wind)
    alpha_w = gamma_k - gamma_a
    notes += [
        f"noise floor of alpha_w about {math.degrees(noise / float(np.mean(V))):.2g} deg (vertical-speed noise "
        f"{noise:.2g} m/s over V = {np.mean(V):.4g} m/s)",
        "any error of alpha (bias, scale, lag, upwash) appears one-for-one in alpha_w: correct alpha "
        "first (fdml.flightpath)",
    ]
    if horizontal_wind == 0.0:
        notes.append(
            "along-track horizontal wind taken as 0 (no ground speed in the record): error of order gamma u_w / V"
        )
    return GustEstimate(
        t=record.t.copy(),
        alpha_w=alpha_w,
        w_wind=w_wind,
        gamma_k=gamma_k,
        gamma_a=gamma_a,
        source=source,
        channels=("alpha", "V", "theta", vert),
        cutoff_hz=cutoff,
        hdot_noise=float(noise),
        notes=tuple(notes),
        _record=record,
    )
