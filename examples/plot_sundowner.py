"""
Sundowner: a short record beside WK Table 3
===========================================

The Sundowner (Beech C23) preset carries the geometry of Wells-Keskar Table 2 (the tail
length 4.38 m is an assumption, THEORY.md section 11.2). A 6 s simulated record with 3 %
noise stands in for the paper's 3 s flight record; both models are fitted on the paper's
0.1 rad/s grid over 0.1-10 rad/s.
"""

import numpy as np

import fdml
from fdml.compare import compare_steady_unsteady
from fdml.plotting import plot_time_histories
from fdml.record import add_noise
from fdml.simulate import simulate_maneuver

# WK Table 3 (flight estimates), {derivative: (unsteady, steady)}
WK_TABLE3 = {
    "Cz_a": (-5.03, -4.96),
    "Cz_q": (-0.17, -0.25),
    "Cz_de": (-0.88, -0.75),
    "Cm_a": (-1.17, -1.01),
    "Cm_q": (-18.58, -21.93),
    "Cm_de": (-3.11, -3.05),
}

ac = fdml.get_aircraft("sundowner")
print(ac.describe())
truth = fdml.make_model("unsteady", ac)
rec = add_noise(
    simulate_maneuver(truth, "3211", duration=6.0, dt=0.02, unit=0.4), 0.03, np.random.default_rng(7), relative=True
)
cmp = compare_steady_unsteady(rec, ac, band=(0.1, 10.0, 0.1))
print(cmp.table(reference=WK_TABLE3))

# %%
# The unsteady fit's time histories, simulated from the estimate:
fig, axs = plot_time_histories(cmp.unsteady, title="Sundowner: measured and simulated from the unsteady fit")
