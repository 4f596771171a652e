"""
Quickstart: simulate, fit, read the result
==========================================

Simulate a Navion 3-2-1-1 manoeuvre with the Wells-Keskar unsteady model, add 2 %
measurement noise, and fit the unsteady model's parameter vector theta (THEORY.md Eq. 18)
by frequency-domain maximum likelihood from a start 30 % away from the truth.
"""

import numpy as np

import fdml
from fdml.plotting import plot_spectra
from fdml.record import add_noise
from fdml.simulate import simulate_maneuver

truth = fdml.make_model("unsteady", "navion")
clean = simulate_maneuver(truth, "3211", duration=12.0, dt=0.02)
rec = add_noise(clean, 0.02, np.random.default_rng(1), relative=True)
print(f"{rec.n} samples, dt = {rec.dt:g} s, channels {', '.join(rec.signals)}")

# %%
# The fit
# -------
# ``band`` is (low, high, step) in rad/s. The start values are 0.7 times the truth.
theta = ["CLa_w", "CLa_t", "deps_da", "Cm_de", "Cz_de"]
true = truth.parameters.values
start = truth.with_values({n: 0.7 * true[n] for n in theta})
res = fdml.fit(rec, start, band=(0.1, 10.0, 0.1))
print(res.summary())

# %%
# Each estimate against the truth, in standard errors:
for n in theta:
    print(
        f"{n:8s} true {true[n]:8.4g}  estimate {res[n]:8.4g} +/- {res.errors[n]:.2g}"
        f"  ({(res[n] - true[n]) / res.errors[n]:+.1f} s.e.)"
    )

# %%
# Measured and fitted spectra, with the fit's uncertainty band:
fig, axes = plot_spectra(res, ["unsteady fit"], title="Navion 3-2-1-1: measured and fitted spectra")
