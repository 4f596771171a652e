"""
Diagnosing a withheld effect
============================

Simulate a record whose truth has an effect the base model lacks (a 60 ms delay on the
alpha vane), fit the base model, and let :func:`fdml.diagnose.diagnose` find where the
model misses the data (the gap map), which effect explains it, and how far the gap shrinks
once the effect is added.
"""

import warnings

import fdml
from fdml.diagnose import diagnose
from fdml.diagnose.plots import plot_report
from fdml.simulate import simulate_maneuver

truth = fdml.make_model("derivatives", "navion", effects=["time_delay:alpha"]).with_values(tau_alpha=0.06)
rec = simulate_maneuver(truth, "3211", duration=20.0, dt=0.02, noise=0.02, seed=5)
base = fdml.make_model("derivatives", "navion")

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # the report keeps what matters
    rep = diagnose(rec, base, library=["time_delay", "actuator_lag", "sensor_offset", "lift_lag"])
print(rep.summary())

# %%
# The accepted effects and the recommended model:
print("accepted:", [s["key"] for s in rep.selected])
if rep.recommended is not None:
    print(f"tau_alpha = {rep.recommended['tau_alpha']:.4f} s (truth 0.06 s)")

# %%
# The gap map before and after, and the ranking of the candidates:
fig = plot_report(rep)
