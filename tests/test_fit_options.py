"""The options of a fit, declared once (issue 22): :class:`fdml.fit_options.FitOptions`.

The fit's signature, :func:`fdml.estimate.prepare`'s, the command line's fit options, batch's check
and hash and ``FitResult.options`` all come from the one table; every value is checked when the
options are made; and an option that does not apply (a band given with spectra made on another
band) is refused, not ignored.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import pickle
import re
from pathlib import Path

import numpy as np
import pytest

import fdml
from fdml.batch import _fit_options_key, check_fit_kwargs
from fdml.cli import build_parser
from fdml.errors import FdmlError
from fdml.estimate import fit, prepare
from fdml.fit_options import FitOptions, NoiseModel, command_line_options, option_docs
from fdml.models import make_model
from fdml.simulate import simulate_maneuver
from fdml.spectral import spectra

SRC = Path(fdml.__file__).parent


@pytest.fixture(scope="module")
def model():
    return make_model("steady", "navion")


@pytest.fixture(scope="module")
def record(model):
    """A 3-2-1-1 of 8 s at 20 Hz with 2 % noise."""
    return simulate_maneuver(model, "3211", duration=8.0, dt=0.05, noise=0.02, seed=3)


def _keyword_defaults(func) -> dict:
    return {p.name: p.default for p in inspect.signature(func).parameters.values() if p.kind is p.KEYWORD_ONLY}


# --- one table ----------------------------------------------------------------------------------
def test_every_fit_option_is_declared_once():
    table = {f.name: f.default for f in dataclasses.fields(FitOptions)}
    assert len(table) >= 20  # the table is the fit's options, not a stub
    # the signatures: the fit takes every option, prepare those of the spectra and the problem
    assert _keyword_defaults(fit) == {**table, "callback": None}
    spectra_and_problem = FitOptions.names("spectra", "problem")
    assert _keyword_defaults(prepare) == {k: table[k] for k in spectra_and_problem}
    assert {"band", "trim", "outputs", "fix"} <= set(spectra_and_problem) and "method" not in spectra_and_problem
    # the command line: each fit option of `fdml fit` is a field, with the field's values as its choices
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    group = next(g for g in sub.choices["fit"]._action_groups if g.title.startswith("fit options"))
    shown = {a.dest: a for a in group._group_actions}
    assert set(shown) == {o["name"] for o in command_line_options()} and set(shown) <= set(table)
    for o in command_line_options():
        field = next(f for f in dataclasses.fields(FitOptions) if f.name == o["name"])
        if field.metadata["choices"] and not o["repeat"]:
            spelled = shown[o["name"]].choices
            assert tuple(o["values"].get(c, c) for c in spelled) == field.metadata["choices"], o["name"]
    # each option's choices are spelled in one module (the trim modes and end corrections in the
    # record's and the transform's), and nothing reads the options back from the fit's signature
    literals = {
        f.name: "(" + ", ".join(map(repr, f.metadata["choices"])).replace("'", '"') + ")"
        for f in dataclasses.fields(FitOptions)
        if f.metadata["choices"] and all(isinstance(c, str) for c in f.metadata["choices"])
    }
    assert {"boundary", "cov_type", "trim", "end_correction"} <= set(literals)
    texts = {path: path.read_text(encoding="utf-8") for path in SRC.rglob("*.py")}
    assert not [p for p, t in texts.items() if "signature(fit)" in t]
    for name, lit in literals.items():
        spelled = [p.name for p, t in texts.items() if lit in t]
        assert len(spelled) <= 1, f"the choices of {name} are spelled in {spelled}"  # fourier: a mapping's keys


def test_the_docstrings_come_from_the_table():
    """Each option is documented once, in FitOptions' docstring; fit's and prepare's entries are those."""
    section = inspect.getdoc(FitOptions).split("Parameters\n----------\n")[1]
    heads = [ln for ln in section.splitlines() if ln and not ln.startswith(" ")]
    assert [h.split(" : ")[0] for h in heads] == list(FitOptions.names())  # every field, in order, nothing else
    for head in heads:
        name = head.split(" : ")[0]
        assert fit.__doc__.count(f"\n    {head}\n") == 1, name
        assert (f"\n    {head}\n" in prepare.__doc__) == (name in FitOptions.names("spectra", "problem")), name
    assert option_docs("checks").splitlines()[0] == "    check : bool, optional"
    assert "<the fit options" not in fit.__doc__ + prepare.__doc__


def test_batch_checks_and_hashes_through_the_table():
    for name in FitOptions.names():
        check_fit_kwargs({name: FitOptions.__dataclass_fields__[name].default})  # each option is known
    with pytest.raises(FdmlError, match=r"unknown fit option\(s\) \['bnad'\]"):
        check_fit_kwargs({"bnad": "0.1:10:0.1"})
    with pytest.raises(FdmlError, match="boundary must be 'estimated', 'measured' or 'none'"):
        check_fit_kwargs({"boundary": "guessed"})  # refused before any record is read
    # one hash for one fit however it is spelled; another band, another hash
    key = _fit_options_key({"band": "0.2:8"})
    assert key == _fit_options_key({"band": [0.2, 8.0, 0.1], "boundary": "estimated"})
    assert key != _fit_options_key({"band": "0.2:6"})


# --- checked once, when made ----------------------------------------------------------------------
@pytest.mark.parametrize(
    "given, fragment",
    [
        ({"boundary": "exact"}, "boundary must be 'estimated', 'measured' or 'none', got 'exact'"),
        ({"biases": "yes"}, "biases must be 'auto', True or False, got 'yes'"),
        ({"strict": "no"}, "strict must be True or False, got 'no'"),  # a truthy string is not True
        ({"tol": -1.0}, "tol must be a finite number of at least 0"),
        ({"max_iter": 2.5}, "max_iter must be an integer of at least 0"),
        ({"trim_window": float("nan")}, "trim_window must be a finite number"),
        ({"band": "1:0.5"}, "band"),
        ({"outputs": "alpha,beta"}, "unknown output(s) ['beta']"),
        ({"fix": "Cm_de", "free": ["Cm_de"]}, "Cm_de named in both fix and free"),
        ({"bounds": {"Cm_de": (1.0,)}}, "bounds: Cm_de must be (lower, upper)"),
        ({"bounds": {"Cm_de": (float("nan"), 1.0)}}, "bounds: Cm_de has a NaN bound"),
        ({"noise": "white"}, "noise must be an fdml.estimate.NoiseModel"),
        ({"trim": "median"}, "trim must be 'first', 'mean' or 'none', got 'median'"),
        ({"omega": []}, "omega must be a non-empty list"),
    ],
)
def test_a_bad_option_is_one_line_when_made(given, fragment):
    with pytest.raises(FdmlError) as err:
        FitOptions(**given)
    assert fragment in str(err.value) and "\n" not in str(err.value)


def test_values_are_normalised_and_the_object_is_frozen():
    o = FitOptions(band="0.5:8", outputs="q,alpha", free="Cm_q, Cm_a", fix={"Cz_de": -1}, noise=[0.5, 3.0, 9.0])
    assert o.band == (0.5, 8.0, 0.1) and o.outputs == ("q", "alpha") and o.free == ("Cm_q", "Cm_a")
    assert dict(o.fix) == {"Cz_de": -1.0} and o.noise == NoiseModel((0.5, 3.0, 9.0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.tol = 1.0  # type: ignore[misc]
    assert pickle.loads(pickle.dumps(o)) == o
    assert FitOptions.from_dict(o.to_dict()) == o
    assert FitOptions.of(o, max_iter=5) == dataclasses.replace(o, max_iter=5)


# --- options that do not apply ----------------------------------------------------------------------
def test_a_band_given_with_spectra_made_otherwise_is_refused(record, model):
    data = spectra(record)  # the default band 0.1:10:0.1, trim "first"
    made = r"band=1:5:0.1 does not apply to record 1 \('3211 simulation'\): it was given as spectra, made with band 0.1"
    with pytest.raises(FdmlError, match=made):
        fit(data, model, band="1:5:0.1")  # it used to be ignored: the fit ran on 0.1:10:0.1
    with pytest.raises(FdmlError, match="trim='mean' does not apply"):
        fit(data, model, trim="mean")
    with pytest.raises(FdmlError, match="omega=.* does not apply"):
        fit(data, model, omega=np.linspace(1.0, 5.0, 20))
    with pytest.raises(FdmlError, match="end_correction='trapezoid' does not apply"):
        fit([record, data], model, end_correction="trapezoid")  # the record's spectra follow it; these cannot
    # what the spectra were made with applies: the same fit as without it
    same = fit(data, model, band="0.1:10:0.1", trim="first", adequacy=False)
    plain = fit(data, model, adequacy=False)
    np.testing.assert_array_equal(same.values, plain.values)


def test_the_stored_options_are_resolved_and_refit_the_same(record, model):
    res = fit(record, model, band="0.5:8", trim="mean", adequacy=False)
    opts = FitOptions.from_dict(res.options)  # noise_covariance (a fact of the fit) is left aside
    assert opts.band == (0.5, 8.0, 0.1) and opts.trim == "mean" and opts.trim_window == pytest.approx(0.5)
    assert opts.biases is True and opts.sensitivity == "analytic"  # "auto" as resolved
    again = fit(record, model, opts)
    np.testing.assert_array_equal(again.values, res.values)
    on_spectra = fit(spectra(record, band="0.5:8", trim="mean"), model, opts)  # they apply to these spectra
    np.testing.assert_array_equal(on_spectra.values, res.values)
    # spectra given as such: the stored options say how they were made
    from_spectra = fit(spectra(record, band="1:6", trim="none"), model, adequacy=False)
    assert from_spectra.options["band"] == (1.0, 6.0, 0.1) and from_spectra.options["trim"] == "none"


def test_an_options_object_and_keywords_beside_it(record, model):
    opts = FitOptions(band="0.5:8", boundary="measured", adequacy=False)
    res = fit(record, model, opts, max_iter=1)
    assert res.iterations == 1 and res.options["boundary"] == "measured" and res.options["max_iter"] == 1
    assert opts.max_iter == 200  # the object given is not changed
    with pytest.raises(FdmlError, match=r"unknown fit option\(s\) \['bands'\]"):
        fit(record, model, bands="0.5:8")
    with pytest.raises(FdmlError, match="options must be an fdml FitOptions, got dict"):
        fit(record, model, {"band": "0.5:8"})
    with pytest.raises(FdmlError, match=re.escape("prepare does not take the fit option(s) ['method']")):
        prepare(record, model, method="lm")
