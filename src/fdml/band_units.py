"""Does a fit's band look like Hz?  The ``band.hz`` finding, with the band in rad/s.

fdml's bands are in rad/s.  A band typed in Hz (``--band 0.1:1.5:0.02`` for
0.1-1.5 Hz) is 2 pi times too low in every number: it usually lies below the
short period it is meant to cover, and its step is far finer than the record's
frequency resolution 2 pi/T.  A fit on it runs to its iteration limit and returns
nonsense.  After the fit, :func:`hz_band_finding` says so and gives the band in
rad/s.

It is a finding (a warning), not an error: neither sign proves a unit slip (a
band below the short period or a fine grid can be chosen on purpose), and the
fit, good or bad, is kept.  The default band is never flagged: only a typed band
can be typed in Hz.
"""

from __future__ import annotations

import math

from .findings import Finding

__all__ = ["HZ_STEP_FACTOR", "hz_band_finding"]

#: A band step this many times finer than the record's resolution 2 pi/T looks like Hz: finer
#: frequencies add no information (the estimator's bounds account for their correlation), and a
#: Hz step read as rad/s is 2 pi times finer than the rad/s one meant.  The default step 0.1 rad/s
#: stays within this factor on records of 3 s and longer.
HZ_STEP_FACTOR = 20.0


def hz_band_finding(data, model) -> Finding | None:
    """A ``band.hz`` finding when the fit's band looks like Hz, else None.

    Parameters
    ----------
    data : sequence of FrequencyData
        The fit's spectra; their ``band`` (lo, hi, step), rad/s, ``T`` (s) and ``dt`` (s).
    model : Model
        The model at the estimate; its short-period frequency (rad/s) is compared with the band.

    Returns
    -------
    Finding or None
        Kind ``"estimation"``; ``value`` the band's top and ``expected`` the short-period
        frequency, rad/s.  None for the default band, a band of explicit frequencies, or a
        band whose rad/s reading would reach the Nyquist frequency pi/dt.
    """
    from .spectral import DEFAULT_BAND

    bands = {tuple(d.band) for d in data if d.band is not None}
    if len(bands) != 1 or bands == {tuple(DEFAULT_BAND)}:
        return None
    lo, hi, step = bands.pop()
    resolution = 2 * math.pi / max(d.T for d in data)
    w_sp = model.short_period_frequency()
    reasons = []
    if math.isfinite(w_sp) and hi < w_sp:
        reasons.append(f"it lies below the fitted short-period frequency {w_sp:.3g} rad/s")
    if step * HZ_STEP_FACTOR < resolution:
        reasons.append(
            f"its step is {resolution / step:.0f} times finer than the record's resolution "
            f"2 pi/T = {resolution:.3g} rad/s"
        )
    if not reasons or 2 * math.pi * hi >= math.pi / max(d.dt for d in data):
        return None
    rad = [f"{2 * math.pi * x:.4g}" for x in (lo, hi, step)]
    return Finding(
        "band.hz",
        f"the band {lo:g}:{hi:g}:{step:g} rad/s looks like Hz: {' and '.join(reasons)}; in rad/s it is "
        f"--band {':'.join(rad)} (Python: band=({', '.join(rad)}))",
        kind="estimation",
        value=float(hi),
        expected=float(w_sp),
    )
