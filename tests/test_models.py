"""Models: analytic limits, independent implementations, published tables."""

import json
import math

import control
import numpy as np
import pytest
from scipy import integrate, special

from fdml import aero
from fdml.aircraft import Aircraft, get_aircraft, list_aircraft, load_aircraft
from fdml.constants import G0
from fdml.errors import AircraftError, ParameterError
from fdml.models import make_model, model_from_dict, model_to_dict
from fdml.models.effects import OutputEffect
from fdml.parameters import Role

OMEGA = np.linspace(0.1, 10.0, 100)


def dimensional_state_space(m):
    """python-control StateSpace of a dimensional model, written from its equations."""
    p = m.parameters.values
    A = np.array([[p["Z_a"], 1 + p["Z_q"]], [p["M_a"], p["M_q"]]])
    B = np.array([[p["Z_de"]], [p["M_de"]]])
    k = m.U / G0
    C = np.array([[1, 0], [0, 1], [k * p["Z_a"], k * p["Z_q"]]])  # a_z = (U/g)(alpha_dot - q)
    D = np.array([[0], [0], [k * p["Z_de"]]])
    return control.ss(A, B, C, D)


def test_presets_listed_and_described():
    assert list_aircraft() == ["do128", "navion", "sundowner"]
    for name in list_aircraft():
        ac = get_aircraft(name)
        assert ac.name == name
        text = ac.describe()
        assert "[assumed]" in text  # every preset flags its assumed values


def test_sundowner_derived_factors_match_theory():
    # THEORY.md 11.2 quotes rho U S/(2m) = 0.3682 1/s and rho U^2 S c/(2 Iy) = 10.33 1/s^2 (4 digits)
    ac = get_aircraft("sundowner")
    assert ac.k_z == pytest.approx(0.3682, abs=5e-5)
    assert ac.k_m == pytest.approx(10.33, abs=5e-3)
    assert ac.l_t == 4.38 and "l_t" in ac.assumed


def test_alternate_set_reproduces_wk_table1_unsteady_column():
    # WK Table 1 (THEORY.md 11.1), printed to 2 decimals: half a unit in the last place
    m = make_model("unsteady", "navion")
    d = m.derived()
    table = {"Cz_a": -4.99, "Cz_q": -4.82, "Cz_de": -0.51, "Cm_a": -1.00, "Cm_q": -12.77, "Cm_de": -1.42}
    for k, v in table.items():
        assert d[k] == pytest.approx(v, abs=0.005 + 1e-9), k
    # and the consistency relation Cm_q / Cz_q = l/c = 2.649 (THEORY.md 6)
    assert d["Cm_q"] / d["Cz_q"] == pytest.approx(2.6494, rel=1e-6)


def test_steady_derivatives_dimensional_agree():
    # three independent parameterisations of the same quasi-steady system; only rounding differs
    ac = get_aircraft("navion")
    st = make_model("steady", ac, gust=True)
    de = make_model("derivatives", ac, gust=True)
    di = make_model("dimensional", ac, gust=True)
    Gs, Gd, Gi = (m.frequency_response(OMEGA) for m in (st, de, di))
    assert np.allclose(Gs, Gd, rtol=1e-12, atol=0)
    assert np.allclose(Gs, Gi, rtol=1e-12, atol=0)


def test_dimensional_matches_python_control():
    m = make_model("dimensional", airspeed=60.0)
    sys = dimensional_state_space(m)
    ref = sys.frequency_response(OMEGA).complex  # (3, 1, n)
    assert np.allclose(m.frequency_response(OMEGA), ref, rtol=1e-12, atol=1e-14)


def test_derivatives_with_adot_matches_hand_solution():
    # alpha_dot terms: E xdot = A x + B u solved per frequency with numpy (independent of fdml's 2x2 solve)
    ac = get_aircraft("sundowner")
    m = make_model("derivatives", ac, adot=True).with_values(Cz_adot=-1.5, Cm_adot=-6.0)
    p = m.parameters.values
    kz, km, cu = ac.k_z, ac.k_m, ac.c_w / (2 * ac.U)
    E = np.array([[1 - kz * p["Cz_adot"] * cu, 0], [-km * p["Cm_adot"] * cu, 1]])
    A = np.array([[kz * p["Cz_a"], 1 + kz * p["Cz_q"] * cu], [km * p["Cm_a"], km * p["Cm_q"] * cu]])
    B = np.array([kz * p["Cz_de"], km * p["Cm_de"]])
    G = m.frequency_response(OMEGA)[:, 0, :]
    for i, w in enumerate(OMEGA):
        x = np.linalg.solve(1j * w * E - A, B)
        az = ac.U / G0 * (1j * w * x[0] - x[1])
        assert np.allclose(G[:, i], [x[0], x[1], az], rtol=1e-12)


def test_gust_column_steady_state_weathercocks():
    # THEORY.md 8: a constant gust gives alpha = -alpha_g, q = 0 (and so a_z = 0)
    for kind in ("unsteady", "steady", "derivatives", "dimensional"):
        m = make_model(kind, "sundowner", gust=True)
        g = m.frequency_response([1e-7])[:, 1, 0]
        # residual terms are O(omega) (and O(omega ln omega) for F): 1e-7 rad/s * lag times < 1e-5
        assert g[0] == pytest.approx(-1.0, abs=1e-5), kind
        assert abs(g[1]) < 1e-5 and abs(g[2]) < 1e-5, kind


def test_unsteady_tends_to_steady_at_low_frequency():
    # THEORY.md 9(b): with F = 0 the difference is O(omega * lag time); lag times here < 0.5 s
    ac = get_aircraft("sundowner")
    mu = make_model("unsteady", ac, gust=True).with_values(F=0.0)
    ms = make_model("steady", ac, gust=True)
    w = 1e-3
    Gu, Gs = mu.frequency_response([w]), ms.frequency_response([w])
    rel = np.abs(Gu - Gs) / np.abs(Gs).max(axis=0, keepdims=True)
    assert rel.max() < 10 * w * 0.5
    # ... and the lags matter at 5 rad/s (they are not a no-op)
    Gu5, Gs5 = mu.frequency_response([5.0]), ms.frequency_response([5.0])
    assert np.abs(Gu5 - Gs5).max() / np.abs(Gs5).max() > 0.05


def test_downwash_properties_and_theory_values():
    # THEORY.md 5: Sundowner, eps_ss = 1, l = 4.38 m: |E| = 1.05, 1.13, 1.43, 2.36 at 1, 5, 10, 20 rad/s
    ac = get_aircraft("sundowner")
    kw = dict(eps_ss=1.0, F=1.358, G=0.513, H=0.065, l=4.38, U=ac.U, c=ac.c_w)
    w = np.array([1.0, 5.0, 10.0, 20.0])
    E = aero.downwash(1j * w, **kw)
    assert np.allclose(np.abs(E), [1.05, 1.13, 1.43, 2.36], atol=0.005 + 1e-9)  # quoted to 2 decimals
    assert aero.downwash(np.array([0j]), **kw)[0] == pytest.approx(1.0)  # E(0) = eps_ss
    Em = aero.downwash(-1j * w, **kw)
    assert np.allclose(Em, np.conj(E), rtol=1e-14)  # conjugate symmetry: real responses
    # scipy's expi on complex input is the principal branch quoted in THEORY.md 5
    assert special.expi(1j) == pytest.approx(0.3374039229 + 2.5168793972j, abs=1e-9)


def test_downwash_wrong_branch_would_be_caught():
    # THEORY.md 5: -exp1(-z) drops j pi and changes E by about 53 % at 5 rad/s
    ac = get_aircraft("sundowner")
    s = 5j
    T = (4.38 - ac.c_w) / ac.U
    good = aero.downwash(np.array([s]), 1.0, 1.358, 0.513, 0.065, 4.38, ac.U, ac.c_w)[0]
    bracket_wrong = (
        1
        - s * 0.513 / (s + 2 * 0.065 * ac.U / ac.c_w)
        - (s * ac.c_w * 1.358 / ac.U) * (-special.exp1(-s * T)) * np.exp(-s * T)
    )
    assert abs(bracket_wrong - good) / abs(good) == pytest.approx(0.53, abs=0.01)


def test_lift_lag_matches_laplace_transform_of_indicial():
    # Eq. 17 = s L{Eq. 1}: check by numerical Laplace transform at real s (smooth integrand)
    y, z, U, c = 0.361, 0.381, 47.5, 1.34
    for s in (0.5, 3.0, 12.0):
        val, _ = integrate.quad(lambda t: aero.lift_indicial(t, y, z, U, c) * math.exp(-s * t), 0, np.inf)
        assert s * val == pytest.approx(aero.lift_lag(s, 1.0, y, z, U, c).real, rel=1e-9)


def test_kussner_weights_and_step():
    K0 = aero.kussner(np.array([0j]), [6.0, 8.0], 70.0, 1.87, weights=[0.3, 0.7])
    assert K0[0] == pytest.approx(1.0)
    with pytest.raises(ParameterError, match="sum to one"):
        aero.kussner(np.array([1j]), [6.0, 8.0], 70.0, 1.87, weights=[1.0, 1.0])
    # BS-17 is the step response of BS-12: s L{phi(2Vt/c)} = K(s), checked at real s
    b, V, c = 7.5, 70.0, 1.87
    for s in (1.0, 10.0):
        val, _ = integrate.quad(lambda t: aero.kussner_indicial(2 * V * t / c, b) * math.exp(-s * t), 0, np.inf)
        assert s * val == pytest.approx(aero.kussner(np.array([s + 0j]), b, V, c)[0].real, rel=1e-9)


def test_indicial_presets():
    f = aero.get_indicial("kussner_jones_2d")
    assert f.step(0.0) == pytest.approx(0.0)  # 2-D Kussner starts at zero lift
    # THEORY.md 8: its mean lag is 4.35 semichords (0.5/0.13 + 0.5/1)
    assert f.mean_lag == pytest.approx(4.346, abs=1e-3)
    with pytest.raises(ParameterError, match="unknown indicial preset"):
        aero.get_indicial("nope")


def test_unsteady_with_indicial_gust_preset():
    m = make_model("unsteady", "do128", gust=True, gust_lag="kussner_jones_2d")
    assert "b1" not in m.parameters
    g = m.frequency_response([1e-6, 2.0])
    assert g[0, 1, 0].real == pytest.approx(-1.0, abs=1e-4)


def test_input_delay_is_a_pure_phase():
    m = make_model("dimensional", airspeed=50.0)
    md = m.with_values(tau_de=0.05)
    G, Gd = m.frequency_response(OMEGA), md.frequency_response(OMEGA)
    assert np.allclose(Gd, G * np.exp(-1j * OMEGA * 0.05), rtol=1e-13)


def test_boundary_response_matches_free_response_transform():
    # H maps d = x(0) - x(T) e^{-sT} to the finite transforms of the free response
    m = make_model("dimensional", "navion")
    p = m.parameters.values
    A = np.array([[p["Z_a"], 1 + p["Z_q"]], [p["M_a"], p["M_q"]]])
    x0 = np.array([0.02, -0.05])
    T = 1.5  # short record: the state has not decayed
    from scipy.linalg import expm

    def outputs(t):
        x = expm(A * t) @ x0
        xdot = A @ x
        return np.array([x[0], x[1], m.U / G0 * (xdot[0] - x[1])])

    xT = expm(A * T) @ x0
    for w in (0.3, 2.0, 7.0):
        ref = integrate.quad_vec(lambda t: outputs(t) * np.exp(-1j * w * t), 0, T, epsabs=1e-13)[0]
        H = m.evaluate([w]).H[0]
        d = x0 - xT * np.exp(-1j * w * T)
        assert np.allclose(H @ d, ref, rtol=1e-9, atol=1e-12)


def test_derived_jacobian_matches_closed_form():
    m = make_model("unsteady", "navion")
    keys, J = m.derived_jacobian(m.parameters.values, ["CLa_t", "deps_da"])
    ac = m.aircraft
    sr, lc = ac.S_t / ac.S_w, m.parameters["l_t"].value / ac.c_w
    eps, at = m.parameters["deps_da"].value, m.parameters["CLa_t"].value
    i = keys.index("Cm_a")
    # d Cm_a / d a_t = -lc sr (1 - eps); d Cm_a / d eps = lc sr a_t; central difference error ~1e-9
    assert J[i, 0] == pytest.approx(-lc * sr * (1 - eps), rel=1e-7)
    assert J[i, 1] == pytest.approx(lc * sr * at, rel=1e-7)


def test_model_json_roundtrip():
    m = make_model("unsteady", "sundowner", gust=True, tail_lag_chord="c_t").with_values(F=1.1).free(["H"])
    m2 = model_from_dict(json.loads(json.dumps(model_to_dict(m))))
    assert m2 == m
    assert np.array_equal(m2.frequency_response(OMEGA), m.frequency_response(OMEGA))


def test_bad_model_inputs():
    with pytest.raises(ParameterError, match="unknown model"):
        make_model("quasi", "navion")
    with pytest.raises(ParameterError, match="needs an Aircraft"):
        make_model("unsteady")
    with pytest.raises(ParameterError, match="airspeed"):
        make_model("dimensional")
    m = make_model("steady", "navion")
    with pytest.raises(ParameterError, match="unknown parameter 'Cm_alpha'"):
        m.frequency_response(OMEGA, {"Cm_alpha": 1.0})
    with pytest.raises(ParameterError, match="l_t = 1.0 m must exceed"):
        make_model("unsteady", "sundowner").with_values(l_t=1.0).frequency_response([1.0])
    with pytest.raises(ParameterError, match="tail_lag_chord"):
        make_model("unsteady", "navion", tail_lag_chord="c_x")


def test_aircraft_file(tmp_path):
    d = get_aircraft("sundowner").to_dict()
    f = tmp_path / "mine.json"
    f.write_text(json.dumps(d))
    assert load_aircraft(f) == get_aircraft("sundowner")
    del d["Iy"]
    f.write_text(json.dumps(d))
    with pytest.raises(AircraftError, match="missing key.*Iy"):
        load_aircraft(f)
    minimal = {k: 1.0 for k in ("S_w", "c_w", "S_t", "c_t", "l_t", "mass", "Iy", "U", "rho")}
    minimal["name"] = "box"
    ac = Aircraft.from_dict(minimal)
    assert ac.constants["F"] == 0.0  # generic defaults assume no downwash lag
    minimal["rho"] = -1
    with pytest.raises(AircraftError, match="rho must be positive"):
        Aircraft.from_dict(minimal)
    with pytest.raises(AircraftError, match="unknown aircraft"):
        load_aircraft("concorde")


def _forcing_case(model, rng):
    """Inputs, boundary vector and state forcing on OMEGA, random (the forms are linear in each)."""
    shape_u = (OMEGA.size, len(model.inputs))
    u = rng.normal(size=shape_u) + 1j * rng.normal(size=shape_u)
    d = rng.normal(size=(OMEGA.size, 2)) + 1j * rng.normal(size=(OMEGA.size, 2))
    f = rng.normal(size=(OMEGA.size, 2)) + 1j * rng.normal(size=(OMEGA.size, 2))
    return u, d, f


@pytest.mark.parametrize(
    "kind, options",
    [
        ("dimensional", {}),
        ("derivatives", {"gust": True}),
        ("steady", {"gust": True}),
        ("unsteady", {}),
        ("unsteady", {"effects": ["sensor_offset:az"]}),  # a station: the output row, the root's matrices
        ("steady", {"gust": True, "effects": ["gust_lag:tail", "sensor_offset:alpha"]}),  # a matrix-level effect
        # output-level effects by their factors: scaled outputs and inputs, and an added mode
        ("dimensional", {"effects": ["time_delay:alpha", "sensor_offset:az", "actuator_lag"]}),
        ("derivatives", {"gust": True, "effects": ["gust_lag:alpha_w", "sensor_scale:q", "structural_mode"]}),
    ],
)
def test_forced_sensitivity_matches_the_derivatives_of_the_response(kind, options):
    # Model.forced_sensitivity, P (dB u + dE d - dM x) per name with one 2 x 2 solve of the forcing
    # (augmented models without output-level effects too), against dG u + dH d + dP f from
    # Model.sensitivity's derivative matrices: the same arithmetic reordered, so rounding ~ 1e-13 of
    # the largest term; a station's row is a central difference in both, exact for an affine row.
    # Output-level effects: the reference pushes dG through them by differences of 1e-6 of the
    # response, so its rounding is ~1e-16/1e-6 = 1e-10 relative: tolerance 1e-9 there
    model = make_model(kind, "navion", **options).free(["tau_de"])
    rng = np.random.default_rng(5)
    u, d, f = _forcing_case(model, rng)
    vals = {n: v * (1.0 + 0.1 * rng.normal()) for n, v in model.parameters.values.items()}
    vals["tau_de"] = 0.03
    effect_values = {n: 0.05 for n in model.parameters.names if model.parameters[n].role is Role.EFFECT}
    vals.update(effect_values)  # away from their nulls, where every factor is one
    tol = 1e-9 if any(isinstance(e, OutputEffect) for e in getattr(model, "effects", ())) else 1e-12
    names = list(model.parameters.free_model_names)
    resp = model.evaluate(OMEGA, vals)
    _, dG, dH, dP = model.sensitivity(OMEGA, vals, names)
    for dd, ff in ((None, None), (d, None), (d, f)):
        dy = (dG @ u[:, :, None])[..., 0]
        dy = dy + (0 if dd is None else (dH @ dd[:, :, None])[..., 0])
        dy = dy + (0 if ff is None else (dP @ ff[:, :, None])[..., 0])
        resp2, got_dy = model.forced_sensitivity(OMEGA, vals, names, u, dd, ff)
        assert got_dy.shape == (len(names), OMEGA.size, 3)
        assert np.abs(got_dy - dy).max() <= tol * np.abs(dy).max()
        assert np.abs(resp2.G - resp.G).max() <= 1e-14 * np.abs(resp.G).max()
