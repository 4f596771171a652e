"""
The Kussner lag from a gust record (Do 128)
===========================================

The Braunschweig paper identified the lag of the gust lift, K(s) = 1 / (T* s + 1) with
T* = c b1 / (2 U) (THEORY.md Eq. BS-12), from Do 128 records with a measured gust angle.
Here a Do 128-like record in Dryden turbulence is simulated with b1 = 7.3 semichords and
b1 is estimated with the aerodynamic parameters; a fit with the lag switched off
(b1 = 0) shows what the lag explains.
"""

import matplotlib.pyplot as plt

import fdml
from fdml.aero import get_indicial
from fdml.plotting import plot_residual_spectra
from fdml.simulate import simulate_maneuver

ac = fdml.get_aircraft("do128")
truth = fdml.make_model("unsteady", ac, gust=True)
rec = simulate_maneuver(
    truth, "3211", duration=30.0, dt=0.02, gust_std=1.5, seed=3, noise={"alpha": 1e-3, "q": 2e-3, "az": 5e-3}
)
b1_true = truth.parameters["b1"].value
print(f"channels {', '.join(rec.signals)}; b1 (true) = {b1_true}")

# %%
# Fit with b1 free (from the classical 2-D Kussner mean lag) and with b1 fixed at 0:
band = (0.2, 15.0, 0.1)
b1_start = get_indicial("kussner_jones_2d").mean_lag
best = fdml.fit(rec, truth.with_values(b1=b1_start), band=band, free=["b1"])
no_lag = fdml.fit(rec, truth, band=band, fix={"b1": 0.0})
b1, se = best["b1"], best.errors["b1"]
print(f"b1 = {b1:.2f} +/- {se:.2f} semichords (start {b1_start:.2f}); T* = {ac.c_w * b1 / (2 * ac.U):.3f} s")
print(f"det R without the lag / with it: {no_lag.cost / best.cost:.2f}")

# %%
# Residual spectra with and without the lag:
fig, axs = plt.subplots(2, 3, figsize=(11, 5.5), sharex=True, sharey="col")
plot_residual_spectra(best, ax=axs[0])
plot_residual_spectra(no_lag, ax=axs[1])
axs[0, 0].set_ylabel("b1 identified\n" + axs[0, 0].get_ylabel())
axs[1, 0].set_ylabel("no lag\n" + axs[1, 0].get_ylabel())
fig.tight_layout()
