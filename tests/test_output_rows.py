"""The output table (fdml.channels.OUTPUT_TABLE) and the one descriptor of the conventional models (issue 22).

Reference values are independent of the code under test: closed forms (theta = q/s, q_dot = s q,
a_z at a station = a_z - x q_dot/g), scipy's lsim of the dimensional model written out here (with
theta as an integrator state of its own), and the finite Fourier transform of the time-domain
simulation of a record that does not end at rest, against the frequency-domain model with Klein's
boundary terms of the record's ends (theta's own included).
"""

import json

import numpy as np
import pytest
from scipy import signal

import fdml
from fdml.channels import ALL_OUTPUTS, OUTPUT_TABLE, OUTPUTS, SIGNALS, boundary_channels, row_space
from fdml.cli import main
from fdml.constants import G0
from fdml.errors import FdmlError, ParameterError, RecordError
from fdml.maneuvers import three_two_one_one, time_vector
from fdml.models import DescriptorModel, make_model, model_from_dict, model_to_dict, realize, with_effects
from fdml.models.measurement import nuisance_names, predict
from fdml.record import add_noise
from fdml.simulate import simulate
from fdml.spectral import spectra

OMEGA = np.linspace(0.2, 10.0, 50)
S = 1j * OMEGA
MORE = ("theta", "qdot")
KINDS = [("dimensional", {}), ("derivatives", {"adot": True}), ("steady", {}), ("unsteady", {})]
ADOT = {"Cz_adot": -1.0, "Cm_adot": -4.0}


def _model(kind, opts, gust=False, outputs=MORE):
    m = make_model(kind, "sundowner", gust=gust, outputs=outputs, **opts)
    return m.with_values(ADOT) if opts.get("adot") else m


# --- the table -----------------------------------------------------------------------------------------


def test_the_table_is_the_registry():
    assert ALL_OUTPUTS == ("alpha", "q", "az", "theta", "qdot") and OUTPUTS == ALL_OUTPUTS[:3]
    assert all(o.name in SIGNALS for o in OUTPUT_TABLE)
    assert row_space(["qdot"]) == ("alpha", "q", "az", "qdot") and row_space() == OUTPUTS
    assert boundary_channels(row_space(MORE)) == ("alpha", "q", "theta")
    with pytest.raises(ValueError, match="unknown output"):
        row_space(["beta"])
    with pytest.raises(ParameterError, match="unknown output"):
        make_model("dimensional", airspeed=50.0, outputs=("pitch",))


@pytest.mark.parametrize("kind, opts", KINDS)
@pytest.mark.parametrize("gust", [False, True])
def test_theta_is_q_over_s_and_qdot_is_s_q(kind, opts, gust):
    m = _model(kind, opts, gust)
    base = make_model(kind, "sundowner", gust=gust, **opts).with_values(ADOT if opts.get("adot") else {})
    G, G3 = m.frequency_response(OMEGA), base.frequency_response(OMEGA)
    assert m.outputs == ALL_OUTPUTS and G.shape[0] == 5
    # the three first rows are the model without the new outputs (rounding of a different product order)
    np.testing.assert_allclose(G[:3], G3, rtol=1e-13, atol=1e-15 * np.abs(G3).max())
    np.testing.assert_allclose(G[3], G[1] / S, rtol=1e-13)  # theta = q/s
    np.testing.assert_allclose(G[4], G[1] * S, rtol=1e-13)  # q_dot = s q


@pytest.mark.parametrize("kind, opts", KINDS)
def test_boundary_columns_theta_its_own_and_qdot_the_rate_of_q(kind, opts):
    r = _model(kind, opts).evaluate(OMEGA)
    assert r.H.shape == (OMEGA.size, 5, 3) and r.outputs == ALL_OUTPUTS
    s = S[:, None]
    # theta~ = (q~ + d_theta)/s: q's boundary columns over s, and 1/s on its own boundary value
    np.testing.assert_allclose(r.H[:, 3, :2], r.H[:, 1, :2] / s, rtol=1e-13)
    np.testing.assert_allclose(r.H[:, 3, 2], 1.0 / S, rtol=1e-15)
    # q_dot~ = s q~ - d_q
    np.testing.assert_allclose(r.H[:, 4, :2], r.H[:, 1, :2] * s - [0.0, 1.0], rtol=1e-12, atol=1e-14)
    assert not np.any(r.H[:, :3, 2]) and not np.any(r.H[:, 4, 2])  # only theta sees its own term
    np.testing.assert_allclose(r.P[:, 3], r.P[:, 1] / s, rtol=1e-13)
    np.testing.assert_allclose(r.P[:, 4], r.P[:, 1] * s, rtol=1e-13)


def test_az_at_a_station_is_az_minus_x_qdot_over_g():
    x = 3.0
    base = make_model("derivatives", "sundowner", outputs=("qdot",))
    m = with_effects(base, "sensor_offset:az").with_values(x_az=x)
    r0, r = base.evaluate(OMEGA), m.evaluate(OMEGA)
    qdot = r0.outputs.index("qdot")
    for a in ("G", "H", "P"):
        A0, A = getattr(r0, a), getattr(r, a)
        np.testing.assert_allclose(A[:, 2], A0[:, 2] - x / G0 * A0[:, qdot], rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(np.delete(A, 2, axis=1), np.delete(A0, 2, axis=1))
    R = realize(m)
    np.testing.assert_allclose(R.frequency_response(OMEGA), m.frequency_response(OMEGA), rtol=1e-11, atol=1e-14)


# --- the time domain -----------------------------------------------------------------------------------


def _lsim_reference(m, t, de):
    """alpha, q, a_z, theta, q_dot of a dimensional model by scipy's lsim, theta an integrator state."""
    p = m.parameters.values
    A = np.array([[p["Z_a"], 1 + p["Z_q"], 0], [p["M_a"], p["M_q"], 0], [0, 1, 0]])
    B = np.array([[p["Z_de"]], [p["M_de"]], [0]])
    k = m.U / G0
    C = np.vstack([np.eye(3)[:2], [k * p["Z_a"], k * p["Z_q"], 0], np.eye(3)[2], A[1]])
    D = np.array([[0], [0], [k * p["Z_de"]], [0], [p["M_de"]]])
    return signal.lsim(signal.StateSpace(A, B, C, D), de, t, interp=True)[1]


def test_simulated_theta_and_qdot_match_an_independent_lsim():
    m = make_model("dimensional", "sundowner", outputs=MORE)
    t = time_vector(10.0, 0.02)
    de = three_two_one_one(t, 0.02, start=1.0, unit=0.3)
    rec = simulate(m, t, {"de": de})
    assert set(rec.signals) == {"de", *ALL_OUTPUTS}
    ref = _lsim_reference(m, t, de)
    for j, o in enumerate(ALL_OUTPUTS):  # both exact for inputs linear between samples: rounding only
        np.testing.assert_allclose(rec[o], ref[:, j], rtol=0, atol=1e-9 * np.abs(ref[:, j]).max(), err_msg=o)


@pytest.mark.parametrize(
    "kind, opts, values",
    # the models whose states are alpha and q alone: their boundary terms are complete (the unsteady
    # model's lag states are not among them: a record ending mid-response misfits it by about 1 %)
    [("dimensional", {}, {}), ("derivatives", {"adot": True}, ADOT), ("steady", {}, {})],
)
def test_transform_of_a_record_not_at_rest_is_the_model_with_its_boundary_terms(kind, opts, values):
    m = make_model(kind, "sundowner", outputs=MORE, **opts).with_values(values)
    dt = 0.01
    t = time_vector(4.0, dt)  # ends in the middle of the response: x(T), theta(T) far from zero
    de = three_two_one_one(t, 0.02, start=0.5, unit=0.4, rise=0.2)
    rec = simulate(m, t, {"de": de})
    d = spectra(rec, OMEGA, trim="none", outputs=MORE)
    assert d.outputs == ALL_OUTPUTS and d.x0.size == 3 and abs(d.xT[2]) > 0.1 * np.abs(rec["theta"]).max()
    y = predict(m.evaluate(OMEGA), d.u, d.ones, d.boundary())
    scale = np.abs(d.z).max(axis=0)
    err = np.abs(d.z - y).max(axis=0) / scale
    # the transform's cubic end correction and the hold of the sampled input: (w dt)^2/8 at most
    # (as tests/test_model_effects.py), 1.2e-3 at 10 rad/s (measured: 2.3e-4, falling as dt^2)
    tol = (OMEGA[-1] * dt) ** 2 / 8
    assert np.all(err < tol), dict(zip(ALL_OUTPUTS, err))
    # the check could fail: without theta's own boundary term, theta misses by far more
    own = d.boundary().copy()
    own[:, 2] = 0.0
    miss = np.abs(d.z[:, 3] - predict(m.evaluate(OMEGA), d.u, d.ones, own)[:, 3]).max() / scale[3]
    assert miss > 20 * tol


def test_realisation_export_and_saved_model_carry_the_outputs():
    control = pytest.importorskip("control")
    from fdml.export import to_frd, to_statespace

    m = make_model("derivatives", "sundowner", outputs=("theta",))
    R = realize(m)
    assert R.outputs == ("alpha", "q", "az", "theta") and R.states == 3  # theta's integrator
    ss = to_statespace(m)
    assert isinstance(ss, control.StateSpace) and ss.output_labels == list(R.outputs)
    G = m.frequency_response(OMEGA)
    Gs = np.asarray(ss(S)).reshape(4, 1, OMEGA.size)
    np.testing.assert_allclose(Gs, G, rtol=1e-11, atol=1e-14)
    assert to_frd(m, OMEGA).output_labels == list(R.outputs)
    back = model_from_dict(json.loads(json.dumps(model_to_dict(m))))
    assert back.outputs == m.outputs and back.parameters == m.parameters
    assert "outputs" not in model_to_dict(make_model("derivatives", "sundowner"))["options"]  # files as before


# --- the fit -------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def noisy_record():
    truth = make_model("dimensional", "sundowner", outputs=MORE)
    t = time_vector(12.0, 0.02)
    rec = simulate(truth, t, {"de": three_two_one_one(t, 0.02, start=1.0, unit=0.4)})
    return truth, add_noise(rec, 0.02, np.random.default_rng(5), relative=True)


@pytest.mark.parametrize("outputs", ["alpha,q,theta,qdot", "alpha,q,theta,az"])
def test_a_fit_of_theta_and_qdot_recovers_the_truth(noisy_record, outputs):
    truth, rec = noisy_record
    res = fdml.fit(rec, make_model("dimensional", "sundowner"), band=(0.3, 10, 0.1), outputs=outputs)
    assert res.converged and res.outputs == tuple(outputs.split(","))
    assert "x0_theta" in res.names and "xT_theta" in res.names  # theta's own boundary values
    p = truth.parameters.values
    for n in ("Z_a", "Z_de", "M_a", "M_q", "M_de"):
        assert abs(res[n] - p[n]) < 4 * res.errors[n], (n, res[n], p[n], res.errors[n])
    resid = res.resid
    assert resid.shape[1] == len(res.outputs) and np.all(np.isfinite(resid))


def test_a_fit_of_theta_with_an_effect(noisy_record):
    truth, rec = noisy_record
    model = make_model("dimensional", "sundowner", effects=["sensor_offset:az"])
    res = fdml.fit(rec, model, band=(0.3, 10, 0.1), outputs="alpha,q,theta,az")
    assert res.converged and res.model.outputs == ("alpha", "q", "az", "theta")
    assert abs(res["x_az"]) < 4 * res.errors["x_az"]  # the truth's accelerometer is at the c.g.


def test_the_fit_refuses_an_output_the_record_lacks():
    rec = simulate(make_model("dimensional", "sundowner"), time_vector(8.0, 0.02), {"de": np.zeros(401) + 0.01})
    with pytest.raises(RecordError, match="has no theta column"):
        fdml.fit(rec, make_model("dimensional", "sundowner"), outputs="alpha,q,theta")
    with pytest.raises(FdmlError, match="unknown output"):
        fdml.fit(rec, make_model("dimensional", "sundowner"), outputs="alpha,pitch")
    assert nuisance_names(row_space(MORE))[:5] == tuple(f"bias_{o}" for o in ALL_OUTPUTS)


def test_command_line_simulates_and_fits_theta_and_qdot(tmp_path, capsys):
    rec = tmp_path / "r.csv"
    args = ["--model", "dimensional", "--aircraft", "sundowner"]
    code = main(["simulate", *args, "--outputs", "theta,qdot", "--noise", "0.02", "--seed", "4", "-o", str(rec)])
    assert code == 0 and "signals de, alpha, q, az, theta, qdot" in capsys.readouterr().out
    code = main(["fit", str(rec), *args, "--outputs", "alpha,q,theta,az", "--band", "0.3:10:0.1", "--json"])
    out = capsys.readouterr().out
    assert code == 0, out
    d = json.loads(out)
    assert d["outputs"] == ["alpha", "q", "theta", "az"] and d["converged"] and "xT_theta" in d["params"]
    code = main(["simulate", *args, "--outputs", "pitch", "-o", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "unknown output(s) ['pitch']" in err


# --- the one descriptor --------------------------------------------------------------------------------


@pytest.mark.parametrize("kind, opts", [("dimensional", {"gust": True}), ("derivatives", {"adot": True, "gust": True})])
def test_a_conventional_model_writes_its_equations_once(kind, opts):
    from fdml.export import descriptor_matrices

    m = make_model(kind, "sundowner", **opts)
    m = m.with_values(ADOT if kind == "derivatives" else {"Z_q": 0.01})
    cls = type(m)
    assert isinstance(m, DescriptorModel) and "_matrices" not in vars(cls) and "_matrix_derivatives" not in vars(cls)
    d = m.descriptor()
    # the export reads the descriptor itself (no recovery from M(s) at sample points)
    for a, b in zip(descriptor_matrices(m), (d.E, d.A, d.B0, d.B1)):
        np.testing.assert_array_equal(a, b)
    # M = s E - A and B = B0 + s B1: the frequency response is the descriptor's
    M, B, E = m.matrices(OMEGA)
    np.testing.assert_allclose(M, S[:, None, None] * d.E - d.A, rtol=1e-15)
    np.testing.assert_allclose(B, d.B0 + S[:, None, None] * d.B1, rtol=1e-15)
    # the sensitivities rest on every entry being affine in the parameters jointly: second differences vanish
    names = [n for n in m.parameters.free_model_names] + list(ADOT if kind == "derivatives" else ())
    rng = np.random.default_rng(0)
    p0 = m.values()
    for a, b in zip(names, rng.permutation(names)):
        step = {a: 0.7, b: -1.3}

        def at(k):
            return m.descriptor({n: p0[n] + k * v for n, v in step.items()})

        mid, hi, lo = at(0.0), at(1.0), at(-1.0)
        for f in ("E", "A", "B0", "B1"):
            second = getattr(hi, f) - 2 * getattr(mid, f) + getattr(lo, f)
            assert np.abs(second).max() < 1e-12 * max(np.abs(getattr(mid, f)).max(), 1.0), (a, b, f)


@pytest.mark.parametrize("kind, opts", [("dimensional", {}), ("derivatives", {"adot": True, "gust": True})])
def test_descriptor_sensitivities_equal_differences_of_the_response(kind, opts):
    m = make_model(kind, "sundowner", outputs=MORE, **opts)
    m = m.with_values(ADOT) if opts.get("adot") else m
    names = [n for n in m.parameters.names if m.parameters[n].role.value == "aero"]
    resp, dG, dH, dP = m.sensitivity(OMEGA, None, names)
    p = m.values()
    for i, n in enumerate(names):
        h = 1e-6 * max(abs(p[n]), 1.0)
        up, dn = m.evaluate(OMEGA, {n: p[n] + h}), m.evaluate(OMEGA, {n: p[n] - h})
        # central differences: truncation O(h^2) ~ 1e-12 and rounding eps/h ~ 1e-10 relative
        for got, a, b in ((dG[i], up.G, dn.G), (dH[i], up.H, dn.H), (dP[i], up.P, dn.P)):
            ref = (a - b) / (2 * h)
            assert np.abs(got - ref).max() <= 1e-7 * max(np.abs(ref).max(), np.abs(resp.G).max()), n


def test_station_sensitivities_with_theta_and_qdot_equal_differences_of_the_response():
    # a sensor's station enters its output row only; with theta's own boundary column (an integral
    # row) beside it, the response's derivatives and the forced outputs' (y = G u + H d + P f) against
    # central differences of the response: the rows are affine in the station, so the differences
    # carry rounding alone, eps/h ~ 1e-13 relative at h = 1e-3 m
    m = with_effects(
        make_model("unsteady", "navion", outputs=OUTPUTS + MORE), "sensor_offset:alpha", "sensor_offset:az"
    )
    p = {**m.values(), "x_alpha": 4.0, "x_az": 1.3}
    names = ["x_alpha", "x_az", "Cm_de"]
    _, dG, dH, dP = m.sensitivity(OMEGA, p, names)
    rng = np.random.default_rng(2)
    u, d, f = (rng.normal(size=(OMEGA.size, k)) + 1j * rng.normal(size=(OMEGA.size, k)) for k in (1, dH.shape[-1], 2))
    _, dy = m.forced_sensitivity(OMEGA, p, names, u, d, f)
    for i, n in enumerate(names[:2]):
        h = 1e-3
        up, dn = m.evaluate(OMEGA, {**p, n: p[n] + h}), m.evaluate(OMEGA, {**p, n: p[n] - h})
        refs = [(a - b) / (2 * h) for a, b in ((up.G, dn.G), (up.H, dn.H), (up.P, dn.P))]
        for got, ref in zip((dG[i], dH[i], dP[i]), refs):
            assert got.shape == ref.shape and np.abs(got - ref).max() <= 1e-10 * np.abs(ref).max(), n
        forced = sum((x @ v[:, :, None])[..., 0] for x, v in zip(refs, (u, d, f)))
        assert np.abs(dy[i] - forced).max() <= 1e-10 * np.abs(forced).max(), n


def test_figures_draw_theta_and_qdot(noisy_record):
    from matplotlib.figure import Figure

    from fdml.plotting import plot_residual_spectra, plot_spectra, plot_time_histories, simulate_fit

    _, rec = noisy_record
    res = fdml.fit(rec, make_model("dimensional", "sundowner"), band=(0.3, 10, 0.1), outputs="alpha,q,theta,qdot")
    sim = simulate_fit(res)
    assert {"theta", "qdot"} <= set(sim.signals)
    # the model's time history from the estimate: theta within a few noise levels of the measured one
    assert np.sqrt(np.mean((sim["theta"] - rec["theta"]) ** 2)) < 3 * rec.meta["noise_std"]["theta"]
    fig, axes = plot_spectra(res)
    assert isinstance(fig, Figure) and axes.shape == (2, 4) and axes[0, 2].get_title() == "theta"
    fig, axes = plot_time_histories(res, outputs=["q", "theta", "qdot"])
    assert axes.shape == (4,) and r"$\theta$ (deg)" == axes[2].get_ylabel() and "deg/s^2" in axes[3].get_ylabel()
    fig, axes = plot_residual_spectra(res)
    assert axes.shape == (4,)
    plain = fdml.fit(rec, make_model("dimensional", "sundowner"), band=(0.3, 10, 0.1))
    with pytest.raises(ValueError, match="the fit has no theta spectra"):
        plot_spectra(plain, outputs=["theta"])


@pytest.mark.parametrize(
    "rel",
    ["twin_otter/totter_lon_020213f1_017.mat", "hfb320/hfb320_1_10.asc", "attas/fAttasElv1.mat"],
)
def test_readers_give_theta_and_qdot_in_the_registry_units_and_signs(rel):
    from fdml.io import data_path, load_record

    rec = load_record(data_path(rel))
    assert {"theta", "qdot"} <= set(rec.signals)

    def slope(y, x):
        x, y = x - x.mean(), y - y.mean()
        return float(x @ y / (x @ x)), float(np.corrcoef(x, y)[0, 1])

    # theta_dot = q (wings level) and d q/dt = q_dot, from the recorded signals themselves: a degree
    # left unconverted would give 57 or 1/57, a sign -1; measured 0.89-1.01 (Twin Otter's theta:
    # 0.89, correlation 0.99, a scale or a bank angle the reader cannot know)
    for y, x in ((np.gradient(rec["theta"], rec.dt), rec["q"]), (np.gradient(rec["q"], rec.dt), rec["qdot"])):
        b, r = slope(y, x)
        assert 0.85 < b < 1.15 and r > 0.95, (rel, b, r)
