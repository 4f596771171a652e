"""Cost of the adequacy check (fdml.adequacy) relative to the fit it checks.

Run with ``python benchmarks/bench_adequacy.py [REPEATS]`` (default 7).  Two
cases: a 12 s, 50 Hz 3-2-1-1 record of the Navion ``derivatives`` model over
the default band 0.1:10:0.1 rad/s, and the Twin Otter 017 record (dimensional
model, 0.1-1.5 Hz at 0.02 Hz; skipped without the data).  For each, the
median over REPEATS of the fit time (``FitResult.elapsed``: the estimator,
without the check) and of the check's time (``Adequacy.elapsed``), and their
ratio; issue 8 allows at most 1 (the check may cost as much again as the fit).
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np

import fdml
from fdml.io import data_path, load_record
from fdml.simulate import simulate_maneuver

warnings.simplefilter("ignore")
HZ = 2 * math.pi


def cases():
    nav = fdml.make_model("derivatives", "navion")
    rec = simulate_maneuver(nav, "3211", duration=12.0, dt=0.02, noise={"alpha": 1e-3, "q": 2e-3, "az": 5e-3},
                            seed=1)
    out = {"12 s Navion 3-2-1-1, 0.1:10:0.1": (rec, nav, (0.1, 10.0, 0.1))}
    try:
        to = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
        out["Twin Otter 017, 0.1-1.5 Hz"] = (to, fdml.make_model("dimensional", airspeed=float(to.meta["U"])),
                                             (0.1 * HZ, 1.5 * HZ, 0.02 * HZ))
    except (fdml.FdmlError, OSError) as exc:
        print(f"Twin Otter skipped: {exc}")
    return out


def measure(rec, model, band, repeats: int):
    fdml.fit(rec, model, band=band)  # warm-up: imports, caches
    t_fit, t_adq = [], []
    for _ in range(repeats):
        res = fdml.fit(rec, model, band=band)
        t_fit.append(res.elapsed)
        t_adq.append(res.adequacy.elapsed)
    return float(np.median(t_fit)), float(np.median(t_adq)), res.adequacy


def main(repeats: int = 7):
    print("| case | fit, ms | adequacy, ms | ratio | flagged |")
    print("|---|---|---|---|---|")
    for name, (rec, model, band) in cases().items():
        tf, ta, a = measure(rec, model, band, repeats)
        flagged = ", ".join(e.key for e in a.flagged) or "nothing"
        print(f"| {name} | {tf * 1e3:.0f} | {ta * 1e3:.0f} | {ta / tf:.2f} | {flagged} |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 7)
