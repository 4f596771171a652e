"""Every public result class with ``to_dict`` has ``from_dict``, its inverse, with one-line errors.

Each instance is made by the public computation that produces it, on one small simulated record
(the Navion's unsteady model, a 12 s 3-2-1-1 with 2 % noise), and read back from the JSON text of
its ``to_dict``: the copy's ``to_dict`` equals the original's (and, where no array or NaN is
involved, the copy equals the original).  A damaged dict (a key missing, a key of the wrong
type, not an object at all) raises one FdmlError line that names the source.
"""

from __future__ import annotations

import importlib
import inspect
import json
import pkgutil

import numpy as np
import pytest

import fdml
from fdml import fit
from fdml.adequacy import Adequacy, Verdict
from fdml.batch import ModelSpec
from fdml.datacheck import DataCheck, check_data
from fdml.design import Design, Discrimination, Prediction, design
from fdml.design.discrimination import Detectable
from fdml.diagnose.data import analysis_data
from fdml.diagnose.likelihood import fit_model, noise_bands
from fdml.diagnose.locate import Cell, default_bands, forced_response, gap_map
from fdml.errors import FdmlError
from fdml.findings import Finding
from fdml.flightpath import CompatibilityResult, ParameterEstimate, check_compatibility
from fdml.jsoncodec import dumps, to_jsonable
from fdml.kinematics import KinematicEvidence, kinematic_evidence
from fdml.models import make_model
from fdml.parameters import Parameter, Role, Slot
from fdml.quality import ChannelQuality, QualityReport, check_quality
from fdml.record import Record
from fdml.simulate import simulate_maneuver
from fdml.spectral import spectra
from fdml.warning_log import RecordedWarning
from fdml.wind import GustEstimate, gust_angle

#: Subpackages that are not public API (as tests/test_docstrings.py).
PRIVATE_PACKAGES = ("fdml.commands",)
#: Named in every error of the damaged dicts.
SOURCE = "damaged file x.json"


def _public_classes() -> dict[str, type]:
    """Every class in the ``__all__`` of every public fdml module (as tests/test_docstrings.py finds them)."""
    names = ["fdml"]
    for info in pkgutil.walk_packages(fdml.__path__, "fdml."):
        parts = info.name.split(".")
        if not any(p.startswith("_") for p in parts[1:]) and not info.name.startswith(PRIVATE_PACKAGES):
            names.append(info.name)
    out = {}
    for modname in names:
        mod = importlib.import_module(modname)
        for name in getattr(mod, "__all__", ()):
            obj = getattr(mod, name)
            if inspect.isclass(obj) and obj.__module__.startswith("fdml"):
                out[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return out


def test_every_class_with_to_dict_has_from_dict():
    classes = _public_classes()
    with_to = {k for k, c in classes.items() if callable(getattr(c, "to_dict", None))}
    assert len(with_to) >= 20  # the scan sees the result classes (it would pass vacuously otherwise)
    missing = sorted(k for k in with_to if not callable(getattr(classes[k], "from_dict", None)))
    assert not missing, f"to_dict without from_dict: {missing}"


# --- real instances ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def record():
    return simulate_maneuver(make_model("unsteady", "navion"), "3211", duration=12, noise=0.02, seed=1)


@pytest.fixture(scope="module")
def fitted(record):
    return fit(record, make_model("unsteady", "navion"))


@pytest.fixture(scope="module")
def air_record(record):
    """The record about a trim (alpha 0.05 rad, a_z -1 g) with attitude, airspeed and vertical speed.

    theta integrates q (trapezoids) from alpha(0); V is constant; hdot = V sin(theta - alpha).
    """
    t, q, U = record.t, record["q"], float(record.meta["U"])
    alpha = record["alpha"] + 0.05
    theta = alpha[0] + np.concatenate([[0.0], np.cumsum((q[1:] + q[:-1]) / 2 * np.diff(t))])
    sig = {
        **record.signals,
        "alpha": alpha,
        "az": record["az"] - 1.0,
        "theta": theta,
        "V": np.full_like(t, U),
        "hdot": U * np.sin(theta - alpha),
    }
    return Record(t, sig, name="air data", meta={"U": U})


@pytest.fixture(scope="module")
def plan():
    return design(
        make_model("unsteady", "navion"), duration=12.0, band="0.5:10", refine=2, detect=("time_delay:alpha",)
    )


@pytest.fixture(scope="module")
def cell(record):
    base = make_model("steady", "navion")
    data = analysis_data(record, (0.3, 12.0, 0.05))
    f0 = fit_model(data, base, noise_bands(data))
    gm = gap_map(data, f0.full_residual(), forced_response(data, f0.model), default_bands(data))
    return gm.cells[0]


@pytest.fixture(scope="module")
def instances(record, fitted, air_record, plan, cell):
    """Class -> (instance, keyword arguments of from_dict, whether the copy must equal the original)."""
    comp = check_compatibility(air_record)
    estimate = next(iter(comp.params.values()))
    quality = check_quality(record)
    return {
        RecordedWarning: (RecordedWarning("DataWarning", "ends far from trim"), {}, True),
        Slot: (fitted.slots[0], {"name": fitted.slots[0].name}, True),
        Parameter: (fitted.model.parameters["CLa_w"], {}, True),
        Finding: (Finding("units.q", "q looks like deg/s", record="r", value=57.3, expected=1.0), {}, True),
        Adequacy: (fitted.adequacy, {}, True),
        DataCheck: (check_data(record), {}, True),
        ParameterEstimate: (estimate, {"name": estimate.name}, True),
        CompatibilityResult: (comp, {}, False),
        ChannelQuality: (quality.channels[0], {}, True),
        QualityReport: (quality, {}, False),
        GustEstimate: (gust_angle(air_record), {}, False),
        Cell: (cell, {}, False),
        ModelSpec: (ModelSpec.from_model(fitted.model).normalized(), {}, False),
        Discrimination: (plan.discrimination[plan.input.name], {}, True),
        Detectable: (plan.detectable[0], {}, True),
        Prediction: (plan.predicted, {"noise": plan.noise, "input": plan.input}, False),
        Design: (plan, {"input": plan.input}, False),
        Verdict: (_delayed_fit().adequacy.verdict, {}, True),
        KinematicEvidence: (kinematic_evidence([spectra(_delayed_record())], 53.6448), {}, False),
    }


CLASSES = [
    RecordedWarning,
    Slot,
    Parameter,
    Finding,
    Adequacy,
    DataCheck,
    ParameterEstimate,
    CompatibilityResult,
    ChannelQuality,
    QualityReport,
    GustEstimate,
    Cell,
    ModelSpec,
    Discrimination,
    Detectable,
    Prediction,
    Design,
    Verdict,
    KinematicEvidence,
]


def _delayed_record():
    """A Navion record whose alpha lags 40 ms: the kinematics settle it, and a fit flags it."""
    from fdml.diagnose.truth import simulate_truth

    base = make_model("dimensional", "navion")
    return simulate_truth(base, "time_delay@alpha", {"tau_alpha": 0.04}, maneuver="3211", noise=0.03, seed=5)


def _delayed_fit():
    return fit(_delayed_record(), make_model("dimensional", "navion"))


def _through_json(obj) -> dict:
    return json.loads(dumps(obj.to_dict()))


@pytest.mark.slow
@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_round_trip_through_json(cls, instances):
    obj, kw, exact = instances[cls]
    back = cls.from_dict(_through_json(obj), **kw)
    assert type(back) is cls
    assert to_jsonable(back.to_dict()) == to_jsonable(obj.to_dict())
    if exact:
        assert back == obj


def test_restored_arrays_and_what_is_not_restored(instances, plan):
    q = QualityReport.from_dict(_through_json(instances[QualityReport][0]))
    np.testing.assert_array_equal(q.omega, instances[QualityReport][0].omega)  # JSON floats are exact (repr)
    assert set(q.coherence) == set(instances[QualityReport][0].coherence)
    g = GustEstimate.from_dict(_through_json(instances[GustEstimate][0]))
    with pytest.raises(FdmlError, match="does not keep the record"):
        g.record  # noqa: B018 (the property raises)
    c = CompatibilityResult.from_dict(_through_json(instances[CompatibilityResult][0]))
    assert c.record is None and c.corr.shape == (len(c.names), len(c.names))
    p = Prediction.from_dict(_through_json(plan.predicted))
    assert p.stderr == {n: plan.predicted.stderr[n] for n in p.names}  # sqrt(fl(s * s)) == s in IEEE arithmetic
    assert set(p.names) == set(plan.predicted.to_dict())  # the model parameters: nuisance terms are not written
    assert np.count_nonzero(p.cov - np.diag(np.diag(p.cov))) == 0  # no correlations are written


def test_names_left_to_the_container():
    """Their to_dict leaves out the name: a Slot's defaults to the base name, an estimate's is required."""
    slot = Slot.from_dict({"base": "bias_q", "role": "output_bias", "record": "r1"})
    assert slot == Slot("bias_q", "bias_q", Role.OUTPUT_BIAS, "r1")
    assert Slot.from_dict(slot.to_dict(), name="bias_q[r1]").name == "bias_q[r1]"
    with pytest.raises(TypeError):
        ParameterEstimate.from_dict({})  # name is keyword-only and required


def test_design_reads_its_input_csv(plan, tmp_path):
    path = tmp_path / "input.csv"
    plan.input.to_csv(path)
    back = Design.from_dict(json.loads(dumps(plan.to_dict(path))))
    np.testing.assert_array_equal(back.input.de, plan.input.de)  # %.17g: exact
    assert back.input.name == plan.input.name
    assert to_jsonable(back.to_dict(path)) == to_jsonable(plan.to_dict(path))
    assert back.baselines["3211"].input is None  # the baselines' histories are not written
    with pytest.raises(FdmlError, match="input CSV"):
        Design.from_dict(_through_json(plan), source=SOURCE)


# --- damaged dicts ------------------------------------------------------------------------------
#: Class -> (a key to delete, a key to give the wrong type); a key path "a.b" reaches into a nested object.
DAMAGE = {
    RecordedWarning: ("message", "category"),
    Slot: ("base", "role"),
    Parameter: ("name", "lower"),
    Finding: ("code", "value"),
    Adequacy: ("alpha", "whiteness"),
    DataCheck: ("record", "kinematics.slope_q"),
    ParameterEstimate: ("stderr", "unit"),
    CompatibilityResult: ("names", "corr"),
    ChannelQuality: ("resolution", "n_levels"),
    QualityReport: ("omega", "channels"),
    GustEstimate: ("alpha_w", "t"),
    Cell: ("channel", "significant"),
    ModelSpec: ("kind", "values"),
    Discrimination: ("noncentrality", "steady_values"),
    Detectable: ("minimum", "effect"),
    Prediction: ("CLa_w.stderr", "CLa_w.value"),
    Design: ("criterion", "band"),
    Verdict: ("source", "params"),
    KinematicEvidence: ("airspeed", "source"),
}


def _container(d: dict, path: str) -> tuple[dict, str]:
    *outer, last = path.split(".")
    for k in outer:
        d = d[k]
    return d, last


def _refused(cls, d, kw) -> str:
    with pytest.raises(FdmlError) as err:
        cls.from_dict(d, **kw, source=SOURCE)
    text = str(err.value)
    assert "\n" not in text and SOURCE in text, text
    return text


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_damaged_dict_is_refused_in_one_line(cls, instances):
    obj, kw, _ = instances[cls]
    missing, mistyped = DAMAGE[cls]
    d = _through_json(obj)
    inner, key = _container(d, missing)
    del inner[key]
    assert key in _refused(cls, d, kw)
    d = _through_json(obj)
    inner, key = _container(d, mistyped)
    inner[key] = [True] if isinstance(inner[key], str) else "not a value"
    assert key in _refused(cls, d, kw)
    _refused(cls, ["not", "an", "object"], kw)
