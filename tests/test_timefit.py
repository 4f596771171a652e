"""Time-domain output-error fit: recovers the truth and agrees with the frequency-domain fit."""

import numpy as np
import pytest
from conftest import noisy_record

from fdml import fit
from fdml.errors import FdmlError, RecordError
from fdml.timefit import fit_time_domain

DIM = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")


def test_time_domain_fit_recovers_truth_and_matches_frequency_domain(dimensional_case):
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de, y, np.random.default_rng(12))
    start = m.with_values({n: 1.2 * m.parameters[n].value for n in DIM})
    td = fit_time_domain(rec, start)
    fd = fit(rec, start)
    assert td.converged
    for n in DIM:
        true = m.parameters[n].value
        assert abs(td[n] - true) < 3 * td.errors[n], n
        # the two estimates use the same data: they agree within about one combined error
        assert abs(td[n] - fd[n]) < np.hypot(td.errors[n], fd.errors[n]), n
    # noise std: 5 % of each output's std was added (3 sigma of a std from 500 samples ~ 10 %)
    assert np.allclose(td.sigma, 0.05 * y.std(axis=0), rtol=0.1)
    assert "bias_az" in td.names and "M_q" in td.summary()


def test_time_domain_fit_subset_and_errors(dimensional_case):
    m, t, de, y = dimensional_case
    rec = noisy_record(t, de, y, np.random.default_rng(1))
    td = fit_time_domain(rec, m, outputs="alpha,q", biases=False, fix={"Z_q": 0.0})
    assert td.outputs == ("alpha", "q") and "Z_q" not in td.names and "bias_alpha" not in td.names
    with pytest.raises(FdmlError, match="unknown output"):
        fit_time_domain(rec, m, outputs="nz")
    from fdml.models import make_model

    with pytest.raises(RecordError, match="no alpha_w"):
        fit_time_domain(rec, make_model("dimensional", "navion", gust=True))
