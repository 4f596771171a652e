"""Export to python-control: FRD for every model, StateSpace for the rational ones, named signals."""

import control
import numpy as np
import pytest

import fdml
from fdml.export import descriptor_matrices, to_frd, to_statespace
from fdml.record import add_noise
from fdml.simulate import simulate_maneuver

OMEGA = np.linspace(0.05, 30.0, 120)

RATIONAL = [
    ("dimensional", {}, {}),
    ("dimensional", {"gust": True}, {}),
    ("derivatives", {}, {}),
    ("derivatives", {"adot": True}, {"Cz_adot": -1.2, "Cm_adot": -4.0}),  # E != I
    ("derivatives", {"adot": True, "gust": True}, {"Cz_adot": 0.0, "Cm_adot": -4.0}),  # B1 != 0
    ("steady", {}, {}),
    ("steady", {"gust": True}, {}),
]


def _frdata(frd):
    return frd.frdata if hasattr(frd, "frdata") else frd.fresp


def _ss_response(ss, omega):
    return np.asarray(ss(1j * omega)).reshape(ss.noutputs, ss.ninputs, omega.size)


@pytest.mark.parametrize("kind, opts, values", RATIONAL)
def test_statespace_matches_the_model(kind, opts, values):
    m = fdml.make_model(kind, "navion", **opts).with_values(values)
    ss = to_statespace(m)
    assert isinstance(ss, control.StateSpace)
    assert ss.output_labels == ["alpha", "q", "az"]
    assert ss.input_labels == (["de", "alpha_w"] if opts.get("gust") else ["de"])
    assert ss.nstates == 2
    G = m.frequency_response(OMEGA)
    Gs = _ss_response(ss, OMEGA)
    np.testing.assert_allclose(Gs, G, rtol=1e-12, atol=1e-12 * np.abs(G).max())
    if not (opts.get("gust") and opts.get("adot")):
        assert ss.state_labels == ["alpha", "q"]
        np.testing.assert_array_equal(ss.C[:2], np.eye(2))  # the states are alpha and q themselves
    # poles: zeros of det(sE - A), the model's own characteristic equation
    E, A, _, _ = descriptor_matrices(m)
    for p in ss.poles():
        assert abs(np.linalg.det(p * E - A)) < 1e-9 * max(1.0, abs(p) ** 2)


def test_frd_matches_exactly_for_every_model():
    for kind in ("unsteady", "steady", "derivatives", "dimensional"):
        for gust in (False, True):
            m = fdml.make_model(kind, "navion", gust=gust)
            frd = to_frd(m, OMEGA)
            assert isinstance(frd, control.FrequencyResponseData)
            np.testing.assert_array_equal(frd.omega, OMEGA)
            np.testing.assert_array_equal(_frdata(frd), m.frequency_response(OMEGA))
            assert frd.output_labels == ["alpha", "q", "az"]
            assert frd.input_labels == (["de", "alpha_w"] if gust else ["de"])


def test_frd_sorts_and_validates_omega():
    m = fdml.make_model("unsteady", "navion")
    frd = to_frd(m, OMEGA[::-1])
    np.testing.assert_array_equal(frd.omega, OMEGA)
    np.testing.assert_array_equal(_frdata(frd), m.frequency_response(OMEGA))
    with pytest.raises(fdml.ParameterError, match="positive"):
        to_frd(m, [0.0, 1.0])
    with pytest.raises(fdml.ParameterError, match="omega"):
        to_frd(m)


def test_export_from_a_fit():
    truth = fdml.make_model("derivatives", "navion")
    r = simulate_maneuver(truth, "3211", duration=10.0, dt=0.02)
    r = add_noise(r, 0.02, np.random.default_rng(2), relative=True)
    res = fdml.fit(r, truth, band=(0.2, 8, 0.2))
    w = res.spectra[0].omega
    frd = to_frd(res)  # default: the fitted frequencies
    np.testing.assert_array_equal(frd.omega, w)
    np.testing.assert_array_equal(_frdata(frd), res.model.frequency_response(w))
    ss = to_statespace(res)
    np.testing.assert_allclose(
        _ss_response(ss, w), res.model.frequency_response(w), rtol=1e-12, atol=1e-12 * np.abs(_frdata(frd)).max()
    )
    # the estimate, not the start values
    assert not np.allclose(ss.A, to_statespace(truth.with_values(Cm_a=-0.5)).A)


def test_unsteady_has_no_statespace():
    with pytest.raises(fdml.ParameterError, match="to_frd"):
        to_statespace(fdml.make_model("unsteady", "navion"))
    with pytest.raises(fdml.ParameterError, match="s ln s"):
        to_statespace(fdml.make_model("unsteady", "navion", gust=True))


def test_improper_gust_response_is_refused():
    m = fdml.make_model("derivatives", "navion", adot=True, gust=True).with_values(Cz_adot=-1.0)
    with pytest.raises(fdml.ParameterError, match="improper"):
        to_statespace(m)
    to_frd(m, OMEGA)  # the frequency response is fine


def test_delays_need_pade():
    m = fdml.make_model("derivatives", "navion", gust=True).with_values(tau_de=0.05, tau_alpha_w=0.02)
    with pytest.raises(fdml.ParameterError, match="pade"):
        to_statespace(m)
    with pytest.raises(fdml.ParameterError, match="positive integer"):
        to_statespace(m, pade=0)
    ss = to_statespace(m, pade=6)
    assert ss.state_labels[:2] == ["alpha", "q"]
    assert ss.state_labels[2:] == [f"de_delay{i}" for i in range(6)] + [f"alpha_w_delay{i}" for i in range(6)]
    assert ss.input_labels == ["de", "alpha_w"]
    G = m.frequency_response(OMEGA)
    np.testing.assert_allclose(_ss_response(ss, OMEGA), G, rtol=0, atol=1e-9 * np.abs(G).max())
    # one delayed input only
    m1 = fdml.make_model("dimensional", "navion").with_values(tau_de=0.1)
    ss1 = to_statespace(m1, pade=3)
    assert ss1.nstates == 5
    G1 = m1.frequency_response(OMEGA[:40])
    np.testing.assert_allclose(_ss_response(ss1, OMEGA[:40]), G1, rtol=0, atol=1e-4 * np.abs(G1).max())


def test_rejects_other_objects():
    with pytest.raises(fdml.ParameterError, match="FitResult or Model"):
        to_statespace("navion")
