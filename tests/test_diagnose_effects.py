"""fdml.diagnose effects: exact nesting, closed forms, the open registry, and time-domain truths."""

import math

import numpy as np
import pytest

import fdml
from fdml.constants import G0
from fdml.errors import ParameterError
from fdml.models.effect_library import to_unsteady_equivalent
from fdml.models.effects import (
    OutputEffect,
    Param,
    get_effect,
    register_effect,
    registered_effects,
    scale_rows,
    unregister_effect,
    with_gust,
)

OMEGA = np.linspace(0.3, 12.0, 40)


def _models():
    for kind in ("steady", "unsteady", "derivatives", "dimensional"):
        for gust in (False, True):
            yield fdml.make_model(kind, "navion", gust=gust)


@pytest.mark.parametrize("model", list(_models()), ids=lambda m: m.describe())
def test_every_effect_at_its_null_is_the_base_model(model):
    # DIAGNOSIS.md 3.4 nesting gate: the augmentation at its null reproduces the base outputs
    # (max relative error < 1e-10); anything larger would bias every likelihood ratio.
    base = model.evaluate(OMEGA)
    tested = 0
    for eff in registered_effects():
        if eff.kind != "deterministic" or eff.applicable(model, inputs=model.inputs):
            continue
        r = eff.augment(model).evaluate(OMEGA)
        for a, b in ((r.G, base.G), (r.H, base.H), (r.P, base.P)):
            assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(b))
        tested += 1
    assert tested >= 11  # every library effect that applies to this base model was checked


def test_steady_model_is_the_unsteady_model_with_every_lag_off():
    for gust in (False, True):
        s = fdml.make_model("steady", "navion", gust=gust)
        u = to_unsteady_equivalent(s)
        assert u.kind == "unsteady"
        a, b = s.evaluate(OMEGA), u.evaluate(OMEGA)
        assert np.max(np.abs(a.G - b.G)) <= 1e-12 * np.max(np.abs(a.G))


def test_output_delay_is_a_pure_phase_lag_on_its_channel():
    m = fdml.make_model("derivatives", "navion")
    tau = 0.03
    aug = get_effect("time_delay@q").augment(m).with_values({"tau_q": tau})
    G0_, G1 = m.evaluate(OMEGA).G, aug.evaluate(OMEGA).G
    ratio = G1[:, 1, 0] / G0_[:, 1, 0]
    assert np.allclose(np.abs(ratio), 1.0, atol=1e-12)
    assert np.allclose(np.angle(ratio), -OMEGA * tau, atol=1e-12)  # -omega tau, linear in omega
    assert np.allclose(G1[:, [0, 2]], G0_[:, [0, 2]], atol=0)  # other channels untouched


def test_accelerometer_offset_adds_minus_x_qdot_over_g():
    m = fdml.make_model("dimensional", "navion")
    x = 1.2
    aug = get_effect("sensor_offset@az").augment(m).with_values({"x_az": x})
    a, b = m.evaluate(OMEGA), aug.evaluate(OMEGA)
    s = 1j * OMEGA
    assert np.allclose(b.G[:, 2, 0], a.G[:, 2, 0] - x / G0 * s * a.G[:, 1, 0], rtol=1e-12)
    # the boundary term of q_dot's finite transform: s q~ - d_q
    assert np.allclose(b.H[:, 2, 1], a.H[:, 2, 1] - x / G0 * (s * a.H[:, 1, 1] - 1.0), rtol=1e-12)


def test_actuator_lag_and_mode_closed_forms():
    m = fdml.make_model("steady", "navion")
    T = 0.05
    aug = get_effect("actuator_lag@de").augment(m).with_values({"T_act": T})
    s = 1j * OMEGA
    assert np.allclose(aug.evaluate(OMEGA).G[:, :, 0], m.evaluate(OMEGA).G[:, :, 0] / (1 + s * T)[:, None])
    w, z, r = 9.0, 0.04, 0.03
    mode = get_effect("structural_mode@q,az").augment(m).with_values({"omega_s": w, "zeta_s": z, "r_q": r, "r_az": 0.0})
    d = mode.evaluate([w]).G[0, 1, 0] - m.evaluate([w]).G[0, 1, 0]
    assert abs(abs(d) - r / (2 * z)) < 1e-9  # resonance peak r/(2 zeta)


def test_structural_mode_frequency_and_damping_are_nuisance_not_tested():
    m = fdml.make_model("steady", "navion")
    aug = get_effect("structural_mode@q,az").augment(m)
    free = set(aug.parameters.free_names) - set(m.parameters.free_names)
    assert free == {"r_q", "r_az"}


def test_user_registers_an_effect_in_a_few_lines():
    def gyro_lag(s, p, G, H, P, root):
        return scale_rows(G, H, P, 1, 1.0 / (1.0 + s * p["T_gyro"]))

    eff = register_effect(
        OutputEffect("gyro_lag", "q", (Param("T_gyro", 0.0, lower=0.0, plausible=(0, 0.1), unit="s"),), gyro_lag)
    )
    try:
        assert get_effect("gyro_lag@q") is eff
        m = fdml.make_model("steady", "navion")
        aug = eff.augment(m)
        assert "T_gyro" in aug.parameters.free_names
        assert np.array_equal(aug.evaluate(OMEGA).G, m.evaluate(OMEGA).G)
        with pytest.raises(ParameterError, match="already registered"):
            register_effect(eff)
    finally:
        unregister_effect("gyro_lag@q")
    assert all(e.key != "gyro_lag@q" for e in registered_effects())


def test_an_effect_given_by_its_factors_equals_its_function():
    # the gyro lag written as a function of (G, H, P) and as factors scaling q's row: the same response,
    # and the same forced sensitivities (the factors' path scales the solve's; the function's goes
    # through the response's derivatives, whose differences carry ~1e-10 of rounding)
    param = (Param("T_gyro", 0.0, lower=0.0, plausible=(0, 0.1), unit="s"),)

    def gyro_lag(s, p, G, H, P, root):
        return scale_rows(G, H, P, 1, 1.0 / (1.0 + s * p["T_gyro"]))

    def gyro_factors(s, p, root):
        rows = np.ones((s.size, len(root.outputs)), complex)
        rows[:, 1] = 1.0 / (1.0 + s * p["T_gyro"])
        return rows, None, None

    m = fdml.make_model("dimensional", "navion")
    by_fn = OutputEffect("gyro_lag", "q", param, gyro_lag).augment(m)
    by_factors = OutputEffect("gyro_lag", "q", param, factors=gyro_factors).augment(m)
    vals = {"T_gyro": 0.04}
    np.testing.assert_allclose(by_factors.evaluate(OMEGA, vals).G, by_fn.evaluate(OMEGA, vals).G, rtol=1e-14)
    rng = np.random.default_rng(4)
    u, d = (rng.normal(size=(OMEGA.size, k)) + 1j * rng.normal(size=(OMEGA.size, k)) for k in (1, 2))
    names = list(by_fn.parameters.free_model_names)
    (_, a), (_, b) = (x.forced_sensitivity(OMEGA, vals, names, u, d) for x in (by_fn, by_factors))
    assert np.abs(a - b).max() <= 1e-9 * np.abs(a).max()
    with pytest.raises(ParameterError, match="either fn or factors"):
        OutputEffect("gyro_lag", "q", param)
    with pytest.raises(ParameterError, match="either fn or factors"):
        OutputEffect("gyro_lag", "q", param, gyro_lag, factors=gyro_factors)
    # factors of the wrong shape (one row per output expected): named, not a numpy broadcasting error
    wrong = OutputEffect("gyro_lag", "q", param, factors=lambda s, p, root: (np.ones((s.size, 2)), None, None))
    with pytest.raises(ParameterError, match=r"gyro_lag@q: its factors give rows of shape \(40, 2\), not \(40, 3\)"):
        wrong.augment(m).evaluate(OMEGA[:40], vals)


def test_candidate_needing_a_missing_channel_says_why():
    m = fdml.make_model("steady", "navion")
    why = get_effect("gust_lag@alpha_w").applicable(m, inputs=("de",))
    assert why is not None and "alpha_w" in why
    why = get_effect("lift_lag@alpha").applicable(fdml.make_model("dimensional", airspeed=50.0))
    assert why is not None and "chord" in why


def test_with_gust_keeps_the_fitted_values():
    m = fdml.make_model("derivatives", "navion").with_values({"Cm_q": -20.0})
    g = with_gust(m)
    assert g.gust and g.parameters.values["Cm_q"] == -20.0
    assert np.allclose(g.evaluate(OMEGA).G[:, :, 0], m.evaluate(OMEGA).G[:, :, 0])


@pytest.mark.parametrize(
    "key,values",
    [
        ("time_delay@q", {"tau_q": 0.03}),
        ("actuator_lag@de", {"T_act": 0.05}),
        ("sensor_offset@az", {"x_az": 1.5}),
        ("structural_mode@q,az", {"r_q": 0.03, "r_az": 0.03, "omega_s": 9.0, "zeta_s": 0.04}),
        ("lift_lag@alpha", {"y_w": 0.36}),
    ],
)
def test_time_domain_truth_matches_the_augmented_model(key, values):
    # The validation truths are simulated in the time domain (fdml.simulate + the effect where it
    # acts); the frequency-domain augmentation must explain them.  Noise-free, the truth model's
    # residual (with fitted boundary terms and biases only) must be far below the effect itself:
    # < 1 % of the signal, while the base model misses by several per cent.
    from fdml.diagnose.data import analysis_data
    from fdml.diagnose.likelihood import noise_bands
    from fdml.diagnose.shrink import frozen_fit
    from fdml.diagnose.truth import simulate_truth

    base = fdml.make_model("steady", "navion")
    rec = simulate_truth(base, key, values, maneuver="3211", noise=0.0, seed=1)
    data = analysis_data(rec, (0.3, 12.0))
    nb = noise_bands(data)
    opts = {"outputs": None, "boundary": "estimated", "biases": "auto"}
    z = np.concatenate([d.z for d in data.spectra])
    aug = get_effect(key).augment(base).with_values(values)
    rel = lambda f: np.sqrt(np.mean(np.abs(f.full_residual()) ** 2, 0) / np.mean(np.abs(z) ** 2, 0))  # noqa
    r_truth, r_base = rel(frozen_fit(data, aug, nb, opts)), rel(frozen_fit(data, base, nb, opts))
    assert np.max(r_truth) < 0.01
    assert np.max(r_base) > 5 * np.max(r_truth)


def test_actuator_lag_truth_is_the_continuous_lag_of_the_recorded_elevator():
    """The truth's lagged elevator is not linear between the samples: it is simulated on a finer grid.

    Reference: the dimensional Navion with the lag state d_a' = (de - d_a)/T, de linear between the
    record's samples, integrated by DOP853 (tests/independent_truth.py's derivatives; no fdml code).
    """
    from independent_truth import NAVION, U_NAVION
    from scipy import integrate

    from fdml.diagnose.truth import simulate_truth

    T, p = 0.05, NAVION
    base = fdml.make_model("dimensional", "navion")
    rec = simulate_truth(base, "actuator_lag@de", {"T_act": T}, maneuver="3211", duration=8.0, noise=0.0, seed=1)
    t, de = rec.t, rec["de"]

    def rates(tt, x):  # alpha, q and the actuator's deflection
        lagged = p["Z_de"] * x[2], p["M_de"] * x[2]
        a_dot = p["Z_a"] * x[0] + (1 + p["Z_q"]) * x[1] + lagged[0]
        return [a_dot, p["M_a"] * x[0] + p["M_q"] * x[1] + lagged[1], (np.interp(tt, t, de) - x[2]) / T]

    step = (t[1] - t[0]) / 2
    x = integrate.solve_ivp(rates, t[[0, -1]], [0.0] * 3, "DOP853", t_eval=t, rtol=1e-11, atol=1e-14, max_step=step).y
    ref = {"alpha": x[0], "q": x[1], "az": U_NAVION / G0 * (np.array(rates(t, x))[0] - x[1])}
    for ch, y in ref.items():
        # the hold of the lagged elevator on a grid 16 times finer: (1/16)^2 of the 0.4 % of peak q that
        # holding it on the record's samples gave; measured 1.5e-5
        assert np.max(np.abs(rec[ch] - y)) < 1e-4 * np.max(np.abs(y)), ch


def test_accelerometer_offset_truth_on_a_base_with_an_input_delay():
    """a_z - x q_dot/g where the base delays its elevator by 0.7 samples: q_dot is that of the delayed input.

    Reference: q of a simulation on a grid 64 times finer, differenced there (central differences:
    an error of (dt/64)^2, measured below 4e-6 of the peak a_z).  Holding the delayed input's samples
    linear on the record's grid gave 1.4e-3.
    """
    from fdml.diagnose.truth import simulate_truth
    from fdml.maneuvers import time_vector
    from fdml.simulate import simulate

    base = fdml.make_model("steady", "navion").with_values(tau_de=0.014)
    kw = dict(maneuver="3211", duration=8.0, noise=0.0, seed=1)
    rec = simulate_truth(base, "sensor_offset@az", {"x_az": 1.5}, **kw)
    plain = simulate_truth(base, None, {}, **kw)
    t, fine = rec.t, 64
    tf = time_vector(8.0, (t[1] - t[0]) / fine)
    q_dot = np.gradient(simulate(base, tf, {"de": np.interp(tf, t, rec["de"])})["q"], tf)[::fine]
    want = plain["az"] - 1.5 * q_dot / G0
    assert np.max(np.abs(rec["az"] - want)) < 1e-4 * np.max(np.abs(want))


@pytest.mark.parametrize("kind", ["steady", "unsteady"])
def test_every_library_effect_has_an_independent_truth(kind):
    """Issue 22: on the harness's base models each applicable effect is a validation truth: a plain model
    (a freed parameter) or a time-domain form of its own in fdml.diagnose.truth.TRUTHS."""
    from fdml.diagnose.truth import TRUTHS
    from fdml.models.effects import root_model

    base = fdml.make_model(kind, "navion")
    missing = []
    for eff in registered_effects():
        if eff.kind != "deterministic" or eff.applicable(base) is not None:
            continue
        aug = eff.augment(base)
        if root_model(aug) is not aug and eff.key not in TRUTHS:
            missing.append(eff.key)
    assert missing == []


def test_every_truth_at_its_null_is_the_base_record():
    """A truth form at its effect's null changes nothing: the record equals the base model's, sample for
    sample (noise-free), so the withheld effect is the only difference a diagnosis can find."""
    from fdml.diagnose.truth import TRUTHS, simulate_truth

    base = fdml.make_model("steady", "navion")
    plain = simulate_truth(base, None, maneuver="3211", duration=8.0, noise=0.0, seed=2)
    for key in TRUTHS:
        if key in ("vane_filter", "downwash_lag@tail"):
            # outside the library (no null value); the textbook downwash delay has no null either
            # (its closed-form check is tests/test_downwash_effect.py)
            continue
        eff = get_effect(key)
        nulls = {p.name: 0.0 if p.null is None else p.null for p in eff.param_list(base)}
        if key == "structural_mode@q,az":
            nulls.update(omega_s=9.0, zeta_s=0.05)  # a mode with zero residues: r_q = r_az = 0
        rec = simulate_truth(base, key, nulls, maneuver="3211", duration=8.0, noise=0.0, seed=2)
        for ch in ("alpha", "q", "az"):
            # a zero delay interpolates at the samples themselves and a zero residue adds lsim of nothing:
            # equal to rounding (1e-12 of the signal)
            assert np.max(np.abs(rec[ch] - plain[ch])) <= 1e-12 * np.max(np.abs(plain[ch])), (key, ch)


def test_truth_noise_must_be_a_level():
    from fdml.diagnose.truth import simulate_truth

    with pytest.raises(ParameterError, match=">= 0"):
        simulate_truth(fdml.make_model("steady", "navion"), None, duration=4.0, noise=-0.05)


def test_coloured_noise_has_the_stated_low_frequency_excess():
    from fdml.diagnose.truth import COLOURED_LF_RATIO, sensor_noise

    rng = np.random.default_rng(5)
    n, dt = 2**16, 0.02
    x = sensor_noise(rng, n, dt, "coloured")
    P = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(n, dt) * 2 * math.pi
    lo = P[(f > 0.01) & (f < 0.05)].mean()
    hi = P[(f > 20) & (f < 60)].mean()
    # spectrum ratio 1 + 16/(1 + (w/0.5)^2) at w ~ 0.03 vs ~1 at w > 20: 17 within sampling error
    # (about 60 periodogram ordinates per band: relative s.e. ~ 13 %)
    assert 0.7 * (1 + COLOURED_LF_RATIO) < lo / hi < 1.3 * (1 + COLOURED_LF_RATIO)
