"""Issue 11's proof: which inputs tell steady from unsteady, what a designed input gains, Do 128's b1.

1. Navion (THEORY.md section 10; 12 s, 1 deg, band 0.5:10) and Sundowner
   (section 11.2; 20 s, 3 deg, band 0.5:15): the expected likelihood-ratio
   statistic lambda and the detection probability at level 0.05 of each classic
   input (doublet, 3-2-1-1, linear and log sweeps, Schroeder and min-crest
   multisines) and of the input designed for discrimination, at sensor noise of
   10 % and 20 % of the 3-2-1-1 response's RMS (the same stds for every input).
2. Do 128 gust case (section 8): the unsteady gust model with the Kussner
   length b1 free, a 1 deg 3-2-1-1 flown in measured Dryden turbulence (vertical
   RMS sigma_w, L = 533 m), sensors 0.1 deg, 0.1 deg/s, 0.01 g, fit band
   0.2:20 rad/s: the predicted relative stderr of b1 against record length
   (the same 1.4 s elevator 3-2-1-1 at every length, so that only the
   turbulence grows; median over 3 turbulence draws), and the shortest length
   giving 10 %.

Run: ``python benchmarks/design_proof.py [discrimination,b1]`` (a few minutes).
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np

from fdml import maneuvers as mv
from fdml.design import CLASSIC_KINDS, DesignInput, Limits, classic_input, design, discriminate, predict
from fdml.design.prediction import noise_stds, response
from fdml.models import make_model

SETUPS = {"navion": (12.0, 1.0, (0.5, 10.0)), "sundowner": (20.0, 3.0, (0.5, 15.0))}
SENSORS = {"alpha": math.radians(0.1), "q": math.radians(0.1), "az": 0.01}
#: Fit band of the gust case, rad/s: the Kussner lag T* = c b1 / (2 V) ~ 0.1 s has its corner near 10 rad/s.
BAND_B1 = (0.2, 20.0, 0.1)


def discrimination_table(aircraft: str, fraction: float) -> None:
    duration, amp_deg, band = SETUPS[aircraft]
    mu, ms = make_model("unsteady", aircraft), make_model("steady", aircraft)
    lim = Limits(amplitude=math.radians(amp_deg), duration=duration, dt=0.02)
    stds = noise_stds(response(mu, classic_input("3211", lim, band)), fraction)
    fband = (*band, 0.1)
    print(
        f"\n{aircraft}: {duration:g} s, {amp_deg:g} deg, band {band[0]:g}:{band[1]:g}, noise {fraction:g} of 3211 RMS"
    )
    print(f"{'input':<26}{'lambda':>9}{'P(detect)':>11}{'crest':>7}")
    rows = {k: classic_input(k, lim, band) for k in CLASSIC_KINDS}
    d = design(
        mu,
        criterion="discriminate",
        duration=duration,
        amplitude=lim.amplitude,
        band=f"{band[0]}:{band[1]}",
        noise=stds,
        baselines=(),
    )
    rows[d.input.name] = d.input
    for k, inp in rows.items():
        r = discriminate(mu, ms, inp, noise=stds, band=fband)
        print(f"{k:<26}{r.noncentrality:>9.3g}{r.probability:>11.3f}{inp.report()['crest_factor']:>7.2f}")


def b1_length(sigma_w: float, lengths=(3.0, 5.0, 8.0, 12.0, 20.0, 30.0)) -> None:
    model = make_model("unsteady", "do128", gust=True)
    model = model.with_parameters(model.parameters.free(["b1"]))
    print(f"\nDo 128, sigma_w = {sigma_w:g} m/s: relative stderr of b1 (b1 = {model.parameters['b1'].value:g})")
    need = None
    for T in lengths:
        lim = Limits(amplitude=math.radians(1.0), duration=T, dt=0.02)
        base = classic_input("3211", lim, unit=0.2)  # the same 1.4 s elevator input at every length
        rel = []
        for seed in range(3):
            aw = mv.dryden_gust(base.t, sigma_w, model.U, rng=np.random.default_rng(seed))
            inp = DesignInput("3211 in turbulence", base.t, {"de": base.de, "alpha_w": aw}, {}, lim)
            rel.append(predict(model, inp, noise=SENSORS, band=BAND_B1).relative("b1"))
        med = float(np.median(rel))
        if need is None and med <= 0.1:
            need = T
        print(f"  T = {T:5.1f} s: {100 * med:6.1f} %  (draws {', '.join(f'{100 * r:.1f}' for r in rel)})")
    print(f"  shortest record for b1 to 10 %: {need if need is not None else '> ' + str(lengths[-1])} s")


def main() -> None:
    warnings.simplefilter("ignore")
    parts = sys.argv[1].split(",") if len(sys.argv) > 1 else ["discrimination", "b1"]
    if "discrimination" in parts:
        for ac in SETUPS:
            for f in (0.1, 0.2):
                discrimination_table(ac, f)
    if "b1" in parts:
        for s in (0.1, 0.3, 1.0):
            b1_length(s)


if __name__ == "__main__":
    main()
