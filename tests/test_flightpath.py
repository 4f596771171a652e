"""Data-compatibility check: known sensor errors injected into exact kinematics, and the real records.

The synthetic truth is made independently of fdml.flightpath: a short-period response (scipy lsim)
gives smooth q and a_z; the kinematic equations are integrated on a grid five times finer than
the record with their own RK4; then the sensor models of fdml.flightpath corrupt the samples.
"""

import math

import numpy as np
import pytest
from scipy import signal
from scipy.interpolate import CubicSpline

from fdml.constants import DEG, G0
from fdml.errors import FdmlError, RecordError
from fdml.flightpath import PARAMETERS, apply_corrections, check_compatibility, noise_level
from fdml.io import data_path, load_record
from fdml.record import Record

#: Noise levels of the Twin Otter at 50 Hz (third-difference estimates, see fdml.flightpath.noise_level).
NOISE = {"q": 2e-4, "az": 1e-3, "ax": 5e-4, "alpha": 1e-4, "theta": 1e-4, "V": 0.02, "h": 0.15}
#: Injected sensor errors (measured = K true(t - tau) + b).
ERRORS = {
    "b_q": 0.002,
    "K_q": 1.05,
    "b_az": 0.02,
    "b_ax": 0.005,
    "K_alpha": 1.1,
    "b_alpha": 0.01,
    "tau_alpha": 0.08,
    "tau_theta": 0.04,
}


def _truth(T=8.0, dt=0.02, fine=5, U=60.0, alpha0=0.06, h0=1000.0):
    """Exact kinematics on a fine grid: returns (t_fine, signals)."""
    dtf = dt / fine
    tf = np.arange(0, T + 1e-9, dtf)
    de = np.zeros_like(tf)
    start, level = 1.0, 0.0
    for width, sign in ((3, 1), (2, -1), (1, 1), (1, -1), (0, 0)):
        ramp = np.clip((tf - start) / 0.1, 0, 1)
        de += (0.03 * sign - level) * 0.5 * (1 - np.cos(np.pi * ramp))
        level, start = 0.03 * sign, start + 0.4 * width
    Za, Zde, Ma, Mq, Mde = -1.5, -0.1, -8.0, -2.5, -10.0
    _, y, _ = signal.lsim(([[Za, 1.0], [Ma, Mq]], [[Zde], [Mde]], np.eye(2), np.zeros((2, 1))), de, tf)
    q = y[:, 1]
    # trim (alpha_dot = 0, theta = alpha, a_x = sin(theta) + 0.01): a_z cos a - a_x sin a + 1 = 0
    sa = math.sin(alpha0)
    az = (sa**2 + 0.01 * sa - 1) / math.cos(alpha0) + (U / G0) * (Za * y[:, 0] + Zde * de)
    n = tf.size
    out = np.empty((n, 4))
    x = np.array([alpha0, alpha0, U, h0])  # alpha, theta, V, h

    def f(x, qi, azi):
        a, th, V, _h = x
        ax = math.sin(th) + 0.01
        gam = th - a
        return np.array(
            [
                qi + G0 / V * (azi * math.cos(a) - ax * math.sin(a) + math.cos(gam)),
                qi,
                G0 * (ax * math.cos(a) + azi * math.sin(a) - math.sin(gam)),
                V * math.sin(gam),
            ]
        )

    out[0] = x
    for k in range(n - 1):
        qm, zm = 0.5 * (q[k] + q[k + 1]), 0.5 * (az[k] + az[k + 1])
        k1 = f(x, q[k], az[k])
        k2 = f(x + 0.5 * dtf * k1, qm, zm)
        k3 = f(x + 0.5 * dtf * k2, qm, zm)
        k4 = f(x + dtf * k3, q[k + 1], az[k + 1])
        x = x + dtf / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out[k + 1] = x
    return tf, {
        "de": de,
        "q": q,
        "az": az,
        "alpha": out[:, 0],
        "theta": out[:, 1],
        "V": out[:, 2],
        "h": out[:, 3],
        "ax": np.sin(out[:, 1]) + 0.01,
    }


_TRUTH = {}


def _measured(errors, seed, dt=0.02, fine=5, drop=()):
    if "t" not in _TRUTH:
        _TRUTH["t"], _TRUTH["s"] = _truth(dt=dt, fine=fine)
    tf, s = _TRUTH["t"], _TRUTH["s"]
    t = tf[::fine]
    p = {k: errors.get(k, v[0]) for k, v in PARAMETERS.items()}
    rng = np.random.default_rng(seed)

    def at(name, tau=0.0):
        return CubicSpline(tf, s[name])(np.clip(t - tau, tf[0], tf[-1]))

    def noise(k):
        return NOISE[k] * rng.standard_normal(t.size)

    sig = {
        "de": at("de"),
        "q": p["K_q"] * at("q") + p["b_q"] + noise("q"),
        "az": p["K_az"] * at("az", p["tau_az"]) + p["b_az"] + noise("az"),
        "ax": at("ax") + p["b_ax"] + noise("ax"),
        "alpha": p["K_alpha"] * at("alpha", p["tau_alpha"]) + p["b_alpha"] + noise("alpha"),
        "theta": at("theta", p["tau_theta"]) + noise("theta"),
        "V": p["K_V"] * at("V") + noise("V"),
        "h": at("h") + noise("h"),
    }
    sig = {k: v for k, v in sig.items() if k not in drop}
    return Record(t, sig, name=f"kinematics-{seed}", meta={"U": 60.0}), {k: at(k) for k in ("alpha", "theta", "q")}


def test_recovers_injected_errors_within_three_standard_errors():
    rec, _ = _measured(ERRORS, seed=11)
    res = check_compatibility(rec)
    assert res.converged
    assert set(res.params) == set(ERRORS)
    for k, v in ERRORS.items():
        p = res.params[k]
        assert abs(p.value - v) < 3 * p.stderr, (k, p.value, v, p.stderr)
        # every injected error is large enough to be detected
        assert p.z > 3, (k, p.z)
    assert res.residual_rms["alpha"] < 3 * NOISE["alpha"]
    assert any("significant" in f for f in res.findings)
    assert "K_az" in res.fixed and "scale error looks like a bias" in res.fixed["K_az"][1]


def test_consistent_record_is_reported_consistent():
    rec, _ = _measured({}, seed=3)
    res = check_compatibility(rec)
    for p in res.params.values():
        assert p.z < 3, (p.name, p.value, p.stderr)
    assert res.findings[0].startswith("the record is kinematically consistent")


def test_correction_restores_the_true_signals():
    rec, true = _measured(ERRORS, seed=5)
    res = check_compatibility(rec, correct=True)
    c = res.record
    assert c is not None and c.meta["compatibility"]["K_alpha"] == pytest.approx(res.params["K_alpha"].value)
    inner = slice(10, -10)  # the time shift holds the end values over tau at the ends
    err_before = np.std((rec["alpha"] - true["alpha"])[inner])
    err_after = np.sqrt(np.mean((c["alpha"] - true["alpha"])[inner] ** 2))
    # the corrected alpha is within a few noise levels of the truth (before: 10 % scale and 0.08 s lag)
    assert err_after < 5 * NOISE["alpha"] < err_before
    assert np.sqrt(np.mean((c["q"] - true["q"]) ** 2)) < 2 * NOISE["q"]
    # applying the estimates again through the public helper gives the same record
    np.testing.assert_allclose(apply_corrections(rec, res.values())["alpha"], c["alpha"])


def test_requested_accelerometer_scale_and_shift():
    errors = {**ERRORS, "K_az": 1.03, "tau_az": 0.03}
    rec, _ = _measured(errors, seed=2)
    res = check_compatibility(rec, estimate=list(errors))
    for k, v in errors.items():
        p = res.params[k]
        assert abs(p.value - v) < 3 * p.stderr, (k, p.value, v, p.stderr)
    # with a_z near -1 g a scale error is nearly a bias: their estimates are strongly correlated
    i, j = res.names.index("K_az"), res.names.index("b_az")
    assert abs(res.corr[i, j]) > 0.9


def test_without_attitude_and_altitude():
    errors = {"b_az": 0.02, "b_ax": 0.005, "K_alpha": 1.1, "tau_alpha": 0.08}
    rec, _ = _measured(errors, seed=7, drop=("theta", "h"))
    res = check_compatibility(rec)
    assert set(res.params) == set(errors)
    assert "no theta" in res.fixed["b_q"][1] and "no altitude" in res.fixed["b_alpha"][1]
    for k, v in errors.items():
        assert abs(res.params[k].value - v) < 3 * res.params[k].stderr, k
    assert res.outputs == ("alpha", "V")


def test_fix_and_bad_arguments():
    rec, _ = _measured(ERRORS, seed=1)
    res = check_compatibility(rec, fix={"K_q": 1.05})
    assert "K_q" not in res.params and res.fixed["K_q"] == (1.05, "fixed by the caller")
    with pytest.raises(FdmlError, match="unknown compatibility parameter"):
        check_compatibility(rec, estimate=["b_beta"])
    trimmed = rec.remove_trim("first")
    with pytest.raises(RecordError, match="trim kept"):
        check_compatibility(trimmed)
    no_v = Record(rec.t, {k: rec[k] for k in ("de", "alpha", "q", "az")}, name="bare")
    with pytest.raises(RecordError, match="no airspeed"):
        check_compatibility(no_v)
    assert check_compatibility(no_v, U=60.0).outputs == ("alpha",)


def test_sensor_parameters_on_the_outputs_reuse_the_integration(monkeypatch):
    """Issue 22: K_alpha, b_alpha, tau_alpha, tau_theta and h0 act on the integrated outputs, so their
    Jacobian columns integrate nothing again; the outputs equal those of a fresh integration."""
    import fdml.flightpath as fp

    rec, _ = _measured(ERRORS, seed=4)
    free, fixed, _ = fp._choose_free(rec, None, None)

    def problem():
        return fp._Problem(rec, free, fixed, fp.DEFAULT_MAX_SHIFT, 60.0)

    prob = problem()
    p = prob.unpack(fp._start(prob, free, fp.DEFAULT_MAX_SHIFT)[0])
    changes = {"K_alpha": 1.02, "b_alpha": 0.01, "tau_alpha": 0.05, "tau_theta": -0.03, "h0": 1001.0, "b_q": 0.001}
    fresh = {k: problem().simulate({**p, k: v}) for k, v in changes.items()}
    real, calls = fp._integrate, []
    monkeypatch.setattr(fp, "_integrate", lambda *args: calls.append(1) or real(*args))
    prob.simulate(p)
    for k, v in changes.items():
        y = prob.simulate({**p, k: v})
        assert len(calls) == (2 if k == "b_q" else 1), k  # b_q corrects an input of the integration
        for out in y:
            # a fresh problem computes the same way: equal to rounding
            np.testing.assert_allclose(y[out], fresh[k][out], rtol=1e-13, atol=1e-12, err_msg=f"{k} {out}")


def test_noise_level_estimator():
    rng = np.random.default_rng(8)
    t = np.arange(0, 100, 0.02)
    x = np.sin(2 * t) + 0.003 * rng.standard_normal(t.size)
    # third differences of the sine are (0.04)^3 * 8 ~ 5e-4 of its amplitude: far below the noise.
    # The MAD has 37 % efficiency and the differences overlap (MA(3)): with 5000 samples the
    # relative standard deviation is about 0.03, so 10 % is three of them.
    assert noise_level(x) == pytest.approx(0.003, rel=0.1)


@pytest.mark.slow
def test_standard_errors_match_the_scatter():
    """Over seeded repetitions the errors divided by their standard errors have unit spread."""
    z = {k: [] for k in ERRORS}
    for seed in range(12):
        rec, _ = _measured(ERRORS, seed=100 + seed)
        res = check_compatibility(rec)
        for k, v in ERRORS.items():
            z[k].append((res.params[k].value - v) / res.params[k].stderr)
    for k, zs in z.items():
        s = float(np.sqrt(np.mean(np.square(zs))))
        # 12 draws: the RMS of unit normals lies in [0.6, 1.45] with 95 % probability (chi^2_12)
        assert 0.5 < s < 1.6, (k, s)


# --- the real records ----------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize(
    "rel",
    [
        "twin_otter/totter_lon_020213f1_017.mat",
        "twin_otter/totter_lon_020213f1_018.mat",
        "hfb320/hfb320_1_10.asc",
        "attas/fAttasElv1.mat",
    ],
)
def test_real_records(rel):
    rec = load_record(data_path(rel))
    res = check_compatibility(rec)
    assert res.converged
    # the angle-of-attack vanes lag the rate gyro on all three aircraft (0.02 s Twin Otter,
    # 0.22 s HFB-320, 0.11 s ATTAS)
    assert res.params["tau_alpha"].value > 3 * res.params["tau_alpha"].stderr
    if rec.has("h"):
        assert "b_alpha" in res.params
    else:
        assert "no altitude" in res.fixed["b_alpha"][1]


@pytest.mark.slow
def test_twin_otter_matches_sidpacs_own_gyro_bias_correction():
    """fdata = fdatao + SIDPAC's corrections: the q offset between them is SIDPAC's gyro bias."""
    path = data_path("twin_otter/totter_lon_020213f1_017.mat")
    corrected, original = load_record(path), load_record(path, original=True)
    c = float(np.mean(corrected["q"] - original["q"]))
    a, b = check_compatibility(corrected), check_compatibility(original)
    # measured = true + b_q: removing c from the measurements changes the estimate by -c
    assert abs((b.params["b_q"].value + c) - a.params["b_q"].value) < b.params["b_q"].stderr


def test_attas_gyro_bias_agrees_with_the_book():
    """Jategaonkar's flight-path reconstruction of the ATTAS records (umr_reg_attas.m, 2nd edition,
    three maneuvers fitted together) gives b_q = 3.40891e-3 rad/s."""
    res = check_compatibility(load_record(data_path("attas/fAttasElv1.mat")))
    # one maneuver and a longitudinal model against three maneuvers and six degrees of freedom: 5 %
    assert res.params["b_q"].value == pytest.approx(3.40891e-3, rel=0.05)
    assert res.params["b_q"].value / DEG == pytest.approx(0.19, abs=0.01)
