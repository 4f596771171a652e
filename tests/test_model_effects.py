"""Effects as parts of a model: build, describe, serialise, realise, simulate, the CLI, and bad input.

Reference values are independent of the code under test: the frequency response of a model with
effects is checked against the time-domain simulation of the same model (a finite Fourier transform of
the simulated response to a smooth doublet), the realisation against the frequency-domain model
(two different compositions of the same rational functions), and the serialised model against the
original.
"""

import json

import numpy as np
import pytest

import fdml
from fdml.cli import main
from fdml.errors import FdmlError, ParameterError
from fdml.fourier import finite_fourier_transform
from fdml.maneuvers import doublet, time_vector
from fdml.models import make_model, model_from_dict, model_to_dict, realize, with_effects
from fdml.models.effects import AugmentedModel, get_effect, registered_effects
from fdml.simulate import simulate

OMEGA = np.linspace(0.2, 10.0, 50)

#: A non-null value of every effect parameter (inside its plausible range).
VALUES = {
    "y_w": 0.3,
    "y_lift": 0.3,
    "G": 0.3,
    "Cm_adot": -5.0,
    "M_adot": -0.5,
    "b1": 2.0,
    "T_gust": 0.1,
    "tau_tail": 0.1,
    "g_dw": 1.0,
    "tau_dw": 0.09,
    "tau_de": 0.05,
    "tau_alpha": 0.05,
    "tau_q": 0.04,
    "tau_az": 0.03,
    "tau_alpha_q": 0.04,
    "tau_alpha_az": 0.05,
    "tau_q_az": 0.03,
    "T_act": 0.05,
    "x_az": 3.0,
    "x_alpha": 3.0,
    "r_q": 0.05,
    "r_az": 0.05,
    "omega_s": 8.0,
    "zeta_s": 0.1,
    "k_alpha": 0.1,
    "k_q": -0.1,
    "k_az": 0.15,
}

#: Base models (sundowner, the preset with every geometric constant), all finite-state (F = 0).
BASES = {
    "dimensional": ("dimensional", {}, {}),
    "derivatives-adot": ("derivatives", {"adot": True}, {"Cz_adot": -1.0, "Cm_adot": -4.0}),
    "steady": ("steady", {}, {}),
    "unsteady-F0": ("unsteady", {}, {"F": 0.0}),
    "dimensional-gust": ("dimensional", {"gust": True}, {}),
    "derivatives-gust": ("derivatives", {"gust": True}, {}),
    "steady-gust": ("steady", {"gust": True}, {}),
    "unsteady-F0-gust-no-tail": ("unsteady", {"gust": True, "tail_gust_delay": False}, {"F": 0.0}),
}


def _base(name):
    kind, opts, values = BASES[name]
    return make_model(kind, "sundowner", **opts).with_values(values)


def _cases():
    """(effect key, base) pairs: every deterministic registered effect on (at least) two base models."""
    out = []
    for eff in registered_effects():
        if eff.kind != "deterministic":
            continue
        usable = [b for b in BASES if eff.applicable(_base(b), _base(b).inputs) is None]
        assert len(usable) >= 2, (eff.key, usable)
        out += [(eff.key, b) for b in usable[:2]]
    return out


CASES = _cases()


def _with(key, base):
    m = with_effects(_base(base), key)
    mine = {
        n: v
        for n, v in VALUES.items()
        if n in m.parameters and m.parameters[n].free and n not in _base(base).parameters.free_names
    }
    return m.with_values(mine), mine


# --- build and describe ------------------------------------------------------------------------------


def test_one_readable_call_and_description():
    m = make_model("dimensional", airspeed=73.3, effects=["time_delay:alpha", "sensor_offset:az"])
    assert isinstance(m, AugmentedModel)
    assert m.describe() == (
        "dimensional model (elevator only) + alpha time delay (tau_alpha, s) + az sensor offset (x_az, m)"
    )
    assert repr(m) == f"<fdml model: {m.describe()}>"
    assert [e.key for e in m.parts] == ["time_delay@alpha", "sensor_offset@az"]
    # free at the null: the model is the base model until fitted
    assert m.parameters["tau_alpha"].free and m.parameters["x_az"].free
    base = make_model("dimensional", airspeed=73.3)
    np.testing.assert_array_equal(m.frequency_response(OMEGA), base.frequency_response(OMEGA))
    # every spelling and an Effect object give the same model
    eff = get_effect("sensor_offset@az")
    for spec in (["time_delay@alpha", eff], ["time_delay:alpha", "sensor_offset:a_z"]):
        assert with_effects(base, spec).kind == m.kind
    with pytest.raises(ParameterError, match="give sensor_offset:CHANNEL"):
        with_effects(base, "sensor_offset")  # two variants (alpha, az): ambiguous
    assert with_effects(base, "actuator_lag").kind == "dimensional+actuator_lag@de"  # one variant
    assert with_effects(with_effects(base, "time_delay:alpha"), "sensor_offset:az").kind == m.kind


@pytest.mark.parametrize("key, base", CASES)
def test_serialise_and_reload_every_effect(key, base):
    m, mine = _with(key, base)
    m = m.fix([next(iter(mine))]) if mine else m  # a fixed effect parameter keeps its flag
    d = json.loads(json.dumps(model_to_dict(m)))
    assert key in d["effects"]
    back = model_from_dict(d)
    assert back.parameters == m.parameters  # values, free flags, bounds, units
    assert back.describe() == m.describe() and back.kind == m.kind
    G = m.frequency_response(OMEGA)
    np.testing.assert_array_equal(back.frequency_response(OMEGA), G)  # same code, same numbers


# --- realisation and time-domain simulation ------------------------------------------------------------


def _transfer_error(model, driven, dt):
    """max over outputs of max_w |y~/u~ - G| / max_w |G| for a smooth doublet from rest (as test_simulate)."""
    t = time_vector(40.0, dt)
    u = doublet(t, 0.01, start=1.0, width=0.5, rise=0.5)
    inputs = {"de": np.zeros_like(t) if driven == "alpha_w" else u}
    if model.gust:
        inputs["alpha_w"] = u if driven == "alpha_w" else np.zeros_like(t)
    rec = simulate(model, t, inputs)
    y = np.column_stack([rec["alpha"], rec["q"], rec["az"]])
    Y = finite_fourier_transform(y, dt, OMEGA)
    U = finite_fourier_transform(u, dt, OMEGA)
    G = model.frequency_response(OMEGA)[:, model.inputs.index(driven), :].T
    return np.max(np.max(np.abs(Y / U[:, None] - G), axis=0) / np.max(np.abs(G), axis=0))


@pytest.mark.parametrize("key, base", CASES)
def test_frequency_response_equals_time_domain_simulation(key, base):
    m, _ = _with(key, base)
    driven = "alpha_w" if "alpha_w" in key or key == "gust_lag@tail" else "de"
    G = m.frequency_response(OMEGA)
    # the simulation, at dt = 0.01 s: the first-order hold's transform factor is sinc^2(w dt/2), i.e. a
    # relative error up to (w dt)^2/12 = 8e-4 at 10 rad/s (delays, input or sensor, are exact); bound
    # (w dt/2)^2/4 = 6e-4 as in test_simulate, times 2 for filter states fed by interpolated (not exactly
    # piecewise-linear) signals: the gust lags measure 6.1e-4, every other case 5e-4 or less
    tol = 2 * (OMEGA[-1] * 0.01 / 2) ** 2 / 4
    # the effect is really there, 20 times the tolerance on some output (so the check below could fail)
    G0 = _base(base).frequency_response(OMEGA)
    size = np.max(np.abs(G - G0), axis=(1, 2)) / np.max(np.abs(G), axis=(1, 2))
    assert np.max(size) > 20 * tol, size
    # the realisation: the same rational functions composed two ways (rounding of small solves)
    R = realize(m)
    assert np.max(np.abs(R.frequency_response(OMEGA) - G)) < 1e-11 * np.max(np.abs(G))
    e = _transfer_error(m, driven, 0.01)
    assert e < tol, e


def test_simulation_error_is_second_order_in_the_step():
    """The cross-check converges: halving dt divides the error by about 4 (not a fixed offset)."""
    m, _ = _with("structural_mode@q,az", "dimensional")
    m = with_effects(m, "actuator_lag:de", "time_delay:q").with_values(T_act=0.05, tau_q=0.03)
    e1, e2 = _transfer_error(m, "de", 0.02), _transfer_error(m, "de", 0.01)
    assert np.log2(e1 / e2) > 1.7, (e1, e2)


def test_a_sensor_station_is_a_term_of_its_row_whatever_the_order_of_the_effects():
    # the station is part of the alpha row (fdml.channels.OUTPUT_TABLE): the vane sees the true q,
    # alpha - x q/U, not the q sensor's delayed reading, so both orders are one model, realisable
    vals = dict(tau_q=0.02, x_alpha=2.0)
    base = make_model("dimensional", "sundowner")
    G0 = base.frequency_response(OMEGA)
    k = vals["x_alpha"] / base.U
    for order in (("time_delay:q", "sensor_offset:alpha"), ("sensor_offset:alpha", "time_delay:q")):
        m = with_effects(base, *order).with_values(vals)
        G = m.frequency_response(OMEGA)
        np.testing.assert_allclose(G[0], G0[0] - k * G0[1], rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(G[1], G0[1] * np.exp(-1j * OMEGA * vals["tau_q"]), rtol=1e-13, atol=1e-15)
        R = realize(m)
        assert np.max(np.abs(R.frequency_response(OMEGA) - G)) < 1e-11 * np.max(np.abs(G))


# --- export --------------------------------------------------------------------------------------------


def test_export_exact_frd_or_pade_statespace():
    control = pytest.importorskip("control")
    from fdml.export import to_control, to_statespace

    m = make_model("dimensional", "sundowner", effects=["time_delay:alpha", "actuator_lag"])
    m = m.with_values(tau_alpha=0.04, T_act=0.05)
    G = m.frequency_response(OMEGA)
    frd = to_control(m, omega=OMEGA)
    assert frd.delays == "exact" and isinstance(frd.system, control.FrequencyResponseData)
    with pytest.raises(ParameterError, match="pade"):
        to_statespace(m)
    ss = to_control(m, form="statespace", pade=6)
    assert ss.delays == "pade" and ss.pade_order == 6 and ss.system.nstates == 2 + 1 + 6
    Gs = np.asarray(ss.system(1j * OMEGA)).reshape(3, 1, OMEGA.size)
    # Pade (6,6) of exp(-s tau): phase error ~ (w tau)^13 / ... < 1e-12 at w tau = 0.4
    np.testing.assert_allclose(Gs, G, rtol=1e-9, atol=1e-9 * np.abs(G).max())
    plain = to_control(make_model("dimensional", "sundowner"), form="statespace")
    assert plain.delays == "none"


# --- command line --------------------------------------------------------------------------------------


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """A record of a dimensional model with a 30 ms alpha delay and a 2 m accelerometer offset."""
    path = tmp_path_factory.mktemp("rec") / "r.csv"
    code = main(
        [
            "simulate",
            "--model",
            "dimensional",
            "--airspeed",
            "73.3",
            "--effect",
            "time_delay:alpha",
            "--effect",
            "sensor_offset:az",
            "--set",
            "tau_alpha=0.03",
            "x_az=2",
            "--maneuver",
            "3211",
            "--duration",
            "20",
            "--noise",
            "alpha=1e-4,q=1e-4,az=1e-3",
            "--seed",
            "3",
            "-o",
            str(path),
        ]
    )
    assert code == 0
    return path


def test_cli_simulate_reaches_effect_parameters(record):
    from fdml.record import read_csv

    rec = read_csv(record)
    plain = fdml.simulate.simulate(make_model("dimensional", airspeed=73.3), rec.t, {"de": rec["de"]})
    # the alpha delay of 30 ms moves alpha by far more than its noise (1e-4 rad)
    assert np.max(np.abs(rec["alpha"] - plain["alpha"])) > 10 * 1e-4


def test_cli_fit_with_repeated_effect(record, capsys, tmp_path):
    out_json = tmp_path / "fit.json"
    code, out, _ = run(
        capsys,
        "fit",
        str(record),
        "--model",
        "dimensional",
        "--airspeed",
        "73.3",
        "--effect",
        "time_delay:alpha",
        "--effect",
        "sensor_offset:az",
        "--band",
        "0.3:12:0.05",
        "-o",
        str(out_json),
        "--json",
    )
    assert code == 0
    res = json.loads(out)
    p = res["params"] if isinstance(res["params"], dict) else {q["name"]: q for q in res["params"]}
    val = {k: (v["value"] if isinstance(v, dict) else v) for k, v in p.items()}
    err = {k: v["stderr"] for k, v in p.items() if isinstance(v, dict)}
    # the truth (30 ms, 2 m) within 4 standard errors of the estimate
    assert abs(val["tau_alpha"] - 0.03) < 4 * err["tau_alpha"]
    assert abs(val["x_az"] - 2.0) < 4 * err["x_az"]
    from fdml.results import load_result

    back = load_result(out_json)
    assert [e.key for e in back.model.parts] == ["time_delay@alpha", "sensor_offset@az"]
    assert "tau_alpha" in back.names and "x_az" in back.names


@pytest.mark.slow
def test_cli_response_and_batch_and_montecarlo(record, capsys, tmp_path):
    code, out, _ = run(
        capsys,
        "response",
        "--model",
        "dimensional",
        "--airspeed",
        "73.3",
        "--effect",
        "time_delay:alpha",
        "--set",
        "tau_alpha=0.1",
        "--band",
        "1:2:1",
        "--json",
    )
    assert code == 0
    d = json.loads(out)
    G = np.array(d["real"]) + 1j * np.array(d["imag"])
    G0 = make_model("dimensional", airspeed=73.3).frequency_response([1.0, 2.0])
    np.testing.assert_allclose(G[0], G0[0] * np.exp(-1j * np.array([1.0, 2.0]) * 0.1), rtol=1e-12)
    code, out, _ = run(
        capsys,
        "batch",
        str(record),
        "--model",
        "dimensional",
        "--airspeed",
        "73.3",
        "--effect",
        "time_delay:alpha",
        "--effect",
        "sensor_offset:az",
        "--serial",
        "--band",
        "0.3:12:0.05",
        "--output",
        str(tmp_path / "b"),
        "--json",
    )
    assert code == 0
    files = list((tmp_path / "b" / "results").glob("*.json"))
    saved = json.loads(files[0].read_text())
    assert saved["model"]["effects"] == ["time_delay@alpha", "sensor_offset@az"]
    code, out, _ = run(
        capsys,
        "montecarlo",
        "--model",
        "dimensional",
        "--airspeed",
        "73.3",
        "--effect",
        "time_delay:alpha",
        "--set",
        "tau_alpha=0.03",
        "-n",
        "3",
        "--duration",
        "10",
        "--workers",
        "1",
        "--no-progress",
        "--json",
    )
    assert code == 0
    mc = json.loads(out)
    assert mc["used"] == 3 and "tau_alpha" in json.dumps(mc["stats"])
    assert mc["settings"]["truth_model"]["effects"] == ["time_delay@alpha"]


def test_cli_effects_lists_the_library(capsys):
    code, out, _ = run(capsys, "effects", "--json")
    assert code == 0
    cat = {e["key"]: e for e in json.loads(out)["effects"]}
    assert set(cat) == {e.key for e in registered_effects()}
    x = cat["sensor_offset@az"]["parameters"]["dimensional"][0]
    assert (x["name"], x["unit"], x["null"], x["plausible"]) == ("x_az", "m", 0.0, [-8.0, 8.0])
    code, out, _ = run(capsys, "effects")
    assert code == 0 and "time_delay:alpha" in out and "tau_alpha" in out


# --- bad input -----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--effect", "time_dilation:alpha"], "unknown effect.*known effects: .*time_delay"),
        (["--effect", "time_delay"], "give time_delay:CHANNEL"),
        (["--effect", "time_delay:beta"], "no channel 'beta'"),
        (["--effect", "sensor_offset:az", "--outputs", "alpha,q"], "sensor_offset@az acts on az"),
        (["--effect", "sensor_offset:alpha", "--outputs", "alpha,q"], "x_alpha is not identifiable"),
        (["--effect", "unmeasured_gust"], "noise model"),
        (["--effect", "gust_lag:alpha_w"], "alpha_w"),
    ],
)
def test_bad_effects_are_one_line_errors_exit_2(record, capsys, argv, match):
    import re

    code, _, err = run(
        capsys, "fit", str(record), "--model", "dimensional", "--airspeed", "73.3", "--band", "0.3:12:0.05", *argv
    )
    assert code == 2
    assert re.search(match, err), err
    assert len(err.strip().splitlines()) == 1


def test_identifiable_with_az_and_api_errors():
    base = make_model("dimensional", "sundowner")
    with pytest.raises(FdmlError, match="already in the model"):
        with_effects(base, "time_delay:alpha", "time_delay@alpha")
    with pytest.raises(ParameterError, match="unknown effect"):
        make_model("dimensional", "sundowner", effects=["nope"])
    # the alpha-vane offset is confounded with alpha and q alone, separated by a_z
    from fdml.models.effects import confounded_effect_parameters

    m = with_effects(base, "sensor_offset:alpha")
    assert [c[1] for c in confounded_effect_parameters(m, OMEGA, ("alpha", "q"))] == ["x_alpha"]
    assert confounded_effect_parameters(m, OMEGA, ("alpha", "q", "az")) == []
    assert confounded_effect_parameters(with_effects(base, "time_delay:alpha"), OMEGA, ("alpha", "q")) == []


@pytest.mark.parametrize("key, base", CASES)
def test_sensitivities_through_the_solve_equal_differences_of_the_response(key, base):
    """Every free parameter of a model with an effect: the sensitivities through the solve and the
    effects (root and matrix-level parameters analytic, output-level ones by their own differences)
    against central differences of the whole response.  Central differences with a relative step of
    1e-5 carry a truncation error near 1e-10 relative; 1e-7 leaves a margin for the response's
    curvature in the parameters."""
    m, _ = _with(key, base)
    names = [p.name for p in m.parameters if p.free]
    resp, dG, dH, dP = m.sensitivity(OMEGA, None, names)
    ref, rG, rH, rP = m._fd_sensitivity(OMEGA, m.values(), names)
    np.testing.assert_allclose(resp.G, ref.G, rtol=1e-12, atol=1e-15)
    for got, want in ((dG, rG), (dH, rH), (dP, rP)):
        assert np.max(np.abs(got - want)) <= 1e-7 * max(np.max(np.abs(want)), 1e-300)
