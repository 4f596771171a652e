"""The design's predicted detection probability is what ``fdml compare`` then does.

fdml.design predicts, before the flight, the probability that the steady-versus-unsteady
comparison of ``fdml compare`` (Vuong's two-sided test, fdml.compare.vuong_test) favours the
unsteady model; here that prediction meets the comparison itself, run on records made by the
time-domain simulator (not by the frequency-domain model the prediction uses).
"""

import math
import warnings

import pytest

from fdml import compare_steady_unsteady
from fdml import maneuvers as mv
from fdml.design import DesignInput, Limits, discriminate
from fdml.models import make_model
from fdml.simulate import simulate_maneuver

DURATION, DT, AMPLITUDE = 12.0, 0.02, math.radians(1.0)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore")  # misspecified steady fits of unsteady data warn, as they should
@pytest.mark.parametrize("maneuver, noise", [("3211", 0.1), ("doublet", 0.1)])
def test_predicted_compare_power_matches_the_comparisons(maneuver, noise):
    unsteady, steady = make_model("unsteady", "navion"), make_model("derivatives", "navion")
    t = mv.time_vector(DURATION, DT)
    inp = DesignInput(maneuver, t, {"de": mv.make_input(maneuver, t, AMPLITUDE)}, {}, Limits(AMPLITUDE, DURATION, DT))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = discriminate(unsteady, steady, inp, noise=noise, level=0.05)
    n = 24
    hits = 0
    for seed in range(n):
        rec = simulate_maneuver(
            unsteady, maneuver, duration=DURATION, dt=DT, amplitude=AMPLITUDE, noise=noise, seed=5000 + seed
        )
        hits += compare_steady_unsteady(rec, "navion", adequacy=False).evidence.favoured == "unsteady"
    # The cells chosen have a predicted power away from 0 and 1 (0.5-0.7), where a wrong formula
    # shows: P(favoured) = Phi(sqrt(lambda)/2), the sign of the statistic alone, is 0.93-0.99
    # there.  A binomial count of n = 24 scatters by sqrt(p(1-p)/n) <= 0.10; 3 of those bound it.
    assert 0.2 < pred.vuong < 0.8, pred
    assert abs(hits / n - pred.vuong) <= 3 * math.sqrt(pred.vuong * (1 - pred.vuong) / n), (hits, pred)
    assert pred.favoured - hits / n > 0.15  # the sign alone would have over-promised
