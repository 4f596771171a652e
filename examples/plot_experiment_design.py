"""
Designing a manoeuvre to tell steady from unsteady aerodynamics
===============================================================

Before the flight, :func:`fdml.design.design` plans the elevator input: it
optimises a multisine's spectrum for a criterion (here: discrimination
between the Wells-Keskar unsteady model and its quasi-steady limit), gives it
minimum-crest-factor phases within the amplitude limit, and predicts, through
the estimator's own bound, the standard error of every parameter and the
probability of detecting the unsteady effects, against a 3-2-1-1 and a
linear sweep of the same duration and peak.

The command-line equivalent is::

    fdml design --aircraft navion --model unsteady --criterion discriminate \\
        --duration 12 --amplitude 1deg --band 0.5:10 --noise 0.1 -o input.csv
"""

import math
import warnings

import matplotlib.pyplot as plt

from fdml.design import design, plot_design
from fdml.models import make_model

warnings.simplefilter("ignore")

plan = design(
    make_model("unsteady", "navion"),
    criterion="discriminate",
    duration=12.0,
    amplitude=math.radians(1.0),
    band="0.5:10",
    noise=0.1,
)
print(plan.table())

# %%
# The figure: the designed input, the spectra of the three inputs, and the
# ratio of each baseline's predicted standard error to the design's.
fig = plot_design(plan)
plt.show()
