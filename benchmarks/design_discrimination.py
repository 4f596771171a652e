"""Predicted steady-versus-unsteady detection on the grid ``fdml compare`` is calibrated on (issue 11 / 15).

Truth: the Navion Wells-Keskar unsteady model (THEORY.md section 10).  Inputs:
fdml.maneuvers' 3-2-1-1, doublet and multisine with their default shapes
(``fdml simulate --maneuver``), 12 s at 50 Hz, 1 deg amplitude.  Noise: a
fraction of each output's RMS in that record (``simulate_maneuver(noise=f)``),
0.01 .. 0.2.  Fit band: fdml.fit's default (0.1:10:0.1 rad/s).

For each cell: the expected likelihood-ratio statistic lambda (the
non-centrality: the steady model's weighted misfit to the noise-free unsteady
response), the detection probability at level 0.05 with one degree of freedom
(``P{ncx2(1, lambda) > chi2_1(0.95)}``, the comprehensive-model approximation
of fdml.design.discrimination), P(unsteady favoured) = Phi(sqrt(lambda)/2) and
P(Vuong z > z_0.95) = Phi(sqrt(lambda)/2 - 1.645), for both steady models
(``steady``: the Wells-Keskar quasi-steady limit, same five parameters;
``derivatives``: the six conventional derivatives, WK Table 1's steady column).

Run: ``python benchmarks/design_discrimination.py`` (a few seconds).
"""

from __future__ import annotations

import math
import time
import warnings

from fdml import maneuvers as mv
from fdml.design import DesignInput, Limits, discriminate
from fdml.models import make_model

NOISE = (0.01, 0.02, 0.05, 0.1, 0.15, 0.2)
INPUTS = ("3211", "doublet", "multisine")
DURATION, DT, AMPLITUDE = 12.0, 0.02, math.radians(1.0)


def grid_inputs() -> dict[str, DesignInput]:
    """The three inputs as fdml simulate makes them (fdml.maneuvers.make_input defaults)."""
    t = mv.time_vector(DURATION, DT)
    lim = Limits(amplitude=AMPLITUDE, duration=DURATION, dt=DT)
    return {k: DesignInput(k, t, {"de": mv.make_input(k, t, AMPLITUDE)}, {}, lim) for k in INPUTS}


def table(steady_kind: str) -> list[dict]:
    mu = make_model("unsteady", "navion")
    ms = make_model(steady_kind, "navion")
    rows = []
    for name, inp in grid_inputs().items():
        for f in NOISE:
            d = discriminate(mu, ms, inp, noise=f, level=0.05)
            rows.append(
                {
                    "input": name,
                    "noise": f,
                    "lambda": d.noncentrality,
                    "P_detect": d.probability,
                    "P_favoured": d.favoured,
                    "P_vuong": d.vuong,
                }
            )
    return rows


def main() -> None:
    warnings.simplefilter("ignore")
    for kind in ("steady", "derivatives"):
        t0 = time.perf_counter()
        rows = table(kind)
        print(f"\nsteady model: {kind}  ({time.perf_counter() - t0:.1f} s)")
        print(f"{'input':<10}{'noise':>7}{'lambda':>11}{'P_detect':>10}{'P_favoured':>12}{'P_vuong':>9}")
        for r in rows:
            print(
                f"{r['input']:<10}{r['noise']:>7.2f}{r['lambda']:>11.4g}{r['P_detect']:>10.3f}"
                f"{r['P_favoured']:>12.3f}{r['P_vuong']:>9.3f}"
            )


if __name__ == "__main__":
    main()
