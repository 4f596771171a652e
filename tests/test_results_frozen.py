"""Results keep everything and are really frozen; every warning of a fit is kept (issue 10).

Pins: typed roles instead of names (``Role``, ``Slot``), read-only arrays and
immutable mappings in :class:`FitResult`, every fit option stored and
round-tripped, ``conf_int``, ``resid``, ``to_json(include_data=False)``,
every warning recorded with its category, :class:`BoundsWarning` raised, and
the estimator's named thresholds (:class:`EstimatorSettings`).
"""

from __future__ import annotations

import dataclasses
import pickle
import warnings

import numpy as np
import pytest

from fdml.errors import (
    BoundsWarning,
    ConvergenceWarning,
    DataWarning,
    FdmlError,
    ParameterError,
)
from fdml.estimate import SETTINGS, EstimatorSettings, fit
from fdml.jsoncodec import loads
from fdml.models import make_model, with_effects
from fdml.parameters import Parameter, Parameters, Role, Slot
from fdml.plotting import simulate_fit
from fdml.record import Record, add_noise
from fdml.results import FitResult, IterationInfo
from fdml.simulate import simulate_maneuver
from fdml.warning_log import RecordedWarning, recording


def _quiet_fit(rec, model, **kw):
    with recording(reemit=False):  # kept in the result, not shown
        return fit(rec, model, **kw)


@pytest.fixture(scope="module")
def model():
    """The steady Navion model (Wells-Keskar's steady set)."""
    return make_model("steady", "navion")


@pytest.fixture(scope="module")
def rec(model):
    clean = simulate_maneuver(model, "3211", duration=10.0, dt=0.02)
    return add_noise(clean, 0.02, np.random.default_rng(3), relative=True)


@pytest.fixture(scope="module")
def res(rec, model):
    return _quiet_fit(rec, model, trim="mean", trim_window=1.0, tol=2e-3, bounds={"Cm_de": (-5.0, None)})


@pytest.fixture(scope="module")
def cut(rec):
    """The record cut at 2.6 s, while the response to the 3-2-1-1 is still large: it ends far from trim."""
    keep = rec.t <= 2.6
    return Record(rec.t[keep], {k: v[keep] for k, v in rec.signals.items()}, name="cut")


@pytest.fixture(scope="module")
def two(model):
    """A fit of two records: per-record nuisance terms ``bias_q[a]``, ``x0_alpha[b]``, ..."""
    recs = []
    for name, seed in (("a", 1), ("b", 2)):
        clean = simulate_maneuver(model, "3211", duration=8.0, dt=0.02)
        recs.append(dataclasses.replace(add_noise(clean, 0.02, np.random.default_rng(seed), relative=True), name=name))
    return _quiet_fit(recs, model)


# --- 1. typed roles ---------------------------------------------------------------------------------
def test_model_parameters_carry_their_role(model):
    p = model.parameters
    assert p["Cm_de"].role is Role.AERO
    assert p["tau_de"].role is Role.DELAY
    assert p["bias_q"].role is Role.OUTPUT_BIAS
    eff = with_effects(model, "time_delay:alpha").parameters
    assert eff["tau_alpha"].role is Role.EFFECT
    assert Role.OUTPUT_BIAS.nuisance and Role.BOUNDARY.nuisance and not Role.DELAY.nuisance


def test_role_not_name_decides_what_is_nuisance():
    """A model parameter named like a bias is still a model parameter: the role decides."""
    ps = Parameters(
        (Parameter("bias_like", 1.0), Parameter("tau_x", 0.0, role=Role.DELAY), Parameter("k", 0.0, role="output_bias"))
    )
    assert ps.free_model_names == ("bias_like", "tau_x")
    assert ps["k"].role is Role.OUTPUT_BIAS  # its JSON string is accepted
    assert Parameter.from_dict(ps["tau_x"].to_dict()) == ps["tau_x"]
    with pytest.raises(ParameterError, match="unknown role 'gain'"):
        Parameter("g", 1.0, role="gain")


def test_per_record_slots_are_typed(two):
    slots = {s.name: s for s in two.slots}
    assert slots["bias_q[a]"] == Slot("bias_q[a]", "bias_q", Role.OUTPUT_BIAS, "a")
    assert slots["x0_alpha[b]"] == Slot("x0_alpha[b]", "x0_alpha", Role.BOUNDARY, "b")
    assert slots["Cm_de"].record is None and slots["Cm_de"].role is Role.AERO
    assert two.model_names == ("CLa_w", "CLa_t", "deps_da", "Cm_de", "Cz_de")  # the free ones, no nuisance
    # the nuisance values of record b are its own estimates (Eq. 18-19 terms of that record)
    nu = two.nuisance_values(1)
    assert nu.biases[1] == two["bias_q[b]"] and nu.x0[0] == two["x0_alpha[b]"]


def test_old_result_without_slots_gets_them_back(two):
    d = two.to_dict()
    del d["slots"]
    assert FitResult.from_dict(d).slots == two.slots


# --- 2. really frozen ---------------------------------------------------------------------------------
def test_arrays_are_read_only_and_mappings_immutable(res):
    before = str(res.summary())
    with pytest.raises(ValueError, match="read-only"):
        res.values[0] = 99.0
    for arr in (res.stderr, res.cov, res.corr, res.R, res.spectra[0].z, res.time_records[0].t, res.record()["q"]):
        with pytest.raises(ValueError):
            arr[..., 0] = 0
    with pytest.raises(TypeError):
        res.fixed["l_t"] = 1.0  # type: ignore[index]
    with pytest.raises(TypeError):
        res.options["tol"] = 1.0  # type: ignore[index]
    with pytest.raises(TypeError):
        res.time_records[0].signals["q"] = None  # type: ignore[index]
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.converged = False  # type: ignore[misc]
    assert str(res.summary()) == before


def test_frozen_result_pickles_copies_and_replaces(res):
    back = pickle.loads(pickle.dumps(res))
    np.testing.assert_array_equal(back.values, res.values)
    assert back.options == res.options and back.warnings == res.warnings and back.slots == res.slots
    assert not back.values.flags.writeable
    vals = np.array(res.values)
    vals[0] += 1.0
    moved = dataclasses.replace(res, values=vals)
    assert not moved.values.flags.writeable and vals.flags.writeable  # the caller's array stays theirs
    info = IterationInfo(1, 2.0, {"a": 1.0}, 0.1)
    with pytest.raises(TypeError):
        info.params["a"] = 2.0  # type: ignore[index]


# --- 3. every option kept; conf_int, resid, include_data -------------------------------------------------
def test_every_option_is_kept_and_round_trips(res):
    o = res.options
    assert o["trim"] == "mean" and o["trim_window"] == 1.0 and o["tol"] == 2e-3
    assert o["end_correction"] == "cubic" and o["cov_type"] == "white" and o["noise"] == ()
    assert o["sensitivity"] == "analytic"  # "auto" as resolved: every steady parameter has a closed form
    assert o["bounds"] == {"Cm_de": (-5.0, None)} and o["biases"] is True  # "auto" with trim removed
    assert set(o) >= {"band", "boundary", "method", "stop", "max_iter", "free", "fix", "outputs", "adequacy"}
    back = FitResult.from_dict(loads(res.to_json()))
    assert back.options == o


def test_simulate_fit_uses_the_fits_trim_window(res):
    own = simulate_fit(res)
    np.testing.assert_array_equal(own["q"], simulate_fit(res, trim_window=1.0)["q"])
    # the trim added back is the mean of the first second, not of the first half second
    assert not np.array_equal(own["q"], simulate_fit(res, trim_window=0.5)["q"])


def test_conf_int_is_the_normal_interval(res):
    ci = res.conf_int()
    # 1.959964: the standard normal 97.5 % quantile (published tables)
    np.testing.assert_allclose(ci[:, 0], res.values - 1.959964 * res.stderr, rtol=1e-6)
    np.testing.assert_allclose(ci[:, 1], res.values + 1.959964 * res.stderr, rtol=1e-6)
    np.testing.assert_allclose(res.conf_int(0.10)[:, 1] - res.values, 1.644854 * res.stderr, rtol=1e-6)
    assert ci.shape == (len(res.names), 2)
    with pytest.raises(FdmlError, match="alpha"):
        res.conf_int(1.5)


def test_resid_is_the_residual_whose_covariance_is_R(res):
    V = res.resid
    assert V.dtype.kind == "c" and V.shape == (res.n_freq, len(res.outputs)) and not V.flags.writeable
    R = V.T @ V.conj() / V.shape[0]  # Eq. 24
    floor = SETTINGS.r_floor * np.real(np.diag(R)).max()  # the fit's documented floor
    # one sum over the band: rounding far below 1e-12 of the largest variance
    np.testing.assert_allclose(res.R, R + floor * np.eye(len(res.outputs)), rtol=0, atol=1e-12 * np.abs(R).max())


def test_to_json_without_data_drops_the_records_only(res):
    full, lean = res.to_json(), res.to_json(include_data=False)
    assert len(lean) < 0.6 * len(full)  # the time histories are most of a result
    back = FitResult.from_dict(loads(lean))
    assert back.time_records == () and len(back.spectra) == 1
    np.testing.assert_array_equal(back.values, res.values)
    np.testing.assert_array_equal(back.resid, res.resid)
    with pytest.raises(FdmlError, match="no time-domain records"):
        back.record()


# --- 4. warnings: every one, with its category -----------------------------------------------------------
def test_every_warning_is_recorded_with_its_category(cut, model):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a caller's filter hides them; the result still keeps them
        res = fit(cut, model, boundary="none", max_iter=1)
    cats = {w.category for w in res.warnings}
    assert {"DataWarning", "ConvergenceWarning"} <= cats
    assert all(isinstance(w, RecordedWarning) for w in res.warnings)
    assert any(w.category == "DataWarning" and "ends far from trim" in w.message for w in res.warnings)
    text = str(res.summary())
    assert "ConvergenceWarning: fit did not converge" in text
    d = loads(res.to_json())
    assert {
        "category": "ConvergenceWarning",
        "message": "fit did not converge: maximum number of iterations reached",
    } in d["warnings"]
    assert FitResult.from_dict(d).warnings == res.warnings


def test_warnings_are_still_raised(cut, model):
    with pytest.warns(DataWarning, match="ends far from trim"), pytest.warns(ConvergenceWarning):
        fit(cut, model, boundary="none", max_iter=1, adequacy=False)


def test_old_string_warnings_still_load(res):
    d = res.to_dict()
    d["warnings"] = ["IdentifiabilityWarning: parameters a and b are correlated", "plain text"]
    back = FitResult.from_dict(d)
    assert back.warnings == (
        RecordedWarning("IdentifiabilityWarning", "parameters a and b are correlated"),
        RecordedWarning("UserWarning", "plain text"),
    )
    d["warnings"] = [3]
    with pytest.raises(FdmlError, match="warnings"):
        FitResult.from_dict(d)


# --- 5. BoundsWarning ----------------------------------------------------------------------------------
def test_estimate_on_a_bound_raises_and_records_bounds_warning(rec, model):
    free = _quiet_fit(rec, model)
    cap = free["Cm_de"] - 0.2  # a cap below the unconstrained estimate is active at the optimum
    with pytest.warns(BoundsWarning, match="Cm_de ended on its upper bound"):
        res = fit(rec, model, bounds={"Cm_de": (None, cap)}, adequacy=False)
    assert res["Cm_de"] == cap and "Cm_de" in res.at_bound
    assert any(w.category == "BoundsWarning" for w in res.warnings)
    assert not any(w.category == "BoundsWarning" for w in free.warnings)


# --- 6. named thresholds ----------------------------------------------------------------------------------
def test_settings_are_one_frozen_documented_object(res):
    assert isinstance(SETTINGS, EstimatorSettings)
    with pytest.raises(dataclasses.FrozenInstanceError):
        SETTINGS.correlation_warn = 0.5  # type: ignore[misc]
    for f in dataclasses.fields(EstimatorSettings):
        assert f"    {f.name} :" in EstimatorSettings.__doc__, f.name
    # the summary lists correlations below the level at which the fit warns
    assert SETTINGS.correlation_listed < SETTINGS.correlation_warn
    assert f"|r| >= {SETTINGS.correlation_listed:g}" in str(res.summary()) or not np.any(
        np.abs(np.tril(np.nan_to_num(res.corr), -1)) >= SETTINGS.correlation_listed
    )


def test_dead_unit_helper_is_gone():
    assert not hasattr(FitResult, "_unit")


def test_other_results_are_frozen_too(res, two):
    from fdml.consistency import consistency

    c = consistency([res, _quiet_fit(two.record(0), make_model("steady", "navion"))])
    assert c.names == ("CLa_w", "CLa_t", "deps_da", "Cm_de", "Cz_de")  # model parameters by role, no biases
    for arr in (c.estimates, c.stderr, c.mean, c.p_value):
        with pytest.raises(ValueError, match="read-only"):
            arr[..., 0] = 0.0


@pytest.mark.parametrize("bad", [3, "text", {"category": "X"}])
def test_damaged_warnings_are_refused_in_one_line(res, bad):
    d = res.to_dict()
    d["warnings"] = bad if not isinstance(bad, dict) else [bad]
    with pytest.raises(FdmlError, match="key 'warnings"):
        FitResult.from_dict(d)
