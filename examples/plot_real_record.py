"""
A real record end to end: Twin Otter 017
========================================

A NASA Twin Otter longitudinal record in SIDPAC ``fdata`` layout: read it, check it, fit
the dimensional model (the record carries no geometry), read the adequacy check, and
compare the measured time histories with a simulation from the estimate.

The flight records are not part of the repository: fdml finds them where ``FDML_DATA``
points. Without it, this example says so and stops.
"""

import os
import warnings

import numpy as np

import fdml
from fdml.io import data_path, load_record
from fdml.plotting import plot_time_histories

if not os.environ.get("FDML_DATA"):
    print(
        "FDML_DATA is unset: the real flight records are not available here, so this example "
        "stops. Set FDML_DATA to the folder that holds twin_otter/ to run it."
    )
else:
    rec = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
    print(f"{rec.name}: {rec.meta['format']}, {rec.duration:.1f} s at {1 / rec.dt:.0f} Hz, U = {rec.meta['U']:.1f} m/s")

    # %%
    # Fit the dimensional model over 0.1-1.5 Hz on a 0.02 Hz grid (both in rad/s):
    HZ = 2 * np.pi
    band = (0.1 * HZ, 1.5 * HZ, 0.02 * HZ)
    model = fdml.make_model("dimensional", airspeed=rec.meta["U"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # every warning is kept in res.warnings and the summary
        res = fdml.fit(rec, model, band=band)
    print(res.summary())

    # %%
    # The adequacy check after the fit (score tests of every applicable effect):
    for line in res.adequacy.lines():
        print(line)

    # %%
    fig, axs = plot_time_histories(res, title="Twin Otter 017: measured and simulated from the estimate")
