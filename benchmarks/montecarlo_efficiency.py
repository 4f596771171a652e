"""Efficiency of the frequency-domain ML estimator: Monte Carlo scatter against the reported CRB.

For the ``steady`` and ``unsteady`` models of the Navion preset the script
simulates a 3-2-1-1 manoeuvre (10 s at 50 Hz), adds white noise of 3 % of
each output's RMS with N independent seeds (run i: SeedSequence(seed).spawn(N)[i]),
fits the model that generated the data (started at the truth) on the local
process pool, and prints per parameter: truth, mean, bias, scatter, mean
reported standard error (CRB), scatter/CRB and bias in its own standard
errors, with the wall time of each study and the commit measured.

    python benchmarks/montecarlo_efficiency.py [-n 1000] [--workers 2] [--models steady unsteady]
                                               [--duration 10] [--noise 0.03] [--seed 0] [-o DIR]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import time
from pathlib import Path


def commit() -> str:
    here = Path(__file__).resolve().parent
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], cwd=here, capture_output=True, text=True
        ).stdout.strip()
        return rev + (" (working tree has uncommitted changes)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--models", nargs="+", default=["steady", "unsteady"])
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--noise", type=float, default=0.03)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("-o", "--out", help="save each study as DIR/montecarlo_MODEL.json")
    args = ap.parse_args()

    from fdml.montecarlo import monte_carlo

    print(
        f"fdml Monte Carlo efficiency, commit {commit()}, {platform.python_version()}, "
        f"{args.workers} workers on {os.cpu_count()} cores"
    )
    total = time.perf_counter()
    for kind in args.models:
        res = monte_carlo(
            {"kind": kind, "aircraft": "navion"},
            n=args.n,
            maneuver="3211",
            duration=args.duration,
            dt=0.02,
            noise=args.noise,
            seed=args.seed,
            workers=args.workers,
        )
        print()
        print(res.table())
        fit_s = res.fit_seconds[res.used]
        print(
            f"fits: median {1e3 * float(sorted(fit_s)[len(fit_s) // 2]):.1f} ms in-process, "
            f"{res.iterations[res.used].mean():.1f} iterations on average; "
            f"wall {res.wall_time:.1f} s for {res.n} runs ({res.n / res.wall_time:.1f} fits/s)"
        )
        if args.out:
            Path(args.out).mkdir(parents=True, exist_ok=True)
            res.to_json(Path(args.out) / f"montecarlo_{kind}.json")
    print(f"\ntotal wall time {time.perf_counter() - total:.1f} s")


if __name__ == "__main__":
    main()
