"""One verdict (issue 19): the rules both judges share, the physics of derivative sets, known sensor
positions, the adequacy check's verdict against the diagnosis's, and the report's recommendation.

References are independent of the code under test: the Navion's published mass, inertia and tail arm
for the lever-arm rule (computed here by hand), sampled steps whose position is known by
construction for the edge detector, and the issue's own statements for the verdicts.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

import fdml
from fdml.aircraft import get_aircraft
from fdml.cli import main
from fdml.diagnose import diagnose
from fdml.diagnose.truth import simulate_truth
from fdml.kinematics import input_resolution, unresolved_edges
from fdml.models.effects import get_effect
from fdml.models.plausibility import LEVER_FACTOR, MARGIN, derivative_problems
from fdml.record import Record
from fdml.verdict import ABSORBS, choose_among, judge

NAVION = fdml.make_model("dimensional", "navion")


# --- the physics of a derivative set -----------------------------------------------------------------------------


def test_sign_rules_break_only_beyond_the_margin():
    assert derivative_problems(NAVION, {"Z_de": -0.2, "M_q": -2.6}, {"Z_de": 0.01, "M_q": 0.1}) == []
    # Z_de positive by 15 standard errors: an elevator that pushes its surface down when deflected down
    probs = derivative_problems(NAVION, {"Z_de": 0.6}, {"Z_de": 0.04})
    assert len(probs) == 1 and "Z_de" in probs[0] and "wrong sign" in probs[0]
    # positive, but within MARGIN standard errors of zero: the data cannot say it is wrong
    assert derivative_problems(NAVION, {"Z_de": 0.02}, {"Z_de": 0.02 / (MARGIN - 0.5)}) == []
    assert derivative_problems(NAVION, {"M_q": 1.0}, {"M_q": 0.1})  # an undamped pitch


def test_lever_arm_rule_from_the_navion_geometry():
    """Z_de = M_de Iy / (m U l_t) with the Navion's mass 1247.379 kg, Iy 4067.454 kg m^2, U 53.6448 m/s and
    l_t 4.602962 m (its preset's sources): M_de -18.2753 gives -0.2413, near the preset's Z_de -0.2296."""
    pred = -18.2753 * 4067.454 / (1247.379 * 53.6448 * 4.602962)
    assert derivative_problems(NAVION, {"Z_de": -0.2296, "M_de": -18.2753}, {"Z_de": 0.005}) == []
    too_big = LEVER_FACTOR * pred - 10 * 0.005  # beyond 3x the lever-arm value by 10 standard errors
    probs = derivative_problems(NAVION, {"Z_de": too_big, "M_de": -18.2753}, {"Z_de": 0.005})
    assert any("lever-arm" in p for p in probs)


# --- judge and choose_among ----------------------------------------------------------------------------------------


def test_a_delay_below_a_quarter_sample_absorbs_a_model_error():
    eff = get_effect("time_delay@de")
    why = judge(eff, {"tau_de": (0.001, 1e-4)}, NAVION, {}, dt=0.02, U=53.6)
    assert why is not None and why.startswith(ABSORBS)
    assert judge(eff, {"tau_de": (0.01, 1e-3)}, NAVION, {}, dt=0.02, U=53.6) is None
    # an elevator that steps between samples: its timing is known to half a sample only
    why = judge(eff, {"tau_de": (0.008, 1e-3)}, NAVION, {}, dt=0.02, U=53.6, input_floor=0.01)
    assert why is not None and why.startswith(ABSORBS)
    # an aerodynamic effect has no such floor
    assert judge(get_effect("lift_lag@alpha"), {"y_lift": (0.001, 1e-4)}, NAVION, {}, dt=0.02, U=53.6) is None


def test_unphysical_derivatives_demote_a_candidate():
    eff = get_effect("sensor_offset@az")
    why = judge(eff, {"x_az": (-5.0, 0.3)}, NAVION, {"Z_de": (0.63, 0.04)}, dt=0.04, U=129.0)
    assert why is not None and "not physical" in why and "Z_de" in why
    # 13 m behind the c.g.: no accelerometer package sits there; the size alone sets it aside
    why = judge(eff, {"x_az": (-13.0, 0.3)}, NAVION, {"Z_de": (-0.1, 0.04)}, dt=0.04, U=129.0)
    assert why is not None and "outside its plausible range" in why


class _C:
    def __init__(self, lr, q=1, plausible=True):
        self.lr, self.q_eff, self.plausible = lr, q, plausible


def test_choose_among_ranks_by_bic_and_never_by_order():
    a, b, c = _C(100.0), _C(90.0), _C(70.0)
    for order in ([c, b, a], [a, b, c], [b, c, a]):
        best, amb = choose_among(order, n_obs=200)
        # 10 < 15.4: a and b are one alias set; 30 > 15.4: c is told apart
        assert best is a and set(map(id, amb)) == {id(a), id(b)}
    # one more parameter costs ln(200) in BIC and 2 in the Akaike-penalised comparison
    d = _C(104.0, q=2)
    best, amb = choose_among([a, d], n_obs=200)
    assert best is a and set(map(id, amb)) == {id(a), id(d)}
    assert choose_among([], n_obs=10) == (None, [])


# --- unresolved input edges ------------------------------------------------------------------------------------


def test_steps_between_samples_are_found_and_ramps_are_not():
    t = np.arange(0.0, 4.0, 0.02)
    step = np.where(t > 1.013, 0.02, 0.0) - np.where(t > 2.517, 0.02, 0.0)
    ramp = np.clip((t - 1.0) / 0.1, 0, 1) * 0.02  # five samples
    assert unresolved_edges(step) == 2
    assert unresolved_edges(ramp) == 0
    rec = Record(t, {"de": step, "alpha": 0 * t, "q": 0 * t, "az": 0 * t}, check_units=False)
    assert input_resolution([rec], 0.02) == pytest.approx(0.01)
    assert input_resolution([None], 0.02) == pytest.approx(0.005)


# --- known sensor positions --------------------------------------------------------------------------------------


def _aircraft_file(tmp_path, sensors) -> Path:
    d = get_aircraft("navion").to_dict()
    d["sensors"] = sensors
    path = tmp_path / "navion_sensors.json"
    path.write_text(json.dumps(d))
    return path


def test_known_positions_are_fixed_offsets_of_every_model(tmp_path):
    m = fdml.make_model("derivatives", _aircraft_file(tmp_path, {"alpha": {"x": 2.5}, "az": {"x": -0.3}}))
    p = m.parameters
    assert not p["x_alpha"].free and p["x_alpha"].value == 2.5
    assert not p["x_az"].free and p["x_az"].value == -0.3


@pytest.mark.parametrize(
    "sensors, words",
    [
        ({"beta": {"x": 1.0}}, "unknown channel 'beta'"),
        ({"alpha": {"x": 80.0}}, "outside any airframe"),
        ({"alpha": 3.0}, 'must be {"x"'),
        ({"alpha": {"x": "a"}}, "must be a number"),
        ([1, 2], "must map channels"),
    ],
)
def test_bad_sensor_entries_are_refused_in_one_line(tmp_path, capsys, sensors, words):
    path = _aircraft_file(tmp_path, sensors)
    rec = tmp_path / "r.csv"
    simulate_truth(NAVION, None, {}, maneuver="3211", noise=0.02, seed=1, duration=8).to_csv(rec)
    code = main(["fit", str(rec), "--aircraft", str(path), "--model", "dimensional"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and words in err and len(err.splitlines()) == 1


# --- one verdict: the adequacy check and the diagnosis ---------------------------------------------------------


@pytest.fixture(scope="module")
def delayed():
    """A 40 ms alpha lag on a Navion record: the kinematics settle it."""
    rec = simulate_truth(NAVION, "time_delay@alpha", {"tau_alpha": 0.04}, maneuver="3211", noise=0.03, seed=21)
    return rec, fdml.fit(rec, NAVION), diagnose(rec, NAVION)


def test_the_fit_names_first_what_the_diagnosis_accepts_first(delayed):
    _, res, rep = delayed
    v = res.adequacy.verdict
    assert v is not None and v.key == "time_delay@alpha" and v.source == "kinematics"
    assert rep.selected[0]["key"] == v.key and rep.selected[0]["source"] == "kinematics"
    assert abs(v.params["tau_alpha"][0] - 0.04) < 3 * v.params["tau_alpha"][1]
    msg = next(str(w) for w in res.warnings if w.category == "AdequacyWarning")
    assert "settle time_delay@alpha" in msg and "--fix tau_alpha=" in msg


def test_the_report_carries_the_recommendation(delayed):
    _, _, rep = delayed
    d = json.loads(rep.to_json())
    rec = d["recommended"]
    assert rec["settled_by_kinematics"] == ["time_delay@alpha"] and rec["ambiguous"] is False
    assert rec["alternatives"] == []
    assert set(rec["derivatives"]) == {"Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de"}
    assert all(len(v["recommended"]) == 2 and len(v["base"]) == 2 for v in rec["derivatives"].values())
    assert d["kinematics"]["settled"][0]["key"] == "time_delay@alpha"
    back = type(rep).from_dict(d)
    assert back.recommendation["settled_by_kinematics"] == ["time_delay@alpha"]
    assert back.kinematics["settled"][0]["param"] == "tau_alpha"
    # the settled delay's uncertainty is carried into the recommended standard errors
    shifts = rep.recommended.options["known_uncertainty"]["tau_alpha"]
    assert shifts["stderr"] > 0 and any(abs(x) > 0 for x in shifts["shift_per_se"].values())


def test_a_clean_record_gives_no_verdict():
    rec = simulate_truth(NAVION, None, {}, maneuver="3211", noise=0.03, seed=22)
    res = fdml.fit(rec, NAVION)
    assert res.adequacy.verdict is None or res.adequacy.verdict.key is None
    assert diagnose(rec, NAVION).verdict == "none"


@pytest.mark.slow
def test_an_alias_the_data_cannot_separate_is_ambiguous_in_both():
    """A 1.5 m vane offset on a record of the independent truth: the vane and an accelerometer 1.5 m aft
    are one model with free dimensional derivatives; only the physics of the derivatives each implies
    can separate them.  Neither judge may pick one by order: both name the same first, and where it
    stays ambiguous both say so and list both."""
    sys.path.insert(0, str(Path(__file__).parent))
    import independent_truth as T

    rec, _ = T.simulate_record(sensors=T.Sensors(x_alpha=1.5), noise=0.03, rng=np.random.default_rng(3))
    base = fdml.make_model("dimensional", "navion")
    res, rep = fdml.fit(rec, base), diagnose(rec, base)
    v = res.adequacy.verdict
    first = rep.selected[0]["key"]
    assert v.key == first
    if rep.recommendation["ambiguous"]:
        assert v.ambiguous and {"sensor_offset@alpha", "sensor_offset@az"} <= set(v.aliases)
    else:  # separated, by the physics of the derivatives only
        assert first == "sensor_offset@alpha"
    assert math.isfinite(rep.recommended.params["Z_de"])


# --- a fixed parameter known to a standard error ---------------------------------------------------------------


def test_known_uncertainty_is_carried_exactly_for_a_linear_estimator():
    """theta_hat(psi) = theta0 + J (psi - psi0): the covariance grows by J s^2 J^T, exactly."""
    from dataclasses import dataclass, field
    from types import SimpleNamespace

    from fdml.propagate import with_known_uncertainty

    @dataclass(frozen=True)
    class Result:
        names: tuple
        values: np.ndarray
        cov: np.ndarray
        model: object
        options: dict = field(default_factory=dict)

        @property
        def stderr(self):  # derived from cov, as FitResult's is
            return np.sqrt(np.diag(self.cov))

        @property
        def params(self):
            return dict(zip(self.names, self.values))

    theta0, J, psi0, s = np.array([1.0, -2.0, 0.5]), np.array([0.3, -1.2, 0.0]), 13.0, 0.4
    cov = np.diag([0.01, 0.04, 0.09])
    model = SimpleNamespace(parameters=SimpleNamespace(values={"x_alpha": psi0}))

    def refit(values):
        return Result(("a", "b", "c"), theta0 + J * (values["x_alpha"] - psi0), cov, model)

    res = Result(("a", "b", "c"), theta0, cov, model)
    out = with_known_uncertainty(res, refit, {"x_alpha": s})
    np.testing.assert_allclose(out.cov, cov + s**2 * np.outer(J, J), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(out.stderr, np.sqrt(np.diag(cov) + (s * J) ** 2), rtol=1e-12)
    assert out.stderr[2] == pytest.approx(0.3)  # a parameter the known one does not move keeps its error
    assert out.options["known_uncertainty"]["x_alpha"]["stderr"] == s


def test_theta_beside_alpha_q_and_az_leaves_the_kinematics_in_the_fits_check():
    """The fit's check reads the short-period identity whenever alpha, q and a_z are among the fitted
    outputs, as the diagnosis does; it used to require exactly those three, so with theta fitted too it
    fell back to refits and called an alias set what the diagnosis had settled."""
    from fdml.models import with_effects
    from fdml.simulate import simulate_maneuver

    model = fdml.make_model("dimensional", "navion", outputs=("theta",))
    truth = with_effects(model, "time_delay:alpha").with_values(tau_alpha=0.04)
    rec = simulate_maneuver(truth, "3211", duration=20.0, dt=0.02, noise=0.03, seed=21)
    assert "theta" in rec.signals
    res = fdml.fit(rec, model, outputs="alpha,q,az,theta")
    v = res.adequacy.verdict
    assert v is not None and v.key == "time_delay@alpha" and v.source == "kinematics"
    rep = diagnose(rec, model, outputs="alpha,q,az,theta")
    assert rep.selected[0]["key"] == v.key and rep.selected[0]["source"] == "kinematics"
