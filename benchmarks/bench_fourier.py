"""Time fdml.fourier.finite_fourier_transform: chirp-z vs direct vs a Python loop.

Run with ``python benchmarks/bench_fourier.py``.  For each case, the cubic
end-corrected transform of a random record is timed (best of several runs) with
method="czt", method="direct", and a straightforward reference that loops over
frequencies in Python (one exp and one dot product per frequency).  Ratios are
reference time / method time (larger is faster), and the largest difference
from the reference, relative to max|X|, is printed as a cross-check.
"""

from __future__ import annotations

import time

import numpy as np

from fdml.fourier import _end_weights, finite_fourier_transform

CASES = [(375, 100), (3000, 100), (30000, 1000)]  # (samples, frequencies)
DT = 0.02  # s (50 Hz)


def loop_reference(x, dt, omega):
    """Per-frequency loop: X(w) = dt [W S + a.x_head + exp(-j w T) conj(a).x_tail]."""
    n = x.size
    j = np.arange(n)
    out = np.empty(omega.size, dtype=complex)
    for i, w in enumerate(omega):
        theta = w * dt
        weight, alpha = _end_weights(np.array([theta]), "cubic")
        interior = np.dot(np.exp(-1j * theta * j), x)
        ends = alpha[0] @ x[:4] + np.exp(-1j * theta * (n - 1)) * (alpha[0].conj() @ x[::-1][:4])
        out[i] = dt * (weight[0] * interior + ends)
    return out


def best_time(func, budget=1.0, max_runs=20):
    """Best wall time of up to max_runs calls, stopping after about budget seconds."""
    best, spent, runs = np.inf, 0.0, 0
    while runs < max_runs and (runs < 2 or spent < budget):
        start = time.perf_counter()
        result = func()
        elapsed = time.perf_counter() - start
        best, spent, runs = min(best, elapsed), spent + elapsed, runs + 1
    return best, result


def main():
    rng = np.random.default_rng(0)
    header = (
        f"{'n':>7} {'m':>6} | {'loop ms':>9} {'direct ms':>10} {'czt ms':>8} | "
        f"{'loop/direct':>11} {'loop/czt':>9} | {'max rel diff':>12}"
    )
    print(header)
    print("-" * len(header))
    for n, m in CASES:
        x = rng.standard_normal(n)
        omega = np.linspace(0.1, 10.0, m)  # rad/s, evenly spaced
        t_loop, ref = best_time(lambda: loop_reference(x, DT, omega))
        t_direct, x_direct = best_time(lambda: finite_fourier_transform(x, DT, omega, method="direct"))
        t_czt, x_czt = best_time(lambda: finite_fourier_transform(x, DT, omega, method="czt"))
        scale = np.max(np.abs(ref))
        diff = max(np.max(np.abs(x_direct - ref)), np.max(np.abs(x_czt - ref))) / scale
        print(
            f"{n:7d} {m:6d} | {1e3 * t_loop:9.3f} {1e3 * t_direct:10.3f} {1e3 * t_czt:8.3f} | "
            f"{t_loop / t_direct:11.1f} {t_loop / t_czt:9.1f} | {diff:12.1e}"
        )


if __name__ == "__main__":
    main()
