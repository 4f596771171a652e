"""Experiment design: plan the manoeuvre before the flight.

* :mod:`fdml.design.inputs`: classic inputs and multisines within amplitude,
  rate and duration limits, as Record-compatible histories (CSV for a card);
* :mod:`fdml.design.prediction`: predicted covariance of the estimates through
  the estimator's own bound (docs/theory.md Eqs. 20-26);
* :mod:`fdml.design.discrimination`: expected steady-versus-unsteady
  likelihood-ratio statistic, detection probability, minimum detectable effects;
* :mod:`fdml.design.optimize`: optimal multisine spectra (D-, A-optimal,
  discrimination) with minimum-crest-factor phases;
* :mod:`fdml.design.plan`: :func:`design`, all of it in one call (``fdml design``).
"""

from .discrimination import Discrimination, detection_probability, discriminate, minimum_detectable
from .inputs import CLASSIC_KINDS, DesignInput, Limits, classic_input, multisine_input, read_input
from .optimize import CRITERIA, optimal_input
from .plan import Design, design, plot_design
from .prediction import Prediction, predict

__all__ = [
    "CLASSIC_KINDS",
    "CRITERIA",
    "Design",
    "DesignInput",
    "Discrimination",
    "Limits",
    "Prediction",
    "classic_input",
    "design",
    "detection_probability",
    "discriminate",
    "minimum_detectable",
    "multisine_input",
    "optimal_input",
    "plot_design",
    "predict",
    "read_input",
]
