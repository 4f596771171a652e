"""False-alarm rate of the adequacy check (fdml.adequacy) on records from the fitted model.

Run with ``python benchmarks/adequacy_false_alarms.py [N] [--processes P]``
(default N = 500).  The model is the Twin Otter 017 plain fit (dimensional,
the record's airspeed, 0.1-1.5 Hz) when the data are there, else the Navion
``derivatives`` model.  Each record is simulated by the *time-domain*
simulator (:func:`fdml.simulate.simulate_maneuver`) from that model, varying
what a real record varies (:func:`null_record`): the manoeuvre (3-2-1-1,
doublet, multisine), the sample rate (50, 100 or 40 Hz), the edges (the
record starts 0-1.6 s into the simulation, i.e. often during the input and
off trim, and lasts 8-14 s), the trim values (constant offsets on every
channel), the noise level, the seed and, in half of the records, an elevator
delay of 0-40 ms (mostly a fraction of a sample; the model is fitted with it
fixed, as a known actuator delay would be).  Each is fitted with the same model
and band (``fdml.fit``, default adequacy check at ``ALPHA``); a false alarm
is a fit that flags anything (an effect or a residual check).

Reports the rate with its exact (Clopper-Pearson) 95 % interval, and which
tests flagged.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from collections import Counter

import numpy as np
from scipy import stats

import fdml
from fdml.adequacy import ALPHA
from fdml.io import data_path, load_record
from fdml.simulate import simulate_maneuver

HZ = 2 * math.pi
BAND = (0.1 * HZ, 1.5 * HZ, 0.02 * HZ)  # the Twin Otter band, 0.1-1.5 Hz at 0.02 Hz
MANEUVERS = ("3211", "doublet", "multisine")
RATES = (0.02, 0.01, 0.025)  # s: 50, 100 and 40 Hz
#: Noise standard deviations (alpha rad, q rad/s, az g) at scale 1: about the Twin Otter 017 residual levels.
NOISE = {"alpha": 0.0015, "q": 0.003, "az": 0.01}


def truth_model():
    """The model records are simulated from: the Twin Otter 017 plain fit, or Navion derivatives."""
    try:
        rec = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
    except (fdml.FdmlError, OSError):
        return fdml.make_model("derivatives", "navion"), (0.1, 10.0, 0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fdml.fit(rec, fdml.make_model("dimensional", airspeed=float(rec.meta["U"])), band=BAND, adequacy=False)
    return res.model, BAND


def delayed(model, seed: int):
    """``model`` with the elevator delay of record ``seed``: 0-40 ms in half of the records, else none."""
    rng = np.random.default_rng([seed, 1])  # its own stream: the other draws of a record stay as they were
    return model.with_values(tau_de=float(rng.uniform(0.0, 0.04)) if rng.uniform() < 0.5 else 0.0)


def null_record(model, seed: int):
    """One time-domain record from ``model`` with a random manoeuvre, rate, edges, trim and noise."""
    rng = np.random.default_rng(seed)
    man = MANEUVERS[seed % len(MANEUVERS)]
    dt = RATES[(seed // len(MANEUVERS)) % len(RATES)]
    start = float(rng.uniform(0.0, 1.6))  # the record starts here: before, at or during the input (off trim)
    length = float(rng.uniform(8.0, 14.0))
    kw = {"start": 1.0} if man != "multisine" else {"omega_lo": 0.5, "omega_hi": 12.0}
    scale = float(rng.uniform(0.5, 2.0))
    noise = {k: v * scale for k, v in NOISE.items()}
    amp = float(rng.uniform(0.6, 1.5)) * math.radians(2.0)
    sim = simulate_maneuver(
        model,
        man,
        duration=start + length + 0.5,
        dt=dt,
        amplitude=amp,
        noise=noise,
        seed=int(rng.integers(2**31)),
        **kw,
    )
    rec = sim.window(sim.t[0] + start, sim.t[0] + start + length)
    trim = {
        "alpha": rng.uniform(0.0, 0.08),
        "q": rng.normal(0.0, 0.002),
        "az": rng.normal(-1.0, 0.02),
        "de": rng.normal(-0.02, 0.01),
    }
    return rec.with_signals(**{k: rec[k] + v for k, v in trim.items() if rec.has(k)})


def one(args):
    """(flagged keys, fit time, adequacy time) of null record ``seed``."""
    model, band, seed = args
    model = delayed(model, seed)
    rec = null_record(model, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fdml.fit(rec, model, band=band)
    a = res.adequacy
    if a is None:  # not converged: no check ran (counted separately)
        return None, res.elapsed, 0.0
    flags = [e.key for e in a.flagged] + [c.name for c in a.residual_flags]
    return flags, res.elapsed, a.elapsed


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial confidence interval for k successes in n trials."""
    a = 1.0 - level
    lo = 0.0 if k == 0 else float(stats.beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(stats.beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def run(n: int, processes: int = 1, seed0: int = 0):
    model, band = truth_model()
    jobs = [(model, band, seed0 + i) for i in range(n)]
    t0 = time.perf_counter()
    if processes > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(processes) as ex:
            out = list(ex.map(one, jobs, chunksize=8))
    else:
        out = [one(j) for j in jobs]
    checked = [o for o in out if o[0] is not None]
    alarms = [o for o in checked if o[0]]
    k, m = len(alarms), len(checked)
    lo, hi = clopper_pearson(k, m)
    which = Counter(key for o in alarms for key in o[0])
    ratio = np.array([o[2] / o[1] for o in checked if o[1] > 0])
    print(f"model: {model.describe()}; band {band[0]:.3g}-{band[1]:.3g} rad/s step {band[2]:.3g}")
    print(f"{n} records ({n - m} fits not converged, not checked), {time.perf_counter() - t0:.0f} s")
    print(
        f"false alarms: {k}/{m} = {k / max(m, 1):.4f}, 95 % CI [{lo:.4f}, {hi:.4f}] at the stated family level {ALPHA}"
    )
    print("flagged:", dict(which) if which else "nothing")
    print(f"adequacy / fit time: median {np.median(ratio):.2f}, 90 % {np.quantile(ratio, 0.9):.2f}")
    return k, m


if __name__ == "__main__":
    argv = sys.argv[1:]
    procs = 1
    if "--processes" in argv:
        i = argv.index("--processes")
        procs = int(argv[i + 1])
        del argv[i : i + 2]
    run(int(argv[0]) if argv else 500, procs)
