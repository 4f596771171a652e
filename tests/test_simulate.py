"""fdml.simulate and fdml.maneuvers: the time-domain simulator and the input generators."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from fdml.errors import FdmlError, ParameterError, RecordError
from fdml.fourier import finite_fourier_transform
from fdml.maneuvers import (
    doublet,
    dryden_gust,
    dryden_psd,
    make_input,
    multisine,
    multisine_frequencies,
    three_two_one_one,
    time_vector,
)
from fdml.models import make_model, with_effects
from fdml.simulate import realize, simulate, simulate_maneuver

OUT = ("alpha", "q", "az")


def _outputs(rec):
    return np.column_stack([rec[k] for k in OUT])


# --- frequency domain vs the Fourier transform of the simulation ----------------------------------

ADOT = {"Cz_adot": -1.0, "Cm_adot": -5.0}
#: (kind, model options, parameter values, input driven)
CASES = {
    "dimensional-de": ("dimensional", {}, {}, "de"),
    "dimensional-gust": ("dimensional", {"gust": True}, {}, "alpha_w"),
    "derivatives-de": ("derivatives", {}, {}, "de"),
    "derivatives-gust": ("derivatives", {"gust": True}, {}, "alpha_w"),
    "derivatives-adot-de-delay": ("derivatives", {"gust": True, "adot": True}, {**ADOT, "tau_de": 0.033}, "de"),
    # a whole number of samples at both steps (see the order test)
    "derivatives-adot-gust": ("derivatives", {"gust": True, "adot": True}, {**ADOT, "tau_alpha_w": 0.02}, "alpha_w"),
    "steady-de": ("steady", {}, {}, "de"),
    "steady-gust": ("steady", {"gust": True}, {}, "alpha_w"),
    "unsteady-F0-de": ("unsteady", {}, {"F": 0.0}, "de"),
    "unsteady-F0-gust": ("unsteady", {"gust": True}, {"F": 0.0}, "alpha_w"),
    "unsteady-F0-gust-jones2d-ct": (
        "unsteady",
        {"gust": True, "gust_lag": "kussner_jones_2d", "tail_lag_chord": "c_t"},
        {"F": 0.0},
        "alpha_w",
    ),
    "unsteady-F0-gust-no-tail-delay": ("unsteady", {"gust": True, "tail_gust_delay": False}, {"F": 0.0}, "alpha_w"),
    "unsteady-F-de": ("unsteady", {}, {}, "de"),
    "unsteady-F-gust": ("unsteady", {"gust": True}, {}, "alpha_w"),
    "unsteady-F-gust-jonesAR6-delay": (
        "unsteady",
        {"gust": True, "gust_lag": "kussner_jones_ar6"},
        {"tau_alpha_w": 0.012},
        "alpha_w",
    ),
}
OMEGA = np.linspace(0.2, 10.0, 50)


def _transfer_error(model, values, driven, dt):
    """max over outputs of max_w |y~/u~ - G| / max_w |G| for a smooth doublet, from rest.

    30 s: finite-state responses decay to ~1e-30; the F-term's algebraic t^-3 tail
    to ~1e-8 of the peak, which truncates the transform by far less than the step error.
    """
    t = time_vector(30.0, dt)
    u = doublet(t, 0.01, start=1.0, width=0.5, rise=0.5)  # C1, zero mean, no spectral zero below 12 rad/s
    inputs = {"de": np.zeros_like(t) if driven == "alpha_w" else u}
    if model.gust:
        inputs["alpha_w"] = u if driven == "alpha_w" else np.zeros_like(t)
    rec = simulate(model, t, inputs, values, substeps=4)
    Y = finite_fourier_transform(_outputs(rec), dt, OMEGA)
    Uw = finite_fourier_transform(u, dt, OMEGA)
    G = model.frequency_response(OMEGA, values)[:, model.inputs.index(driven), :].T
    return np.max(np.max(np.abs(Y / Uw[:, None] - G), axis=0) / np.max(np.abs(G), axis=0))


@pytest.mark.parametrize("case", list(CASES))
def test_simulation_matches_frequency_response(case):
    kind, opts, values, driven = CASES[case]
    model = make_model(kind, "sundowner", **opts)
    dt = 0.01
    e1 = _transfer_error(model, values, driven, dt)
    e2 = _transfer_error(model, values, driven, dt / 2)
    # second order: the simulated input is linear between samples, its transform's factor is
    # sinc^2(w dt/2) = 1 - (w dt)^2/12 (measured orders 1.99-2.01).  A delay that is a fraction
    # of a sample is simulated exactly (test below), but an output's direct feedthrough of the
    # delayed input (a_z of alpha_w and its rate) is then sampled off the input's kinks, at a
    # fraction of dt that changes with dt: its observed order is 1.4-2.5, so the gust case's
    # delay is 2 and 4 samples here; the de case's 0.033 s (3.3 and 6.6 samples) measures 2.01
    assert np.log2(e1 / e2) > 1.9, (e1, e2)
    # with the F-term's h = T/m <= dt/4, its trapezoid error adds (w dt)^2/8: 5/24 < 1/4
    assert e2 < (OMEGA[-1] * dt / 2) ** 2 / 4, e2


# --- exactness for piecewise-linear inputs ----------------------------------------------------------


def _piecewise_ode(E, A, B0, B1, t, u):
    """E x' = A x + B0 u + B1 u' for u linear between samples, by DOP853 one interval at a time."""
    Ei = np.linalg.inv(E)
    x = np.zeros(2)
    out = [x]
    for k in range(t.size - 1):
        slope = (u[k + 1] - u[k]) / (t[k + 1] - t[k])
        f = lambda tt, xx, k=k, slope=slope: Ei @ (A @ xx + B0 * (u[k] + slope * (tt - t[k])) + B1 * slope)  # noqa
        x = integrate.solve_ivp(f, (t[k], t[k + 1]), x, method="DOP853", rtol=1e-12, atol=1e-15).y[:, -1]
        out.append(x)
    return np.array(out)


@pytest.mark.parametrize("driven", ["de", "alpha_w"])
def test_exact_for_piecewise_linear_inputs(driven):
    """Descriptor model with alpha-dot derivatives: states exact for PL inputs, no input derivative used."""
    model = make_model("derivatives", "sundowner", gust=True, adot=True)
    p = model.values(ADOT)
    ac = model.aircraft
    kz, km, cu = ac.k_z, ac.k_m, ac.c_w / (2 * ac.U)
    E = np.array([[1 - kz * p["Cz_adot"] * cu, 0.0], [-km * p["Cm_adot"] * cu, 1.0]])
    A = np.array([[kz * p["Cz_a"], 1 + kz * p["Cz_q"] * cu], [km * p["Cm_a"], km * p["Cm_q"] * cu]])
    if driven == "de":
        B0, B1 = np.array([kz * p["Cz_de"], km * p["Cm_de"]]), np.zeros(2)
    else:
        B0 = np.array([kz * p["Cz_a"], km * p["Cm_a"]])
        B1 = np.array([kz * p["Cz_adot"] * cu, km * p["Cm_adot"] * cu])
    t = time_vector(3.0, 0.05)
    u = three_two_one_one(t, 0.01, start=0.2, unit=0.3)  # sharp edges: ramps over one sample
    inputs = {"de": u if driven == "de" else 0 * u, "alpha_w": u if driven == "alpha_w" else 0 * u}
    rec = simulate(model, t, inputs, ADOT)
    ref = _piecewise_ode(E, A, B0, B1, t, u)
    sim = np.column_stack([rec["alpha"], rec["q"]])
    # DOP853 at rtol 1e-12 per interval; the matrix exponential is accurate to rounding
    assert np.max(np.abs(sim - ref)) < 1e-10 * np.max(np.abs(ref))


@pytest.mark.parametrize("offset", [0.0, 0.005])
@pytest.mark.parametrize(
    "kind, opts, key", [("steady", {}, "tau_de"), ("derivatives", {"gust": True, "adot": True}, "tau_alpha_w")]
)
def test_a_delay_of_a_fraction_of_a_sample_is_exact_for_piecewise_linear_inputs(kind, opts, key, offset):
    """0.7 samples of delay: the states equal those of a 10 times finer grid without the delay, 7 steps later.

    The fine grid holds the same piecewise-linear input (linear interpolation of the samples is
    exact for it), and the model is time-invariant: delaying its input delays its response, which
    on the fine grid is a shift by whole steps, so the reference interpolates nothing.  Sampling the
    delayed input instead and holding it linear between the samples smooths its edges like a short
    lag (1.5 % of the peak q here).  With ``offset`` the input starts off rest: it steps up at t = d.
    """
    model = make_model(kind, "sundowner", **opts)
    values = {**(ADOT if opts.get("adot") else {}), key: 0.014}
    dt, fine, shift = 0.02, 10, 7
    t, tf = time_vector(4.0, dt), time_vector(4.0, dt / fine)
    u = three_two_one_one(t, 0.01, start=0.2, unit=0.3) + offset  # sharp edges: ramps over one sample
    driven = "alpha_w" if key == "tau_alpha_w" else "de"
    uf = np.interp(tf, t, u)
    ref = simulate(model, tf, {name: uf * (name == driven) for name in model.inputs}, values | {key: 0})
    sim = simulate(model, t, {name: u * (name == driven) for name in model.inputs}, values)
    for ch in ("alpha", "q"):  # the states (a_z's rate feedthrough differs by its central differences)
        want = np.r_[np.zeros(shift), ref[ch][:-shift]][::fine]
        # matrix exponentials and a march of 200 and 2,000 steps: rounding, measured 3e-15 to 7e-15 of the peak
        assert np.max(np.abs(sim[ch] - want)) < 1e-12 * np.max(np.abs(want)), ch


@pytest.mark.parametrize("channels, shift", [(("az",), 7), (("alpha", "q"), 7), (("az",), 27), (("q",), 20)])
def test_a_sensor_delay_of_a_fraction_of_a_sample_is_exact(channels, shift):
    """Outputs recorded 0.7, 2.7 or 2 samples late equal the fine-grid outputs 7, 27 or 20 steps earlier.

    a_z and q bend where the elevator does; a cubic spline through the samples rang there (1.8 % of
    the peak a_z on this stepped 3-2-1-1): the simulation now reads the states where each output was.
    """
    base = make_model("steady", "sundowner")
    key = "time_delay:" + ",".join(channels)
    model = with_effects(base, key)
    tau_name = "tau_" + "_".join(channels)  # the effect's delay (the model's own tau_de stays 0)
    dt, fine = 0.02, 10
    t, tf = time_vector(4.0, dt), time_vector(4.0, dt / fine)
    u = three_two_one_one(t, 0.01, start=0.2, unit=0.3)
    ref = simulate(base, tf, {"de": np.interp(tf, t, u)})
    sim = simulate(model, t, {"de": u}, {tau_name: shift * dt / fine})
    for ch in OUT:
        want = np.r_[np.zeros(shift), ref[ch][:-shift]] if ch in channels else ref[ch]
        # rounding, as above: measured 5e-15 of the peak
        assert np.max(np.abs(sim[ch] - want[::fine])) < 1e-12 * np.max(np.abs(want)), ch


def test_realisation_of_every_finite_state_model_is_exact():
    w = np.geomspace(1e-3, 30.0, 80)
    for kind, opts, values in [
        ("dimensional", {}, {}),
        ("derivatives", {"adot": True}, ADOT),
        ("steady", {}, {}),
        ("unsteady", {}, {"F": 0.0}),
        ("unsteady", {"gust_lag": "kussner_jones_ar6", "tail_lag_chord": "c_t"}, {"F": 0.0}),
        ("unsteady", {"tail_gust_delay": False}, {"F": 0.0, "b1": 0.0}),
    ]:
        for ac in ("sundowner", "navion"):
            model = make_model(kind, ac, gust=True, **opts)
            G = model.frequency_response(w, values)
            # same rational functions evaluated two ways: rounding of a small linear solve
            assert np.max(np.abs(realize(model, values).frequency_response(w) - G)) < 1e-12 * np.max(np.abs(G))
    with pytest.raises(ParameterError, match="no finite-state"):
        realize(make_model("unsteady", "sundowner"))


def test_weathercock_in_a_steady_gust():
    """THEORY.md section 8: a constant alpha_g gives alpha = -alpha_g, q = 0 (hence a_z = 0)."""
    model = make_model("unsteady", "sundowner", gust=True)
    t = time_vector(20.0, 0.02)
    ag = 0.01 * (t >= 1.0)
    rec = simulate(model, t, {"de": 0 * t, "alpha_w": ag}, {"F": 0.0})
    # slowest mode decays like exp(-2 t): after 19 s nothing is left above rounding
    assert rec["alpha"][-1] == pytest.approx(-0.01, abs=1e-12)
    assert abs(rec["q"][-1]) < 1e-12 and abs(rec["az"][-1]) < 1e-10


# --- biases, delays, noise, seeds --------------------------------------------------------------------


def test_biases_are_added_to_the_outputs():
    model = make_model("unsteady", "sundowner")
    t = time_vector(5.0, 0.02)
    u = doublet(t, 0.01)
    bias = {"bias_alpha": 0.01, "bias_q": -0.002, "bias_az": 0.05}
    y0 = _outputs(simulate(model, t, {"de": u}))
    yb = _outputs(simulate(model, t, {"de": u}, bias))
    np.testing.assert_allclose(yb - y0, np.broadcast_to([0.01, -0.002, 0.05], y0.shape), rtol=0, atol=1e-15)


@pytest.mark.parametrize("kind", ["dimensional", "unsteady"])
def test_whole_sample_delay_shifts_the_response(kind):
    model = make_model(kind, "sundowner", gust=True)
    values = {"F": 0.0} if kind == "unsteady" else {}
    t = time_vector(5.0, 0.02)
    u = doublet(t, 0.01, rise=0.2)
    for name, key in (("de", "tau_de"), ("alpha_w", "tau_alpha_w")):
        inputs = {"de": 0 * t, "alpha_w": 0 * t, name: u}
        y0 = _outputs(simulate(model, t, inputs, values))
        yd = simulate(model, t, inputs, {**values, key: 5 * 0.02})
        np.testing.assert_array_equal(yd[name], u)  # the record keeps the input as given
        yd = _outputs(yd)
        # a delay of 5 samples is exact: the same samples, shifted (interp at the nodes)
        np.testing.assert_allclose(yd[5:], y0[:-5], rtol=0, atol=1e-14 * np.max(np.abs(y0)))
        assert np.all(yd[:5] == 0)


def test_noise_has_the_requested_std_and_only_where_asked():
    model = make_model("dimensional", "navion")
    t = time_vector(100.0, 0.02)  # n = 5001 samples
    u = three_two_one_one(t, 0.01)
    clean = _outputs(simulate(model, t, {"de": u}))
    noise = {"alpha": 1e-3, "az": 0.02}
    rec = simulate(model, t, {"de": u}, noise=noise, rng=np.random.default_rng(7))
    resid = _outputs(rec) - clean
    n = t.size
    for i, k in enumerate(OUT):
        if k in noise:
            # sample std of n Gaussian draws: relative standard error 1/sqrt(2n) = 1 %; allow 4.5 of them
            assert np.std(resid[:, i]) == pytest.approx(noise[k], rel=4.5 / np.sqrt(2 * n))
            assert abs(np.mean(resid[:, i])) < 4.5 * noise[k] / np.sqrt(n)
        else:
            assert np.all(resid[:, i] == 0)
    assert rec.meta["noise"] == noise


def test_seeded_runs_reproduce():
    model = make_model("unsteady", "sundowner", gust=True)
    kw = dict(duration=5.0, gust_std=1.5, noise={"alpha": 1e-3, "q": 1e-3, "az": 0.01})
    a = simulate_maneuver(model, "doublet", seed=11, **kw)
    b = simulate_maneuver(model, "doublet", seed=11, **kw)
    c = simulate_maneuver(model, "doublet", seed=12, **kw)
    for k in ("alpha", "q", "az", "alpha_w"):
        np.testing.assert_array_equal(a[k], b[k])
        assert not np.array_equal(a[k], c[k])
    assert a.meta["seed"] == 11 and a.meta["maneuver"] == "doublet"


def test_record_contents_and_meta():
    model = make_model("unsteady", "navion", gust=True)
    t = time_vector(4.0, 0.02)
    rec = simulate(model, t, {"de": doublet(t), "alpha_w": 0 * t}, {"CLa_w": 4.7}, name="x")
    assert set(rec.signals) == {"de", "alpha", "q", "az", "alpha_w"}
    assert rec.name == "x"
    assert rec.meta["model"] == "unsteady" and rec.meta["U"] == model.U
    assert rec.meta["values"]["CLa_w"] == 4.7 and rec.meta["noise"] is None
    assert rec.meta["integration"]["pole_steps"] >= 16
    rec = simulate(make_model("dimensional", airspeed=50.0), t, {"de": doublet(t)})
    assert set(rec.signals) == {"de", "alpha", "q", "az"}
    assert "exact" in rec.meta["integration"]["method"]


@pytest.mark.parametrize("maneuver", ["doublet", "3211", "multisine"])
@pytest.mark.parametrize("kind", ["dimensional", "unsteady"])
def test_simulate_maneuver_runs_for_every_input(maneuver, kind):
    model = make_model(kind, "sundowner")
    rec = simulate_maneuver(model, maneuver, duration=8.0, dt=0.02, amplitude=0.02)
    assert rec.n == 401 and np.max(np.abs(rec["de"])) == pytest.approx(0.02)
    assert np.max(np.abs(rec["q"])) > 0


def test_simulate_maneuver_gust_needs_a_gust_model():
    with pytest.raises(ParameterError, match="gust input"):
        simulate_maneuver(make_model("steady", "sundowner"), gust_std=1.0)
    rec = simulate_maneuver(make_model("steady", "sundowner", gust=True), gust_std=1.0, seed=1)
    assert np.std(rec["alpha_w"]) > 0


# --- validation ------------------------------------------------------------------------------------


@pytest.fixture
def gust_model():
    return make_model("unsteady", "sundowner", gust=True)


def _call(model, t, inputs, **kw):
    return simulate(model, t, inputs, **kw)


def test_bad_inputs_raise_clear_errors(gust_model):
    t = time_vector(2.0, 0.02)
    u = doublet(t, 0.01, start=0.5)
    z = np.zeros_like(t)
    with pytest.raises(RecordError, match="missing input.*alpha_w"):
        simulate(gust_model, t, {"de": u})
    with pytest.raises(RecordError, match="no gust input"):
        simulate(make_model("steady", "sundowner"), t, {"de": u, "alpha_w": z})
    with pytest.raises(RecordError, match="input de has shape"):
        simulate(gust_model, t, {"de": u[:-1], "alpha_w": z})
    bad = u.copy()
    bad[7] = np.nan
    with pytest.raises(RecordError, match="non-finite.*sample 7"):
        simulate(gust_model, t, {"de": bad, "alpha_w": z})
    t2 = t.copy()
    t2[10] += 0.003
    with pytest.raises(RecordError, match="not uniformly spaced"):
        simulate(gust_model, t2, {"de": u, "alpha_w": z})
    with pytest.raises(RecordError, match="strictly increasing"):
        simulate(gust_model, t[::-1], {"de": u, "alpha_w": z})
    with pytest.raises(RecordError, match="mapping"):
        simulate(gust_model, t, u)
    with pytest.raises(ParameterError, match="unknown parameter 'Cm_q'"):
        simulate(gust_model, t, {"de": u, "alpha_w": z}, {"Cm_q": -10.0})
    with pytest.raises(ParameterError, match="tau_de must be a delay >= 0"):
        simulate(gust_model, t, {"de": u, "alpha_w": z}, {"tau_de": -0.1})
    with pytest.raises(ParameterError, match="needs rng"):
        simulate(gust_model, t, {"de": u, "alpha_w": z}, noise={"q": 0.01})
    with pytest.raises(ParameterError, match="unknown noise channel"):
        simulate(gust_model, t, {"de": u, "alpha_w": z}, noise={"theta": 0.01}, rng=np.random.default_rng(0))
    with pytest.raises(ParameterError, match=">= 0"):
        simulate(gust_model, t, {"de": u, "alpha_w": z}, noise={"q": -1.0}, rng=np.random.default_rng(0))


def test_F_term_rejects_a_step_at_time_zero(gust_model):
    t = time_vector(2.0, 0.02)
    with pytest.raises(ParameterError, match="step at t = 0"):
        simulate(gust_model, t, {"de": 0.01 + 0 * t, "alpha_w": 0 * t})
    # the same step is fine without the singular F term, and a gust step is fine with the
    # Kussner lag (no direct path into alpha_dot)
    simulate(gust_model, t, {"de": 0.01 + 0 * t, "alpha_w": 0 * t}, {"F": 0.0})
    simulate(gust_model, t, {"de": 0 * t, "alpha_w": 0.01 + 0 * t})
    with pytest.raises(ParameterError, match="pole_steps"):
        simulate(gust_model, t, {"de": 0 * t, "alpha_w": 0 * t}, pole_steps=1)


def test_errors_are_fdml_errors():
    assert issubclass(RecordError, FdmlError) and issubclass(ParameterError, FdmlError)


# --- maneuvers ---------------------------------------------------------------------------------------


def test_time_vector():
    t = time_vector(10.0, 0.02)
    assert t.size == 501 and t[0] == 0.0 and t[-1] == pytest.approx(10.0, abs=1e-12)
    assert np.allclose(np.diff(t), 0.02, rtol=0, atol=1e-14)  # k*dt: rounding of numbers up to 10
    with pytest.raises(ParameterError):
        time_vector(-1.0, 0.02)


def test_doublet_shape_sign_and_amplitude():
    t = time_vector(5.0, 0.01)
    u = doublet(t, 0.02, start=1.0, width=0.5)
    assert np.all(u[(t >= 1.0 - 1e-9) & (t < 1.5 - 1e-9)] == 0.02)  # positive first (TE down)
    assert np.all(u[(t >= 1.5 - 1e-9) & (t < 2.0 - 1e-9)] == -0.02)
    assert np.all(u[(t < 1.0 - 1e-9) | (t >= 2.0 - 1e-9)] == 0.0)
    assert doublet(t, -0.02)[150] == 0.02  # a negative amplitude flips the pulses


def test_rise_smooths_edges_and_keeps_widths_and_areas():
    dt, rise, amp = 0.001, 0.2, 0.02
    t = time_vector(5.0, dt)
    u = doublet(t, amp, start=1.0, width=0.5, rise=rise)
    # raised-cosine ramp: slope at most (jump) pi/(2 rise); the middle edge jumps by 2 amp
    assert np.max(np.abs(np.diff(u))) / dt <= 2 * amp * np.pi / (2 * rise) * (1 + 1e-6)
    # the ramps are centred on the edges: up to t = 1.3 s (flat top) the integral is amp * 0.3 s,
    # as for sharp edges (trapezoid error on the C1 ramp ~dt^2/12 amp pi^2/(2 rise^2) ~ 1e-6 of it)
    first = t <= 1.3 + 1e-9
    assert integrate.trapezoid(u[first], t[first]) == pytest.approx(amp * 0.3, rel=1e-5)
    assert u[np.searchsorted(t, 1.0)] == pytest.approx(amp / 2)  # half-way at the nominal edge
    assert integrate.trapezoid(u, t) == pytest.approx(0.0, abs=1e-12)
    assert u[np.searchsorted(t, 1.0 - rise / 2) - 1] == 0.0  # flat before the first ramp
    with pytest.raises(ParameterError, match="rise time"):
        doublet(t, rise=0.6, width=0.5)


def test_3211_pulse_widths_and_signs():
    dt, unit = 0.01, 0.3
    t = time_vector(6.0, dt)
    u = three_two_one_one(t, 0.01, start=0.5, unit=unit)
    nz = u != 0
    edges = np.flatnonzero(np.diff(np.sign(u)) != 0) + 1
    runs = np.split(u, edges)
    pulses = [r for r in runs if r[0] != 0]
    assert [int(round(r.size * dt / unit)) for r in pulses] == [3, 2, 1, 1]
    assert [np.sign(r[0]) for r in pulses] == [1, -1, 1, -1]
    assert np.all(np.abs(u[nz]) == 0.01)
    assert t[np.flatnonzero(nz)[0]] == pytest.approx(0.5)
    assert t[np.flatnonzero(nz)[-1]] == pytest.approx(0.5 + 7 * unit - dt)


def test_multisine_peak_band_and_start():
    t = time_vector(20.0, 0.02)
    lo, hi, K = 0.5, 8.0, 12
    u = multisine(t, 0.03, lo, hi, K)
    assert np.max(np.abs(u)) == pytest.approx(0.03, rel=1e-14)  # peak scaled to the amplitude
    assert u[0] == 0.0 and u[-1] == 0.0  # starts (and ends) at zero
    w = multisine_frequencies(t, lo, hi, K)
    assert w.size == K and w[0] >= lo and w[-1] <= hi
    # each component is a whole number of periods over T: DFT of one period (n-1 samples)
    spec = np.abs(np.fft.rfft(u[:-1])) ** 2
    bins = np.round(w * 20.0 / (2 * np.pi)).astype(int)
    assert np.allclose(bins * 2 * np.pi / 20.0, w)
    out = np.delete(spec, bins)
    assert out.sum() < 1e-20 * spec.sum()  # no power outside the chosen harmonics (rounding only)
    assert np.allclose(spec[bins], spec[bins].mean(), rtol=1e-10)  # flat amplitude spectrum
    crest = lambda v: np.max(np.abs(v)) / np.std(v)  # noqa: E731
    with pytest.raises(ParameterError, match="rng"):
        multisine(t, 0.01, lo, hi, K, phases="random")
    rng = np.random.default_rng(3)
    randoms = [multisine(t, 0.01, lo, hi, K, phases="random", rng=rng) for _ in range(20)]
    assert all(np.max(np.abs(r)) == pytest.approx(0.01) for r in randoms)
    # Schroeder phases beat every one of 20 random-phase draws on crest factor (2.1 vs 2.2-3.2)
    assert crest(u) < min(crest(r) for r in randoms)
    with pytest.raises(ParameterError, match="harmonics"):
        multisine(t, 0.01, lo, hi, 1000)
    with pytest.raises(ParameterError, match="Nyquist"):
        multisine(t, 0.01, lo, 200.0)


def test_make_input_dispatch():
    t = time_vector(10.0, 0.02)
    np.testing.assert_array_equal(make_input("doublet", t, 0.01, width=0.7), doublet(t, 0.01, width=0.7))
    np.testing.assert_array_equal(make_input("3211", t, 0.01), three_two_one_one(t, 0.01))
    np.testing.assert_array_equal(make_input("multisine", t, 0.01, omega_hi=5.0), multisine(t, 0.01, omega_hi=5.0))
    with pytest.raises(ParameterError, match="unknown input kind"):
        make_input("chirp", t, 0.01)
    with pytest.raises(ParameterError, match="unknown option"):
        make_input("doublet", t, 0.01, unit=0.3)


def test_dryden_variance_and_correlation():
    sigma, U, L, dt = 2.0, 50.0, 10.0, 0.05
    t = time_vector(2000.0, dt)
    a = dryden_gust(t, sigma, U, L, rng=np.random.default_rng(2024))
    wg = a * U
    n_L = U * t[-1] / L  # correlation lengths in the record: 10 000
    # Var(s^2)/sigma^4 = (2/T) int rho^2 = 1.25 L/(U T) for rho = (1 - x/2) e^-x, x = U tau/L
    rel = np.sqrt(1.25 / n_L)  # 1.1 %
    assert np.var(wg) == pytest.approx(sigma**2, rel=4 * rel)
    # Var(mean) = sigma^2 (int rho)/T = sigma^2 L/(U T)
    assert abs(np.mean(wg)) < 4 * sigma * np.sqrt(1 / n_L)
    # autocorrelation at one scale length: (1 - 1/2) e^-1 = 0.184 (its standard error <= 1.4 %)
    k = int(round(L / U / dt))
    rho = np.mean(wg[:-k] * wg[k:]) / np.var(wg)
    assert rho == pytest.approx(0.5 / np.e, abs=4 * np.sqrt(1.9 / n_L))
    # the one-sided spectrum integrates to sigma^2 (QUADPACK to ~1e-10)
    total = integrate.quad(dryden_psd, 0, np.inf, args=(sigma, U, L), epsrel=1e-10)[0]
    assert total == pytest.approx(sigma**2, rel=1e-8)
    with pytest.raises(ParameterError, match="rng"):
        dryden_gust(t, sigma, U, L, rng=None)


def test_simulate_maneuver_noise_fraction_as_the_command_line():
    """noise=0.02 is 2 % of each output's RMS about its mean, as ``fdml simulate --noise 0.02`` (issue 9)."""
    model = make_model("dimensional", "navion")
    clean = simulate_maneuver(model, "3211", duration=20.0, dt=0.02, seed=4)
    noisy = simulate_maneuver(model, "3211", duration=20.0, dt=0.02, seed=4, noise=0.02)
    assert noisy.meta["noise_fraction"] == 0.02
    for k in ("alpha", "q", "az"):
        std = 0.02 * np.std(clean[k])
        assert noisy.meta["noise"][k] == pytest.approx(std, rel=1e-12)
        # 1001 samples: the sample std of the added noise is within 4 x 1/sqrt(2 n) = 9 % of std
        assert np.std(noisy[k] - clean[k]) == pytest.approx(std, rel=0.09)
    for bad in (-0.1, float("nan"), float("inf"), "0.02", True, [0.02]):
        with pytest.raises(ParameterError, match="noise"):
            simulate_maneuver(model, "3211", noise=bad)


@pytest.mark.parametrize(
    "bad, message",
    [
        (-0.1, "noise must be finite and >= 0, got -0.1"),
        (float("nan"), "noise must be finite and >= 0, got nan"),
        ("0.02", "noise must be a fraction of each output's RMS"),
        (True, "noise must be a fraction of each output's RMS"),
        ({"beta": 0.01}, "unknown noise channel(s) beta; channels: alpha, q, az, theta, qdot"),
        ({"q": -1.0}, "noise std for q must be finite and >= 0 (rad/s), got -1.0"),
        ({"az": "x"}, "noise std for az must be a number (g), got 'x'"),
    ],
)
def test_one_noise_check_for_every_entry_point(bad, message):
    """Issue 22: the simulator, add_noise, the design's prediction, Monte Carlo and the diagnosis' truths
    refuse a bad noise level with the same error, from fdml.record.check_noise."""
    from fdml.design.prediction import noise_stds as design_noise_stds
    from fdml.diagnose.truth import simulate_truth
    from fdml.montecarlo import monte_carlo
    from fdml.record import add_noise

    model = make_model("steady", "navion")
    clean = simulate_maneuver(model, "3211", duration=4.0, dt=0.02, seed=1)
    calls = [
        lambda: simulate_maneuver(model, "3211", duration=4.0, noise=bad, seed=1),
        lambda: add_noise(clean, bad, np.random.default_rng(0)),
        lambda: design_noise_stds(clean, bad),
        lambda: monte_carlo({"kind": "steady", "aircraft": "navion"}, n=5, noise=bad),
    ]
    if not isinstance(bad, dict):
        calls.append(lambda: simulate_truth(model, None, duration=4.0, noise=bad))
    for call in calls:
        with pytest.raises(ParameterError) as exc:
            call()
        assert message in str(exc.value)


def test_cli_simulate_noise_is_the_library_noise(tmp_path):
    """The command line passes --noise through: its record equals simulate_maneuver's, sample for sample."""
    from fdml.cli import main
    from fdml.record import read_csv

    out = tmp_path / "r.csv"
    assert (
        main(
            [
                "simulate",
                "--aircraft",
                "navion",
                "--model",
                "dimensional",
                "--noise",
                "0.03",
                "--seed",
                "5",
                "--duration",
                "6",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    lib = simulate_maneuver(make_model("dimensional", "navion"), "3211", duration=6.0, noise=0.03, seed=5)
    cli = read_csv(out)
    for k in ("de", "alpha", "q", "az"):
        np.testing.assert_allclose(cli[k], lib[k], rtol=0, atol=1e-15)  # CSV keeps 17 digits
