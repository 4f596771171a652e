"""Speed of ``fdml.diagnose``, as a ratio against one plain ``fdml.fit`` of the same record in the same run.

Run with ``python benchmarks/bench_diagnose.py [--reps N] [--profile]``.  The case is issue 8's: a 12 s,
50 Hz record simulated in the time domain (``fdml.diagnose.truth.simulate_truth``, navion, steady base
model, 3-2-1-1, 3 % white sensor noise) diagnosed over 0.2-12 rad/s (fdml fit: the same band at
0.1 rad/s).  Two truths: no effect (the null) and a 30 ms pitch-rate delay.  Every time is the best of
``--reps`` in-process repetitions (wall clock), so load from other processes inflates it as little as
possible.  ``--profile`` prints the cProfile top 25 of one diagnosis.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

warnings.simplefilter("ignore")

import fdml
from fdml.diagnose import diagnose
from fdml.diagnose.truth import simulate_truth

BAND = (0.2, 12.0)
FIT_BAND = (0.2, 12.0, 0.1)
CASES = {"no effect": (None, {}), "30 ms q delay": ("time_delay@q", {"tau_q": 0.03})}


def best(f, reps):
    """(best wall-clock time, best CPU time of this process, the last result) over ``reps`` runs."""
    wall, cpu = [], []
    for _ in range(reps):
        t0, c0 = time.perf_counter(), time.process_time()
        r = f()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu), r


def record(key, values, seed=1):
    base = fdml.make_model("steady", "navion")
    return base, simulate_truth(base, key, values, maneuver="3211", duration=12.0, dt=0.02, noise=0.03, seed=seed)


def main(argv=None) -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--reps", type=int, default=3)
    p.add_argument("--profile", action="store_true")
    a = p.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; best of {a.reps}, wall (CPU) s")
    print(f"{'case':16s} {'fit':>14s} {'diagnose':>14s} {'ratio':>7s}  verdict")
    for label, (key, vals) in CASES.items():
        base, rec = record(key, vals)
        t_fit, c_fit, _ = best(lambda rec=rec, base=base: fdml.fit(rec, base, band=FIT_BAND), a.reps)
        t_diag, c_diag, rep = best(lambda rec=rec, base=base: diagnose(rec, base, band=BAND), a.reps)
        print(
            f"{label:16s} {t_fit:6.3f} ({c_fit:5.3f}) {t_diag:6.3f} ({c_diag:5.3f}) {t_diag / t_fit:7.1f}  "
            f"{rep.verdict}"
        )
    if a.profile:
        import cProfile
        import pstats

        base, rec = record(*CASES["30 ms q delay"])
        pr = cProfile.Profile()
        pr.enable()
        diagnose(rec, base, band=BAND)
        pr.disable()
        pstats.Stats(pr).sort_stats("cumulative").print_stats(25)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
