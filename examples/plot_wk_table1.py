"""
Wells-Keskar Table 1: steady against unsteady (Navion)
======================================================

Wells and Keskar simulated a Navion with the unsteady model and fitted the conventional
six-derivative (steady) model to it: the steady fit absorbs the downwash lag into
biased derivatives (C_m_q more negative, the magnitude of C_m_alpha smaller). This example repeats the
experiment and prints both derivative sets beside the paper's Table 1 (THEORY.md
section 11.1).
"""

import numpy as np

import fdml
from fdml.compare import ALTERNATE_NAMES, compare_steady_unsteady
from fdml.demo import WK_TABLE1  # {derivative: (unsteady, steady)} from WK Table 1
from fdml.plotting import plot_spectra
from fdml.record import add_noise
from fdml.simulate import simulate_maneuver

ac = fdml.get_aircraft("navion")
truth = fdml.make_model("unsteady", ac)
rec = add_noise(simulate_maneuver(truth, "3211", duration=12.0, dt=0.02), 0.02, np.random.default_rng(1), relative=True)
cmp = compare_steady_unsteady(rec, ac)
print(cmp.table(reference=WK_TABLE1))

# %%
# How far the steady fit moved, against the paper's shift:
u, s = cmp.unsteady_set, cmp.steady_set
for n in ALTERNATE_NAMES:
    print(
        f"{n:6s} unsteady {u[n][0]:7.2f}  steady {s[n][0]:7.2f}   "
        f"WK Table 1: {WK_TABLE1[n][0]:7.2f} {WK_TABLE1[n][1]:7.2f}"
    )
print(f"det R, steady / unsteady = {cmp.steady.cost / cmp.unsteady.cost:.1f}")

# %%
fig, axes = plot_spectra(
    [cmp.unsteady, cmp.steady],
    ["unsteady fit", "steady (six-derivative) fit"],
    crb=False,
    title="Navion, WK Table 1 set-up",
)
