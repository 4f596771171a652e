"""fdml on the real flight records in $FDML_DATA: issue 3's proof.

With FDML_DATA set, a missing file fails with its name (fdml.io.data_path);
unset, the tests skip naming FDML_DATA (tests/conftest.py).  The
frequency-domain fits are checked against fdml's time-domain output-error fit
of the same model on the same record (an independent estimator sharing only the
model equations), and the two Twin Otter manoeuvres, flown at one condition,
are checked against each other.
"""

import math

import pytest

from fdml import fit, make_model
from fdml.consistency import consistency
from fdml.io import data_path, load_record
from fdml.timefit import fit_time_domain

DIM = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")
HZ = 2 * math.pi
TWIN_BAND = (0.1 * HZ, 1.5 * HZ, 0.02 * HZ)


@pytest.fixture(scope="module")
def records():
    return {
        "017": load_record(data_path("twin_otter/totter_lon_020213f1_017.mat")),
        "018": load_record(data_path("twin_otter/totter_lon_020213f1_018.mat")),
        "hfb": load_record(data_path("hfb320/hfb320_1_10.asc"), t0=0.0, t1=20.0),
        "attas": load_record(data_path("attas/fAttasElv1.mat")),
    }


def dimensional(rec):
    return make_model("dimensional", airspeed=rec.meta["U"])


@pytest.mark.slow
@pytest.mark.parametrize(
    "key, opts, limit",
    [
        # combined-standard-error limits: "within about two CRBs" (issue 3), with the
        # frequency domain's own (wider, nuisance-aware) errors dominating the combination
        ("017", dict(band=TWIN_BAND), 2.0),
        ("hfb", dict(band=(0.3, 6.0, 0.05)), 2.0),
        ("attas", dict(band=(0.3, 8.0, 0.05), outputs="alpha,q"), 2.0),
    ],
)
def test_frequency_and_time_domain_estimates_agree(records, key, opts, limit):
    rec = records[key]
    fd = fit(rec, dimensional(rec), **opts)
    td = fit_time_domain(rec, dimensional(rec), outputs=opts.get("outputs"))
    assert fd.converged and td.converged
    for n in DIM:
        assert abs(fd[n] - td[n]) < limit * math.hypot(fd.errors[n], td.errors[n]), n
    # a stable short period with a nose-down elevator (physical signs survived the loaders)
    assert fd["M_a"] < 0 and fd["M_de"] < 0 and fd["Z_a"] < 0


def test_twin_otter_repeats_and_joint_fit(records):
    f17 = fit(records["017"], dimensional(records["017"]), band=TWIN_BAND, cov_type="colored")
    f18 = fit(records["018"], dimensional(records["018"]), band=TWIN_BAND, cov_type="colored")
    # issue 3: one flight, one condition, yet M_a differs by about 1.0
    assert 0.5 < abs(f17["M_a"] - f18["M_a"]) < 1.5
    # the naive (independent-frequency) bounds are ~10 times too small to explain that
    naive = [math.sqrt(f.cov_naive[f.names.index("M_a"), f.names.index("M_a")]) for f in (f17, f18)]
    assert abs(f17["M_a"] - f18["M_a"]) > 5 * math.hypot(*naive)
    # the coloured-residual bounds do: no parameter disagrees after a Bonferroni correction
    c = consistency([f17, f18], names=DIM)
    assert c.agree()
    joint = fit([records["017"], records["018"]], dimensional(records["017"]), band=TWIN_BAND)
    assert joint.converged and "x0_alpha[totter_lon_020213f1_017]" in joint.names
    lo, hi = sorted([f17["M_a"], f18["M_a"]])
    assert lo - 0.3 < joint["M_a"] < hi + 0.3  # between the two manoeuvres


@pytest.mark.slow
def test_hfb320_fits_theta_and_qdot_as_the_dlr_book_does(records):
    """Jategaonkar's HFB-320 case measures theta and q_dot too; fdml fits them as rows of its output table."""
    rec = records["hfb"]
    five = "alpha,q,theta,qdot,az"
    fd = fit(rec, dimensional(rec), band=(0.3, 6.0, 0.05), outputs=five)
    td = fit_time_domain(rec, dimensional(rec), outputs=five)
    assert fd.converged and td.converged and fd.outputs == tuple(five.split(","))
    assert {"x0_theta", "xT_theta"} <= set(fd.names) and "bias_theta" not in fd.names  # theta's own boundary
    for n in DIM:  # the independent time-domain estimator, as for alpha, q and a_z above
        assert abs(fd[n] - td[n]) < 2.0 * math.hypot(fd.errors[n], td.errors[n]), n
    # what theta and q_dot change on this record: every derivative moves by less than one standard error
    three = fit(rec, dimensional(rec), band=(0.3, 6.0, 0.05))
    for n in DIM:
        assert abs(fd[n] - three[n]) < max(fd.errors[n], three.errors[n]), n
