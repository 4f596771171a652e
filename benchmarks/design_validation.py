"""Predicted standard errors (fdml.design.prediction) against Monte Carlo with the time-domain simulator + fdml.fit.

Part 1: Navion (THEORY.md section 10), steady and unsteady models, 3-2-1-1 and
minimum-crest multisine (12 s, 50 Hz, 1 deg, band 0.5:10 rad/s), noise 5 % of
each output's RMS: the ratio Monte-Carlo std / predicted stderr per parameter.
With N trials an estimated std scatters by about 1/sqrt(2 (N - 1)) (chi with
N - 1 degrees of freedom), 5 % at N = 200: ratios within 0.9..1.1 confirm the
prediction to 10 %.

Part 2: the gain of a designed input (Sundowner, D-optimal, 20 s, 3 deg, band
0.5:15, as ``fdml design``) over a 3-2-1-1 and a linear sweep of the same
duration and peak: predicted stderr ratios against Monte-Carlo ratios (every
input with the same sensor noise, stds from the 3-2-1-1 response).

Part 3: speed: one prediction against one fit of the same record (ratio).

Run: ``python benchmarks/design_validation.py [N] [PARTS]`` (default N = 200, parts 3,1,2;
several minutes).
"""

from __future__ import annotations

import math
import sys
import time
import warnings

import numpy as np

from fdml import fit
from fdml.design import Limits, classic_input, design, predict
from fdml.design.prediction import response
from fdml.models import make_model
from fdml.record import add_noise


def monte_carlo_std(model, inp, stds, n: int, seed: int = 0, band=None) -> dict[str, float]:
    """Std of n fits of noisy simulated records (the truth model fitted from its truth)."""
    rec = response(model, inp)
    rng = np.random.default_rng(seed)
    names = [k for k in model.parameters.free_names if not k.startswith("bias_")]
    est = []
    for _ in range(n):
        res = fit(add_noise(rec, stds, rng), model, band=band, adequacy=False, check=False)
        est.append([res.params[k] for k in names])
    return dict(zip(names, np.std(np.array(est), axis=0, ddof=1).tolist()))


def part1(n: int) -> None:
    lim = Limits(amplitude=math.radians(1.0), duration=12.0, dt=0.02)
    print(f"Part 1: Monte Carlo std / predicted stderr, N = {n} (chi scatter +-{1 / math.sqrt(2 * (n - 1)):.3f})")
    print(f"{'model':<10}{'input':<12}{'parameter':<10}{'predicted':>11}{'MC std':>11}{'ratio':>8}")
    worst = 0.0
    for kind in ("steady", "unsteady"):
        model = make_model(kind, "navion")
        for name in ("3211", "min-crest"):
            inp = classic_input(name, lim, (0.5, 10.0))
            pred = predict(model, inp, noise=0.05)
            mc = monte_carlo_std(model, inp, pred.noise, n)
            for k, s in mc.items():
                r = s / pred.stderr[k]
                worst = max(worst, abs(r - 1))
                print(f"{kind:<10}{name:<12}{k:<10}{pred.stderr[k]:>11.4g}{s:>11.4g}{r:>8.3f}")
    print(f"largest |ratio - 1|: {worst:.3f}")


def part2(n: int) -> None:
    model = make_model("unsteady", "sundowner")
    d = design(model, criterion="d-optimal", duration=20.0, amplitude=math.radians(3.0), band="0.5:15")
    print(f"\nPart 2: gain of the {d.input.name} (crest factor {d.input.report()['crest_factor']:.2f}), N = {n}")
    mc = {d.input.name: monte_carlo_std(model, d.input, d.noise, n, 1, d.band)}
    for b, p in d.baselines.items():
        mc[b] = monte_carlo_std(model, p.input, d.noise, n, 2, d.band)
    print(f"{'baseline':<8}{'parameter':<10}{'predicted gain':>16}{'MC gain':>10}")
    for b, g in d.gains().items():
        for k, v in g.items():
            print(f"{b:<8}{k:<10}{v:>16.3f}{mc[b][k] / mc[d.input.name][k]:>10.3f}")


def part3() -> None:
    model = make_model("unsteady", "navion")
    inp = classic_input("3211", Limits(amplitude=math.radians(1.0), duration=12.0, dt=0.02))
    pred = predict(model, inp, noise=0.05)
    rec = add_noise(response(model, inp), pred.noise, np.random.default_rng(0))
    t_pred = _fastest(lambda: predict(model, inp, noise=0.05))
    t_fit = _fastest(lambda: fit(rec, model, adequacy=False, check=False))
    print(f"\nPart 3: one prediction {1e3 * t_pred:.0f} ms, one fit {1e3 * t_fit:.0f} ms: ratio {t_pred / t_fit:.2f}")


def _fastest(call, reps: int = 5) -> float:
    """Fastest of ``reps`` timings, s (the least disturbed by other load)."""
    out = []
    for _ in range(reps):
        t0 = time.perf_counter()
        call()
        out.append(time.perf_counter() - t0)
    return min(out)


def main() -> None:
    warnings.simplefilter("ignore")
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    parts = sys.argv[2].split(",") if len(sys.argv) > 2 else ["3", "1", "2"]
    for p in parts:
        {"1": lambda: part1(n), "2": lambda: part2(n), "3": part3}[p]()


if __name__ == "__main__":
    main()
