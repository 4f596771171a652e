"""The data check on corrupted copies of a Navion 3-2-1-1: what it names, how well it measures, what it costs.

Run with ``python benchmarks/bench_datacheck.py``.  Printed:

1. for each corrupted copy (the cases of issue 14), the finding's code, the check's
   estimate of the error (unit factor or slope) against the truth, and the
   estimate the plain fit gives of Cm_de (true -1.42, WK Table 1) without the check;
2. the cost of the check per record: best of 20 runs, as a ratio against one
   ``fdml.fit`` of the steady model on the same record (measured in the same run),
   and against the target of 5 ms; and a fit with the check against one without
   (inside a fit the check reuses the fit's spectra); for records of 12 s at 50 Hz
   and 120 s at 100 Hz.
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

warnings.simplefilter("ignore")

import fdml  # noqa: E402
from fdml.constants import G0  # noqa: E402
from fdml.datacheck import DEG, check_data  # noqa: E402
from fdml.record import Record, add_noise  # noqa: E402
from fdml.simulate import simulate_maneuver  # noqa: E402

TRUTH = fdml.make_model("unsteady", "navion")
U = TRUTH.U


def corrupted(rec: Record) -> dict:
    s = rec.signals
    rng = np.random.default_rng(2)

    def mod(**ch):
        return Record(rec.t, {**s, **ch}, name="x", check_units=False)

    return {
        "clean": (mod(), None, None),
        "elevator in degrees": (mod(de=s["de"] * DEG), "units.elevator", None),
        "alpha in degrees": (mod(alpha=s["alpha"] * DEG), "units.alpha", DEG),
        "q in deg/s": (mod(q=s["q"] * DEG), "units.q", DEG),
        "a_z in m/s^2": (mod(az=s["az"] * G0), "units.az", G0),
        "a_z sign flipped": (mod(az=-s["az"]), "sign.az", -G0 / U),
        "q sign flipped": (mod(q=-s["q"]), "sign.q", -1.0),
        "alpha and q swapped": (mod(alpha=s["q"], q=s["alpha"]), "channels.swapped", None),
        "q and a_z swapped": (mod(q=s["az"], az=s["q"]), "channels.swapped", None),
        "outputs white noise": (
            mod(**{k: rng.normal(size=rec.n) * s[k].std() for k in ("alpha", "q", "az")}),
            "response.alpha",
            None,
        ),
    }


def best_of(fn, n):
    best = math.inf
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    rec = simulate_maneuver(TRUTH, "3211", duration=12.0, dt=0.02, amplitude=math.radians(1.0))
    rec = add_noise(rec, 0.02, np.random.default_rng(1), relative=True)
    steady = fdml.make_model("steady", "navion")
    print("1. corrupted copies of a Navion 3-2-1-1 (1 deg, 12 s, 50 Hz, 2 % noise), U known")
    print(f"{'copy':22s} {'codes found':40s} {'estimate':>10s} {'truth':>10s} {'error %':>8s} {'Cm_de fit':>10s}")
    for label, (r, code, truth) in corrupted(rec).items():
        dc = check_data(r, airspeed=U)
        f = next((f for f in dc.findings if f.code == code), None)
        est = "" if f is None or f.value is None or truth is None else f"{f.value:.5g}"
        err = "" if not est else f"{100 * (f.value / truth - 1):+.2f}"
        cm = fdml.fit(r, steady, check=False).params["Cm_de"]
        print(
            f"{label:22s} {' '.join(dc.codes) or '-':40s} {est:>10s} "
            f"{'' if truth is None else f'{truth:.5g}':>10s} {err:>8s} {cm:10.4f}"
        )
        assert (code is None and not dc.codes) or code in dc.codes
    print("\n2. cost per record (best of 20), against one steady fit of the same record")
    for dur, dt in ((12.0, 0.02), (120.0, 0.01)):
        r = add_noise(
            simulate_maneuver(TRUTH, "3211", duration=dur, dt=dt, amplitude=math.radians(1.0)),
            0.02,
            np.random.default_rng(1),
            relative=True,
        )
        t_check = best_of(lambda: check_data(r, airspeed=U), 20)
        t_fit = best_of(lambda: fdml.fit(r, steady, check=False), 5)
        t_fit_checked = best_of(lambda: fdml.fit(r, steady), 5)
        print(
            f"  {dur:5.0f} s at {1 / dt:3.0f} Hz: check alone {1e3 * t_check:6.2f} ms = {t_check / t_fit:.3f} of a "
            f"fit ({1e3 * t_fit:.0f} ms), {t_check / 5e-3:.2f} of the 5 ms target; inside the fit (spectra "
            f"shared) the fit takes {t_fit_checked / t_fit:.3f} times as long"
        )


if __name__ == "__main__":
    main()
