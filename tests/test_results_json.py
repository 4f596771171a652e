"""Results round-trip through the one JSON codec on every stopping branch of the fit (issue 14).

A result saved with :meth:`FitResult.to_json` must load back field for field,
whichever branch of :func:`fdml.estimate.fit` ended the iterations; a
hand-edited or damaged result file must be refused with one line that names
the file and the key (exit code 2 from ``fdml report``), never a traceback.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from fdml.cli import main
from fdml.errors import FdmlError
from fdml.estimate import fit
from fdml.findings import Finding
from fdml.jsoncodec import dumps, loads, read_json, to_jsonable
from fdml.models import make_model
from fdml.models.wells_keskar import SteadyModel
from fdml.record import add_noise
from fdml.results import FitResult, load_result
from fdml.simulate import simulate_maneuver

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


# --- fits that end on each branch --------------------------------------------------------------
def _fit(rec, model, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit(rec, model, **kw)


@pytest.fixture(scope="module")
def model():
    return make_model("steady", "navion")


@pytest.fixture(scope="module")
def clean(model):
    """Noise-free 3-2-1-1, 10 s at 50 Hz."""
    return simulate_maneuver(model, "3211", duration=10.0, dt=0.02)


@pytest.fixture(scope="module")
def noisy(clean):
    return add_noise(clean, 0.02, np.random.default_rng(1), relative=True)


def _det_r_branch(clean, model):
    """A fit that ends on "converged: no further decrease of det R".

    The branch needs a step that no longer lowers det R while the step is
    still between tol and 10 tol standard errors: it happens at noise levels
    near the arithmetic's resolution, so a few (level, seed) pairs are tried.
    """
    for level in (1e-7, 1e-6, 3e-7, 3e-8, 1e-8):
        for seed in range(1, 6):
            res = _fit(add_noise(clean, level, np.random.default_rng(seed), relative=True), model)
            if res.message == "converged: no further decrease of det R":
                return res
    pytest.fail("no record tried ends on the 'no further decrease of det R' branch")


class _UphillSteady(SteadyModel):
    """The steady model with the sign of its sensitivities flipped: its derivatives disagree with its cost."""

    def forced_sensitivity(self, *args, **kw):
        resp, dy = super().forced_sensitivity(*args, **kw)
        return resp, -dy


def _stalled_branch(noisy, model):
    """A fit that ends 'stalled': no step lowers det R while det R still resolves the progress.

    That is where the derivatives disagree with the cost (a user's model with wrong sensitivities):
    every step the pass proposes climbs, and even the shortest one tried predicts a decrease far
    above the rounding error of ln det R on a record with 2 % noise, so it is no floating-point floor.
    """
    uphill = _UphillSteady(**{f.name: getattr(model, f.name) for f in dataclasses.fields(model)})
    res = _fit(noisy, uphill, sensitivity="analytic")
    assert res.message == "stalled: no step decreases det R", res.message
    # the file stores the model by its kind: the flipped sign is this test's device, not a model kind
    fields = {f.name: getattr(res.model, f.name) for f in dataclasses.fields(res.model)}
    return dataclasses.replace(res, model=SteadyModel(**fields))


#: branch -> (how to build it, what identifies it: message prefix, converged, stopped)
BRANCHES = {
    "step": ("converged: every step below", True, False),
    "det_r": ("converged: no further decrease of det R", True, False),
    "stalled": ("stalled: no step decreases det R", False, False),
    "floor": ("converged at the floating-point floor", True, False),
    "max_iter": ("maximum number of iterations reached", False, False),
    "callback": ("stopped by the callback after 2 iterations", False, True),
    "paper": ("paper's rule: relative change of det R below 0.01", True, False),
    "gauss_newton": ("converged: every step below", True, False),
}


@pytest.fixture(scope="module")
def step_fit(model, noisy):
    return _fit(noisy, model)


@pytest.fixture(scope="module")
def floor_fit(model, clean):
    return _fit(clean, model)  # issues 14 and 21: the noise-free record


@pytest.fixture(scope="module")
def fits(model, clean, noisy, step_fit, floor_fit):
    """Every stopping branch (the searches for det_r and stalled take several seconds: slow tests only)."""
    return {
        "step": step_fit,
        "det_r": _det_r_branch(clean, model),
        "stalled": _stalled_branch(noisy, model),
        "floor": floor_fit,
        "max_iter": _fit(noisy, model, max_iter=1),
        "callback": _fit(noisy, model, callback=lambda info: info.iteration >= 2),
        "paper": _fit(noisy, model, stop="paper"),
        "gauss_newton": _fit(noisy, model, method="gauss-newton"),
    }


# --- field-by-field comparison -----------------------------------------------------------------
def _same_array(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, what
    assert np.iscomplexobj(a) == np.iscomplexobj(b), what
    # exact: the JSON text holds the shortest repr of each double, which reads back bit for bit;
    # NaN in the same places (assert_array_equal treats NaN as equal to NaN)
    np.testing.assert_array_equal(a, b, err_msg=what)
    for x, y in ((a.real, b.real), (a.imag, b.imag)):  # -0.0 survives too (a NaN's sign need not)
        assert np.array_equal(np.signbit(x) & ~np.isnan(x), np.signbit(y) & ~np.isnan(y)), what


def _same_number(a, b, what):
    assert isinstance(b, float), what
    assert (math.isnan(a) and math.isnan(b)) or a == b, what


def assert_same(a: FitResult, b: FitResult) -> None:
    """Every field of ``a`` equals the one of ``b`` (arrays exactly, NaN where NaN), and so does what is derived."""
    assert a.model == b.model
    assert a.model.parameters.values == b.model.parameters.values
    for f in ("values", "cov", "cov_naive", "R", "stderr", "corr"):  # stderr and corr: derived from cov
        _same_array(getattr(a, f), getattr(b, f), f)
    assert len(a.cost_history) == len(b.cost_history)
    for x, y in zip(a.cost_history, b.cost_history):
        _same_number(x, y, "cost_history")
    _same_number(a.elapsed, b.elapsed, "elapsed")
    for f in ("names", "at_bound", "outputs", "records", "warnings"):
        assert isinstance(getattr(b, f), tuple), f
        assert getattr(a, f) == getattr(b, f), f
    assert isinstance(b.findings, tuple) and len(a.findings) == len(b.findings)
    for x, y in zip(a.findings, b.findings):
        assert (x.code, x.message, x.kind, x.record) == (y.code, y.message, y.kind, y.record)
        for u, v in ((x.value, y.value), (x.expected, y.expected)):
            assert (u is None and v is None) or _same_number(u, v, "finding") is None
    for f in ("iterations", "n_freq"):
        assert type(getattr(b, f)) is int and getattr(a, f) == getattr(b, f), f
    for f in ("converged", "stopped"):
        assert type(getattr(b, f)) is bool and getattr(a, f) == getattr(b, f), f
    for f in ("message", "boundary", "cov_type", "method", "stop", "nuisance"):
        assert getattr(a, f) == getattr(b, f), f
    assert a.fixed.keys() == b.fixed.keys()
    for k in a.fixed:
        _same_number(a.fixed[k], b.fixed[k], f"fixed {k}")
    assert a.derived.keys() == b.derived.keys()
    for k in a.derived:
        for x, y in zip(a.derived[k], b.derived[k]):
            _same_number(x, y, f"derived {k}")
    assert len(a.spectra) == len(b.spectra)
    for sa, sb in zip(a.spectra, b.spectra):
        for f in dataclasses.fields(sa):
            x, y = getattr(sa, f.name), getattr(sb, f.name)
            if isinstance(x, np.ndarray):
                _same_array(x, y, f"spectra {f.name}")
            elif isinstance(x, float):
                _same_number(x, y, f"spectra {f.name}")
            elif isinstance(x, tuple) and x and isinstance(x[0], float):  # the band
                assert len(x) == len(y) and all(_same_number(u, v, "band") is None for u, v in zip(x, y))
            elif f.name == "record":
                _same_record(x, y)
            else:
                assert to_jsonable(x) == to_jsonable(y), f"spectra {f.name}"  # frozen: lists kept as tuples
    assert (a.band is None) == (b.band is None)
    assert len(a.time_records) == len(b.time_records)
    assert a.adequacy == b.adequacy  # fdml.adequacy: floats and strings only, so exact
    assert to_jsonable(a.provenance) == to_jsonable(b.provenance)  # plain data (fdml.conditions), frozen
    assert a.slots == b.slots  # issue 10: typed roles and records of the estimates
    assert a.options == b.options  # issue 10: every option of the fit
    # nothing was forgotten: every field of the dataclass is covered above
    assert {f.name for f in dataclasses.fields(FitResult)} == {
        "model",
        "names",
        "values",
        "cov",
        "cov_naive",
        "options",
        "R",
        "cost_history",
        "iterations",
        "converged",
        "message",
        "at_bound",
        "spectra",
        "stopped",
        "warnings",
        "elapsed",
        "findings",
        "adequacy",
        "provenance",
        "slots",
    }


def _same_record(ra, rb) -> None:
    assert (ra is None) == (rb is None)
    if ra is None:
        return
    assert ra.name == rb.name
    _same_array(ra.t, rb.t, "record t")
    assert ra.signals.keys() == rb.signals.keys()
    for k in ra.signals:
        _same_array(ra.signals[k], rb.signals[k], f"record signal {k}")
    assert to_jsonable(ra.meta) == to_jsonable(rb.meta)  # frozen: lists kept as tuples


FINDINGS = (
    Finding("units.elevator", "elevator looks like degrees", kind="data", record="sim", value=57.3, expected=1.0),
    Finding("correlation.high", "Cm_a and Cm_q correlated", kind="estimation", value=math.nan, expected=None),
)


# --- every stopping branch ---------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("branch", list(BRANCHES))
def test_every_branch_round_trips(fits, branch, tmp_path):
    res = fits[branch]
    prefix, converged, stopped = BRANCHES[branch]
    assert res.message.startswith(prefix)
    assert res.converged is converged and res.stopped is stopped  # plain bools, not numpy.bool_
    if branch == "gauss_newton":
        assert res.method == "gauss-newton"
    if branch == "paper":
        assert res.stop == "paper"
    res = dataclasses.replace(res, findings=FINDINGS)  # findings of both kinds, NaN and None values
    path = res.to_json(tmp_path / f"{branch}.json")
    back = load_result(path)
    assert_same(res, back)
    assert_same(back, FitResult.from_dict(json.loads(res.to_json())))  # text and file agree


@pytest.mark.slow
@pytest.mark.parametrize("branch", ["det_r", "stalled", "floor", "callback"])
def test_report_works_on_reloaded_result(fits, branch, tmp_path, capsys):
    path = fits[branch].to_json(tmp_path / "r.json")
    assert main(["report", str(path), "-o", str(tmp_path / "rep")]) == 0
    assert (tmp_path / "rep" / "report.md").stat().st_size > 0
    assert "error" not in capsys.readouterr().err


def test_cli_reproduction_writes_loadable_result(tmp_path, capsys):
    """Issue 14: noise-free record, steady model: exit 0 or 1, never 'internal error'."""
    csv, out = tmp_path / "c.csv", tmp_path / "c.json"
    assert main(["simulate", "--aircraft", "navion", "--model", "steady", "--noise", "0", "-o", str(csv)]) == 0
    rc = main(["fit", str(csv), "--aircraft", "navion", "--model", "steady", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc in (0, 1), err
    assert "internal error" not in err
    res = load_result(out)
    assert res.records and res.time_records[0].t.size == 501  # 10 s at 0.02 s
    assert (rc == 0) == res.converged


def test_batch_keeps_a_noise_free_record(clean, tmp_path):
    """Issue 14: batch marked noise-free records failed (the result file could not be written)."""
    from fdml.batch import run_batch

    clean.to_csv(tmp_path / "clean.csv")
    summary = run_batch(
        [str(tmp_path / "clean.csv")], {"kind": "steady", "aircraft": "navion"}, tmp_path / "out", engine="serial"
    )
    (row,) = summary.rows
    assert row["status"] == "ok", row.get("error")
    res = load_result(tmp_path / "out" / row["result_file"])
    assert res.converged is row["converged"]


# --- the codec ---------------------------------------------------------------------------------
def test_to_jsonable_types():
    class WithDict:
        def to_dict(self):
            return {"x": np.float32(1.5)}

    d = to_jsonable(
        {
            "b": np.bool_(True),
            "i": np.int64(3),
            "f": np.float64(-0.0),
            "nan": np.nan,
            "inf": -np.inf,
            "a": np.array([[1.0, np.inf]]),
            "c": np.array([1 + 2j]),
            "t": (1, 2),
            "p": Path("a/b"),
            1: "int key",
            "o": WithDict(),
            "s": {3, 1, 2},
            "u": np.uint8(7),
            "bs": np.array([True, False]),
        }
    )
    assert d == {
        "b": True,
        "i": 3,
        "f": -0.0,
        "nan": "nan",
        "inf": "-inf",
        "a": [[1.0, "inf"]],
        "c": {"re": [1.0], "im": [2.0]},
        "t": [1, 2],
        "p": str(Path("a/b")),
        "1": "int key",
        "o": {"x": 1.5},
        "s": [1, 2, 3],
        "u": 7,
        "bs": [True, False],
    }
    assert type(d["b"]) is bool and type(d["i"]) is int and type(d["u"]) is int
    json.dumps(d, allow_nan=False)  # strictly valid JSON
    with pytest.raises(TypeError, match="object"):
        to_jsonable({"f": object()}, default=None)
    assert to_jsonable([np.nan, 1.0], nonfinite="null") == [None, 1.0]


def test_dumps_compact_and_loads_bom():
    assert dumps({"a": [1, np.bool_(False)]}, compact=True) == '{"a":[1,false]}'
    assert loads("\ufeff" + dumps({"a": 1})) == {"a": 1}
    assert loads(b"\xef\xbb\xbf[1]") == [1]


#: A result of version 1, written by fdml before issue 22 (commit 96a172a): a steady Navion model
#: fitted to two noisy 4 s 3-2-1-1 records (20 Hz) on the band 0.5:10:0.5 with trim "mean" (1 s) and a
#: bound on Cm_de, written with ``to_json(indent=None)``.  It kept stderr, corr, derived, fixed,
#: n_freq, records and nuisance, which version 2 derives, and the records apart from the spectra.
V1_FILE = Path(__file__).parent / "data" / "fit_result_v1.json"


def test_a_version_1_file_loads_and_derives_what_it_kept():
    d = json.loads(V1_FILE.read_text())
    assert d["version"] == 1
    res = load_result(V1_FILE)
    # what version 1 kept and version 2 derives is what it kept (JSON holds doubles exactly)
    np.testing.assert_array_equal(res.stderr, [float(x) for x in d["stderr"]])
    np.testing.assert_array_equal(res.corr, np.array([[float(x) for x in row] for row in d["corr"]]))
    assert {k: list(v) for k, v in res.derived.items()} == d["derived"]
    assert dict(res.fixed) == d["fixed"] and res.n_freq == d["n_freq"] and list(res.records) == d["records"]
    assert list(res.band) == d["band"] and list(res.outputs) == d["outputs"]
    assert (res.boundary, res.cov_type, res.method, res.stop) == tuple(
        d[k] for k in ("boundary", "cov_type", "method", "stop")
    )
    assert to_jsonable(res.nuisance) == d["nuisance"]
    # the records went into the spectra, the band and trim with them
    for s, r in zip(res.spectra, d["time_records"]):
        assert s.record.name == r["name"] and s.trim_mode == r["trim_mode"] == "mean"
        np.testing.assert_array_equal(s.record["q"], r["signals"]["q"])
        assert s.trim_samples == 21  # 1 s at 0.05 s, and the first sample
    # and it is written as version 2 and read back the same
    back = FitResult.from_dict(json.loads(res.to_json()))
    assert json.loads(res.to_json())["version"] == 2
    assert_same(res, back)
    np.testing.assert_array_equal(res.resid, back.resid)


@pytest.mark.parametrize("mode, lead", [("none", 0), ("first", 1), ("mean", 21)])
def test_a_version_1_file_counts_the_trim_samples_as_spectra_does(tmp_path, mode, lead):
    # version 1 kept the trim mode, not its sample count: the reader counts them as fdml.spectra does
    # (trim "none": no leading samples, though the file keeps a 1 s window beside it)
    d = json.loads(V1_FILE.read_text())
    d["nuisance"]["trim"] = [mode] * len(d["nuisance"]["trim"])
    for r in d["time_records"]:
        r["trim_mode"] = mode
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(d))
    res = load_result(path)
    assert [s.trim_samples for s in res.spectra] == [lead] * len(res.spectra)
    assert all(s.trim_mode == mode for s in res.spectra)


def _theta_fit():
    """alpha, q, theta and q_dot fitted (issue 22 item 3): theta's own boundary values, no bias_theta."""
    from fdml.maneuvers import three_two_one_one, time_vector
    from fdml.simulate import simulate

    truth = make_model("dimensional", "sundowner", outputs=("theta", "qdot"))
    t = time_vector(6.0, 0.05)
    rec = simulate(truth, t, {"de": three_two_one_one(t, start=0.5, unit=0.6)})
    rec = add_noise(rec, 0.02, np.random.default_rng(7), relative=True)
    model = make_model("dimensional", "sundowner")
    return _fit(rec, model, band="0.5:8:0.5", outputs="alpha,q,theta,qdot", adequacy=False)


def _assert_theta_rows(res: FitResult) -> None:
    rows = ("alpha", "q", "az", "theta", "qdot")
    assert res.outputs == ("alpha", "q", "theta", "qdot") and res.model.outputs == rows
    assert {"x0_theta", "xT_theta", "bias_qdot"} <= set(res.names) and "bias_theta" not in res.names
    for s in res.spectra:
        assert s.outputs == rows and s.z.shape[1] == 5 and s.x0.shape == s.xT.shape == (3,)  # alpha, q, theta
    assert res.resid.shape[1] == 4


def test_a_fit_of_theta_and_qdot_round_trips(tmp_path):
    res = _theta_fit()
    _assert_theta_rows(res)
    path = tmp_path / "theta.json"
    res.to_json(path)
    d = json.loads(path.read_text())
    assert d["spectra"][0]["outputs"] == ["alpha", "q", "az", "theta", "qdot"]
    back = load_result(path)
    _assert_theta_rows(back)
    assert_same(res, back)
    # the nuisance terms by the model's rows' names: theta's boundary values come back in their place
    for f in ("biases", "x0", "xT"):
        _same_array(getattr(res.nuisance_values(), f), getattr(back.nuisance_values(), f), f)
    assert back.nuisance_values().x0[2] == back["x0_theta"]
    _same_array(res.fitted_spectra(), back.fitted_spectra(), "fitted spectra")
    _same_array(res.resid, back.resid, "residuals")


#: A result of version 1 with theta and q_dot among its outputs, written by fdml after issue 22 item 3
#: (main at e742370, before version 2): a dimensional Sundowner model fitted to alpha, q, theta and q_dot of
#: one noisy 6 s 3-2-1-1 (20 Hz) on the band 0.5:8:0.5, written with ``to_json(indent=None)``.  Version 1
#: kept the spectra's outputs only in the model; its x0 and xT hold alpha, q and theta.
V1_THETA_FILE = Path(__file__).parent / "data" / "fit_result_v1_theta.json"


def test_a_version_1_file_with_theta_and_qdot_loads():
    d = json.loads(V1_THETA_FILE.read_text())
    assert d["version"] == 1 and d["outputs"] == ["alpha", "q", "theta", "qdot"]
    res = load_result(V1_THETA_FILE)
    _assert_theta_rows(res)
    np.testing.assert_array_equal(res.stderr, [float(x) for x in d["stderr"]])
    assert list(res.names) == d["names"] and to_jsonable(res.nuisance) == d["nuisance"]
    # the residuals rebuilt from the loaded estimate, nuisance terms and spectra give the R the fit saved
    # (Eq. 24): the same sums in another order, so equal to rounding (a few 1e-16 per term, relative)
    v = res.resid
    R = np.array(d["R"]["re"]) + 1j * np.array(d["R"]["im"])
    np.testing.assert_allclose(v.T @ v.conj() / v.shape[0], R, rtol=1e-10, atol=1e-10 * np.abs(R).max())
    back = FitResult.from_dict(json.loads(res.to_json()))
    assert_same(res, back)


def test_old_result_files_still_read(tmp_path):
    """Files written before the codec held NaN/Infinity tokens and lacked later keys; they still load."""
    d = json.loads(V1_FILE.read_text())
    d["stderr"] = [math.nan if x == "nan" else x for x in d["stderr"]]
    d["cost_history"] = [math.inf] + d["cost_history"][1:]
    d["derived"] = {k: [v, math.inf] for k, (v, _) in d["derived"].items()}
    d["cov"][0][0] = math.inf
    for key in ("findings", "nuisance", "time_records", "method", "stop", "stopped", "elapsed", "options", "slots"):
        del d[key]  # keys added by later versions have defaults
    path = tmp_path / "old.json"
    path.write_text(json.dumps(d))  # json's own NaN / Infinity tokens
    back = load_result(path)
    assert back.cost_history[0] == math.inf and back.stderr[0] == math.inf
    assert back.findings == () and back.time_records == () and back.method == "lm"
    assert back.outputs == tuple(d["outputs"]) and back.spectra[0].trim_mode == "first"  # the defaults of then
    assert back.slots[0].name == d["names"][0]  # rebuilt from the names


@pytest.mark.parametrize(
    "keys, value, expected",
    [
        (("time_records", 0, "signals", "alpha"), [0.0, 1.0], "key 'time_records[0].signals.alpha' must be a list"),
        (("spectra", 0, "z"), {"re": [[0.0]], "im": [[0.0]]}, "key 'spectra[0].z' must be an array of shape 20 x"),
        (("band",), [0.1, 10.0], "key 'band' must be a list of 3 numbers, got 2"),
        (("version",), "1", "key 'version' is the string '1' where the integer 1 is expected"),
    ],
)
def test_a_damaged_version_1_file_names_its_own_keys(tmp_path, capsys, keys, value, expected):
    d = json.loads(V1_FILE.read_text())
    _set(d, keys, value)
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(d))
    assert main(["report", str(path), "-o", str(tmp_path / "rep")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert f"result file {path}:" in line and expected in line


# --- hand-edited and damaged files -------------------------------------------------------------
def _set(d, path, value):
    *head, last = path
    for k in head:
        d = d[k]
    if value is _DELETE:
        del d[last]
    else:
        d[last] = value


_DELETE = object()

#: (what is changed, new value, text the one-line message must hold)
EDITS = [
    (("values",), _DELETE, "key 'values' is missing"),
    (("iterations",), "5", "key 'iterations' must be an integer, got str"),
    (("iterations",), 5.5, "key 'iterations' must be an integer, got float"),
    (("converged",), "yes", "key 'converged' must be true or false, got str"),
    (("values",), "1.0", "key 'values' must be a list of numbers, got str"),
    (("values",), [1.0, "abc"], "key 'values' must be a list of numbers, holds the string 'abc'"),
    (("values",), [1.0, 2.0], "key 'values' must be a list of 12 numbers, got 2"),
    (("cov",), [[1.0, 2.0], [3.0, 4.0]], "key 'cov' must be an array of shape 12 x 12, got shape 2 x 2"),
    (("cov_naive",), [[1.0], [1.0, 2.0]], "key 'cov_naive' must be a rectangular array"),
    (("R", "im"), _DELETE, "key 'R' must be an object with keys 're' and 'im'; 'im' is missing"),
    (("R",), [[1.0]], "key 'R' must be an object with keys 're' and 'im', got list"),
    (("names",), "Cz_a", "key 'names' must be a list of strings, got str"),
    (("options", "outputs"), ["alpha", "beta"], "key 'options' holds no valid fit options: outputs: unknown output"),
    (("spectra", 0, "band"), [0.1, 10.0], "key 'spectra[0].band' must be a list of 3 numbers, got 2"),
    (("cost_history",), [], "key 'cost_history' must hold at least 1 number"),
    (("message",), None, "key 'message' must be a string, got null"),
    (("options", "tol"), "0.001", "key 'options' holds no valid fit options: tol must be a finite number"),
    (("options",), [], "key 'options' must be an object, got list"),
    (("slots", 0, "role"), "pilot", "key 'slots[0].role' must be one of"),
    (("version",), "2", "key 'version' is the string '2' where the integer 2 is expected"),
    (("version",), 3, "key 'version' is 3: this fdml reads versions 1, 2"),
    (("format",), _DELETE, "key 'format' is missing: not an fdml result file"),
    (("format",), "fdml.MonteCarloResult", "key 'format' is 'fdml.MonteCarloResult'"),
    (("model", "kind"), 3, "key 'model.kind' must be a string, got int"),
    (("model", "kind"), "jet", "key 'model' does not describe a model"),
    (("model", "parameters", 0, "value"), "x", "key 'model.parameters[0].value' must be a number"),
    (("model", "parameters", 0, "free"), "yes", "key 'model.parameters[0].free' must be true or false"),
    (
        ("spectra", 0, "z"),
        {"re": [[0.0]], "im": [[0.0]]},
        "key 'spectra[0].z' must be an array of shape 100 x any, got shape 1 x 1",
    ),
    (("spectra", 0, "n"), "501", "key 'spectra[0].n' must be an integer, got str"),
    # the spectra's outputs (fdml.channels.row_space) say what the columns of z and the entries of x0, xT are
    (("spectra", 0, "outputs"), ["alpha", "q", "az", "theta"], "key 'spectra[0].z' has 3 columns for the 4 outputs"),
    (("spectra", 0, "outputs"), ["q", "alpha", "az"], "outputs in the order alpha, q, az expected"),
    (("spectra", 0, "outputs"), ["alpha", "pitch"], "key 'spectra[0].outputs' holds 'pitch'; allowed: alpha, q, az"),
    (("spectra", 0, "x0"), [0.0, 0.0, 0.0], "key 'spectra[0].x0' has 3 values for the 2 boundary channels"),
    (("options", "outputs"), ["alpha", "theta"], "key 'options.outputs' is ['alpha', 'theta'], but the model predicts"),
    (
        ("model", "options", "outputs"),
        ["alpha", "q", "az", "theta"],
        "key 'spectra[0].outputs' is ['alpha', 'q', 'az'], but the model predicts alpha, q, az, theta",
    ),
    (("spectra", 0, "trim_mode"), "median", "key 'spectra[0].trim_mode' must be one of 'first', 'mean', 'none'"),
    (("spectra", 0), 7, "key 'spectra[0]' must be an object, got int"),
    (
        ("spectra", 0, "record", "signals", "alpha"),
        [0.0, 1.0],
        "key 'spectra[0].record.signals.alpha' must be a list of 501 numbers, got 2",
    ),
    (("spectra", 0, "record", "t"), "0:10", "key 'spectra[0].record.t' must be a list of numbers, got str"),
    (
        ("findings",),
        [{"code": "x", "message": "m", "kind": "bogus"}],
        "key 'findings[0].kind' must be one of 'data', 'estimation', got 'bogus'",
    ),
    (("findings",), [{"message": "m"}], "key 'findings[0].code' is missing"),
    (("provenance",), [], "key 'provenance' must be an object, got list"),
]


@pytest.fixture(scope="module")
def saved(floor_fit):
    """The JSON dict of a real result (the noise-free fit, converged at the floating-point floor)."""
    return floor_fit.to_dict()


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("fdml: error: ")
    return lines[0]


@pytest.mark.parametrize("keys, value, expected", EDITS, ids=[".".join(map(str, e[0])) for e in EDITS])
def test_hand_edited_result_is_refused(saved, tmp_path, capsys, keys, value, expected):
    d = json.loads(json.dumps(saved))
    _set(d, keys, value)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(d))
    rc = main(["report", str(path), "-o", str(tmp_path / "rep")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2
    assert f"result file {path}:" in line
    assert expected in line
    assert not (tmp_path / "rep").exists()  # refused before any output


@pytest.mark.parametrize(
    "content, expected",
    [
        (None, "does not exist"),
        ("folder", "is a folder"),
        (b'{"format": "fdml.FitResult", "message": "d\xe9j\xe0 vu"}', "is not UTF-8 text (byte 0xe9 at offset 42"),
        (
            b'{"format": "fdml.FitResult",\n "version": 1,,}',
            "is not valid JSON: Expecting property name enclosed in double quotes at line 2, column 15",
        ),
        (b"", "is empty"),
        (b"[1, 2]", "expected a JSON object, got list"),
        (b'"fdml"', "expected a JSON object, got str"),
        (b"[" * 100_000, "nested too deeply"),
    ],
)
def test_unreadable_result_file(tmp_path, capsys, content, expected):
    path = tmp_path / "bad.json"
    if content == "folder":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content)
    rc = main(["report", str(path), "-o", str(tmp_path / "rep")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2
    assert str(path) in line and expected in line


def test_bom_is_accepted(step_fit, tmp_path):
    path = tmp_path / "bom.json"
    path.write_bytes(b"\xef\xbb\xbf" + step_fit.to_json().encode())
    assert_same(step_fit, load_result(path))
    with pytest.raises(FdmlError, match="no.json does not exist"):
        read_json(tmp_path / "no.json", what="aircraft file")


def test_monte_carlo_file_is_checked(tmp_path):
    from fdml.montecarlo import MonteCarloResult, load_monte_carlo

    mc = MonteCarloResult(
        names=("a", "b"),
        truth=np.array([1.0, np.nan]),
        estimates=np.array([[1.0, 2.0], [np.nan, 3.0]]),
        stderr=np.ones((2, 2)),
        converged=np.array([True, False]),
        iterations=np.array([3, 200]),
        fit_seconds=np.array([0.1, 0.2]),
        errors={1: "failed"},
        settings={"seed": 0},
        wall_time=1.0,
    )
    path = tmp_path / "mc.json"
    mc.to_json(path)
    back = load_monte_carlo(path)
    np.testing.assert_array_equal(back.estimates, mc.estimates)
    np.testing.assert_array_equal(back.truth, mc.truth)
    assert back.converged.tolist() == [True, False] and back.errors == {1: "failed"}
    d = json.loads(path.read_text())
    d["version"] = "1"
    path.write_text(json.dumps(d))
    with pytest.raises(FdmlError, match=r"Monte Carlo file .*mc.json: key 'version' is the string '1'"):
        load_monte_carlo(path)
    d["version"] = 1
    d["converged"] = [True]
    path.write_text(json.dumps(d))
    with pytest.raises(FdmlError, match=r"mc.json: key 'converged' must have 2 entries, got 1"):
        load_monte_carlo(path)


# --- properties --------------------------------------------------------------------------------
_floats = st.floats(allow_nan=True, allow_infinity=True)  # includes 0.0, -0.0, subnormals and +-1.8e308
_special = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, -0.0, 1e-300])
_any_float = st.one_of(_floats, _special)


@st.composite
def perturbed(draw, base: FitResult):
    """``base`` with some of its numbers, flags and texts replaced by arbitrary ones."""

    def arr(a):
        a = np.array(a, copy=True)
        for _ in range(draw(st.integers(0, 3))):
            idx = tuple(draw(st.integers(0, s - 1)) for s in a.shape)
            a[idx] = complex(draw(_any_float), draw(_any_float)) if np.iscomplexobj(a) else draw(_any_float)
        return a

    def record(r):  # a record's samples are finite (Record refuses others): finite extremes, -0.0, subnormals
        finite = st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.sampled_from([1e308, 5e-324, -0.0]))
        signals = {k: v.copy() for k, v in r.signals.items()}
        for _ in range(draw(st.integers(0, 3))):
            signals[draw(st.sampled_from(sorted(signals)))][draw(st.integers(0, r.n - 1))] = draw(finite)
        return dataclasses.replace(r, signals=signals, check_units=False)

    spectra = tuple(
        dataclasses.replace(
            s,
            omega=arr(s.omega),
            z=arr(s.z),
            T=draw(_any_float),
            band=draw(st.one_of(st.none(), st.tuples(_any_float, _any_float, _any_float))),
            record=None if s.record is None else record(s.record),
        )
        for s in base.spectra
    )
    return dataclasses.replace(
        base,
        values=arr(base.values),
        cov=arr(base.cov),  # stderr, corr and derived follow from it
        cov_naive=arr(base.cov_naive),
        R=arr(base.R),
        cost_history=tuple(draw(st.lists(_any_float, min_size=1, max_size=4))),
        iterations=draw(st.integers(0, 2**62)),
        converged=draw(st.booleans()),
        stopped=draw(st.booleans()),
        message=draw(st.text(max_size=20)),
        warnings=tuple(draw(st.lists(st.text(max_size=10), max_size=2))),
        elapsed=draw(_any_float),
        spectra=spectra,
        findings=tuple(
            Finding(
                draw(st.text(min_size=1, max_size=8)),
                draw(st.text(max_size=8)),
                kind=draw(st.sampled_from(["data", "estimation"])),
                record=draw(st.one_of(st.none(), st.text(max_size=5))),
                value=draw(st.one_of(st.none(), _any_float)),
                expected=draw(st.one_of(st.none(), _any_float)),
            )
            for _ in range(draw(st.integers(0, 2)))
        ),
    )


@pytest.fixture(scope="module")
def small_fit(model, noisy):
    """A real result on a short record: 3 s, 0.05 s steps, a coarse band (fast to write and read)."""
    return _fit(noisy.window(0.0, 3.0), model, band=(0.5, 10.0, 0.5))


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    return tmp_path_factory.mktemp("roundtrip")


# ~100 examples in about 5 s here (limit for the suite: 15 s)
@pytest.mark.slow
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_property_a_result_always_round_trips(small_fit, scratch, data):
    res = data.draw(perturbed(small_fit))
    path = res.to_json(scratch / "r.json")
    assert_same(res, load_result(path))


_json = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), _any_float, st.text(max_size=8)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12,
)


def _key_paths(d, prefix=()):
    """Every key path into the nested dicts and lists of ``d``."""
    out = []
    items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) else ()
    for k, v in items:
        if isinstance(d, list) and k > 1:
            break  # two list entries are enough (the arrays are long)
        out.append(prefix + (k,))
        out.extend(_key_paths(v, prefix + (k,)))
    return out


def _load_or_fdml_error(path):
    try:
        return load_result(path)
    except FdmlError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        return None


# ~150 examples in about 5 s here
@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_property_arbitrary_json_gives_result_or_fdml_error(small_fit, scratch, data):
    doc = small_fit.to_dict()
    paths = _key_paths(doc)
    for _ in range(data.draw(st.integers(1, 3))):
        keys = data.draw(st.sampled_from(paths))
        try:
            _set(doc, keys, data.draw(st.one_of(st.just(_DELETE), _json)))
        except (KeyError, IndexError, TypeError):
            pass  # an earlier edit removed or replaced the parent
    if data.draw(st.booleans()):
        doc = data.draw(_json)  # or no result at all
    path = scratch / "fuzz.json"
    path.write_text(json.dumps(doc))  # NaN / Infinity tokens included
    res = _load_or_fdml_error(path)
    assert res is None or isinstance(res, FitResult)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(raw=st.one_of(st.binary(max_size=200), st.text(max_size=100).map(lambda s: s.encode("utf-8", "replace"))))
def test_property_arbitrary_bytes_give_result_or_fdml_error(scratch, raw):
    path = scratch / "bytes.json"
    path.write_bytes(raw)
    assert _load_or_fdml_error(path) is None  # a valid result needs far more than 200 bytes
