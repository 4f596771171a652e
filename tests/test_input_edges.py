"""Elevator steps between samples (docs/theory.md section 7a): found, modelled, estimated, kept."""

from __future__ import annotations

import math

import numpy as np
import pytest
from independent_truth import Manoeuvre, simulate_record

from fdml import FitResult, fit, make_model, spectra
from fdml.fourier import finite_fourier_transform, step_edges
from fdml.models.base import ModelResponse
from fdml.models.measurement import edge_basis, end_shift, nuisance_columns, predict
from fdml.simulate import simulate_maneuver

DERIVS = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")


def test_a_step_between_samples_is_found_and_nothing_else_is():
    t = np.arange(200) * 0.02
    step = np.where(t > 1.013, 0.02, 0.0)  # the step lies in [1.00, 1.02]: interval 50
    assert step_edges(step).tolist() == [50]
    cosine = 0.01 * (1 - np.cos(np.pi * np.clip((t - 1.0) / 0.1, 0, 1)))  # 0.1 s edge over five intervals
    assert step_edges(cosine).size == 0
    spike = np.zeros(200)
    spike[80] = 0.02  # one bad sample: up and back down, no step
    assert step_edges(spike).size == 0
    quantised = step + 0.0004 * (np.arange(200) % 7 == 3)  # a step of 2 % of the range does not count
    assert step_edges(quantised).tolist() == [50]


@pytest.mark.parametrize("tau", [-0.008, 0.004, 0.009])
def test_the_edge_term_corrects_the_transform_of_a_step_to_first_order(tau):
    # The transform of a unit step at t_s over [0, T] is (exp(-j w t_s) - exp(-j w T)) / (j w): closed form.
    # The samples put it mid-interval at t_k; the edge term adds -tau exp(-j w t_k), the first-order
    # correction, so what is left is of order w tau^2 (and the cubic interpolant's w dt^2): well below
    # the uncorrected error w tau.
    dt, n = 0.02, 401
    t = np.arange(n) * dt
    t_k = 4.01  # middle of [4.00, 4.02]
    x = (t >= t_k + tau).astype(float)
    omega = np.linspace(0.2, 10.0, 50)
    T = t[-1]
    exact = (np.exp(-1j * omega * (t_k + tau)) - np.exp(-1j * omega * T)) / (1j * omega)
    measured = finite_fourier_transform(x, dt, omega)
    corrected = measured + edge_basis(omega, np.array([t_k]), np.array([1.0]))[:, 0] * tau
    before = np.max(np.abs(measured - exact))
    after = np.max(np.abs(corrected - exact))
    assert before > 0.5 * abs(tau)  # the error is the timing itself at low w: |exp(-j w tau) - 1| / w ~ tau
    # w tau^2 / 2 at w = 10 is 4e-4 for 9 ms; the cubic interpolant of a step adds about w dt^2 / 12
    assert after < 0.15 * before


def test_the_edge_columns_are_the_measurement_models_own():
    # predict with an elevator spectrum of edge terms equals the exact nuisance columns times the timings
    rng = np.random.default_rng(2)
    m = 30
    omega = np.linspace(0.2, 8, m)
    edges, steps = np.array([1.01, 2.31, 3.03]), np.array([0.02, -0.04, 0.02])
    B = edge_basis(omega, edges, steps)
    assert B.shape == (m, 3) and edge_basis(omega, edges, steps, "none").shape == (m, 0)
    G = rng.normal(size=(m, 3, 1)) + 1j * rng.normal(size=(m, 3, 1))
    resp = ModelResponse(omega, G, np.zeros((m, 3, 2), complex), np.zeros((m, 3, 2), complex))
    u, ones = rng.normal(size=(m, 1)) + 0j, np.ones(m, complex)
    tau = np.array([0.004, -0.009, 0.001])
    dy = predict(resp, u, ones, elevator=B @ tau) - predict(resp, u, ones)
    C = nuisance_columns(resp, end_shift(omega, 5.0), ones, B)[:, :, -3:]
    np.testing.assert_allclose(dy, C @ tau, rtol=0, atol=1e-15)


def _stepped(seed: int, *, dt: float = 0.01, unit: float = 0.3, noise: float = 0.03):
    """A 3-2-1-1 with true steps at times off the sample grid (scipy's solve_ivp, not fdml)."""
    rng = np.random.default_rng(seed)
    man = Manoeuvre(kind="3211", start=1.0 + rng.uniform(0, 1) * dt, unit=unit, edge="step")
    return simulate_record(man, dt=dt, duration=10.0, x0=(0.01, -0.02), noise=noise, rng=rng)


@pytest.mark.filterwarnings("ignore::fdml.IdentifiabilityWarning")
def test_estimated_timings_recover_where_the_steps_were_and_survive_a_save():
    # The unit 0.3 s is no multiple of dt = 0.04 s: every step sits elsewhere in its interval.
    rec, truth = _stepped(3, dt=0.04, unit=0.3)
    model = make_model("dimensional", "navion")
    est = fit(rec, model, input_edges="estimated", adequacy=False)
    names = [n for n in est.names if n.startswith("edge_de_")]
    off = np.array(truth["step_offsets"])
    assert len(names) == off.size == 5 and est.nuisance["input_edges"] == (5,)
    tau = np.array([est.params[n] for n in names])
    se = np.array([est.errors[n] for n in names])
    # first order in w tau: the estimates agree with where the steps were to a few standard errors
    assert np.all(np.abs(tau - off) < 4 * se + 1e-3)
    back = FitResult.from_dict(est.to_dict())
    np.testing.assert_allclose(back.fitted_spectra(), est.fitted_spectra(), rtol=1e-12, atol=0)


@pytest.mark.filterwarnings("ignore::fdml.IdentifiabilityWarning")
def test_with_the_timings_estimated_no_derivative_is_confidently_wrong():
    # Six records whose steps sit anywhere in their 40 ms intervals, 3 % noise: taking the samples'
    # interpolation as the input puts derivatives several standard errors off; with the timings
    # estimated every derivative of every record lies within 3 of its (scipy-simulated) truth.
    model = make_model("dimensional", "navion")
    z_none, z_est = [], []
    for seed in range(6):
        rec, truth = _stepped(seed, dt=0.04)
        for out, mode in ((z_none, "none"), (z_est, "estimated")):
            res = fit(rec, model, input_edges=mode, adequacy=False)
            out.append(max(abs(res.params[k] - truth[k]) / res.errors[k] for k in DERIVS))
    assert np.median(z_none) > 3.0
    assert max(z_est) < 3.0


@pytest.mark.filterwarnings("ignore::fdml.IdentifiabilityWarning")
def test_auto_adds_the_timings_when_the_steps_disagree_and_not_on_interpolated_records():
    rec, truth = _stepped(3, dt=0.04, unit=0.3)
    model = make_model("dimensional", "navion")
    assert fit(rec, model, adequacy=False).options["input_edges"] == "none"  # the default leaves them out
    res = fit(rec, model, input_edges="auto", adequacy=False)
    assert res.options["input_edges"] == "estimated"
    assert sum(n.startswith("edge_de_") for n in res.names) == len(truth["step_offsets"])
    # equal offsets (unit a multiple of dt) are one common shift, an elevator delay: auto leaves it
    same, truth_same = _stepped(2, dt=0.02, unit=0.3)
    assert np.ptp(truth_same["step_offsets"]) < 1e-9
    assert fit(same, model, input_edges="auto", adequacy=False).options["input_edges"] == "none"
    # fdml's simulator holds the elevator linearly between samples: the interpolation is right there
    sim = simulate_maneuver(make_model("steady", "navion"), "3211", seed=4, noise=0.02)
    assert spectra(sim).edges.size > 0
    steady = make_model("steady", "navion")
    auto, none = fit(sim, steady, input_edges="auto", adequacy=False), fit(sim, steady, adequacy=False)
    assert auto.options["input_edges"] == "none"
    assert auto.names == none.names and np.array_equal(auto.values, none.values)


def test_a_record_without_steps_has_no_edge_terms_whatever_the_option():
    rng = np.random.default_rng(1)
    man = Manoeuvre(kind="3211", start=1.013, edge="cosine", width=0.1)
    rec, _ = simulate_record(man, dt=0.02, duration=10.0, noise=0.02, rng=rng)
    assert spectra(rec).edges.size == 0
    res = fit(rec, make_model("dimensional", "navion"), input_edges="estimated", adequacy=False)
    assert not any(n.startswith("edge_de_") for n in res.names)
    assert math.isfinite(res.cost)


@pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")
def test_the_diagnosis_fits_every_model_with_the_steps_timing_its_base_fit_settled():
    from fdml.diagnose import diagnose

    rec, _ = _stepped(3, dt=0.04)
    model = make_model("dimensional", "navion")
    rep = diagnose(rec, model, input_edges="estimated", max_effects=1)
    assert rep.recommended is not None
    assert rep.recommended.options["input_edges"] == "estimated"
    assert sum(n.startswith("edge_de_") for n in rep.recommended.names) == 5
    plain = diagnose(rec, model, input_edges="none", max_effects=1)  # the record's interpolation, as asked
    assert plain.recommended is None or not any(n.startswith("edge_de_") for n in plain.recommended.names)


@pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")
@pytest.mark.parametrize("seed", [3, 4])
def test_when_the_steps_timing_explains_the_gap_best_the_diagnosis_estimates_it(seed):
    # Every step sits the same few ms off the middle of its 20 ms interval (seed 3: 8.3 ms early,
    # seed 4: 8.9 ms late): to a fit that interpolates the record an elevator lead, which no causal
    # effect can be, or a delay below the data's resolution, which the diagnosis sets aside.  Without
    # the steps' timing it names a structural mode for seed 3; with it (a lower BIC) it finds nothing
    # more, and its derivatives are within 3 standard errors of the scipy-simulated truth.
    from fdml.diagnose import diagnose

    rec, truth = _stepped(seed, dt=0.02)
    assert np.ptp(truth["step_offsets"]) < 1e-9 and 0.005 < abs(truth["step_offsets"][0]) < 0.01
    model = make_model("dimensional", "navion")
    plain = diagnose(rec, model, input_edges="none", max_effects=1)
    assert any(r["significant"] for r in plain.ranking)  # the sampling leaves a gap
    rep = diagnose(rec, model, max_effects=1)
    assert "every step's timing is estimated" in rep.settings["input_edges"]
    assert rep.verdict == "none" and rep.recommended.options["input_edges"] == "estimated"
    z = max(abs(rep.recommended.params[k] - truth[k]) / rep.recommended.errors[k] for k in DERIVS)
    assert z < 3.0


@pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")
def test_the_fits_adequacy_check_gives_the_same_answer_as_the_diagnosis():
    # One question, one answer: on the record whose steps sit 8.3 ms early, the plain fit's check ranks
    # the steps' timing first as the diagnosis does, and its advice runs as printed.
    from fdml.adequacy import Verdict

    rec, _ = _stepped(3, dt=0.02)
    res = fit(rec, make_model("dimensional", "navion"))
    v = res.adequacy.verdict
    assert v is not None and v.source == "steps" and v.key == "input_edges"
    warned = [w.message for w in res.warnings if w.category == "AdequacyWarning"]
    assert len(warned) == 1 and "--input-edges estimated" in warned[0]
    assert Verdict.from_dict(v.to_dict()) == v
    again = fit(rec, make_model("dimensional", "navion"), input_edges="estimated")
    assert again.adequacy.adequate  # with the steps' timing the check finds nothing left


@pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")
@pytest.mark.parametrize("seed", [0, 1])
def test_a_sensor_effect_on_a_stepped_record_is_named_with_the_steps_timing_beside_it(seed):
    # alpha lags 20 ms, the steps sit anywhere in their 40 ms intervals.  The fit's check names the lag
    # (refitted for seed 0, settled by the kinematics for seed 1) and advises the steps' timing beside
    # it; the diagnosis accepts the lag with the timing estimated: one answer, and it runs as printed.
    from independent_truth import Sensors

    from fdml.diagnose import diagnose

    rng = np.random.default_rng(seed)
    man = Manoeuvre(kind="3211", start=1.0 + rng.uniform(0, 1) * 0.04, edge="step")
    rec, truth = simulate_record(
        man, Sensors(delays={"alpha": 0.02}), dt=0.04, duration=12.0, x0=(0.004, -0.01), noise=0.03, rng=rng
    )
    model = make_model("dimensional", "navion")
    res = fit(rec, model)
    v = res.adequacy.verdict
    assert (v.key, v.with_steps) == ("time_delay@alpha", True)
    advice = next(w.message for w in res.warnings if w.category == "AdequacyWarning")
    assert "--input-edges estimated" in advice and "--effect time_delay:alpha" in advice
    rep = diagnose(rec, model)
    assert [s["key"] for s in rep.selected][:1] == ["time_delay@alpha"]
    assert rep.recommended.options["input_edges"] == "estimated"
    z = max(abs(rep.recommended.params[k] - truth[k]) / rep.recommended.errors[k] for k in DERIVS)
    assert z < 3.0
