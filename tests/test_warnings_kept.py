"""Warnings are never lost: a batch, a Monte Carlo study and a diagnosis keep (and count) the
warnings of their fits, which they do not print; their results read back from JSON."""

import csv
import dataclasses
import json
import warnings

import numpy as np
import pytest

import fdml
from fdml.batch import BatchSummary, run_batch
from fdml.diagnose import DiagnosisReport, diagnose
from fdml.errors import ConvergenceWarning
from fdml.montecarlo import MonteCarloResult, monte_carlo
from fdml.record import Record, add_noise
from fdml.simulate import simulate_maneuver

SPEC = {"kind": "steady", "aircraft": "navion"}


@pytest.fixture(scope="module")
def clean():
    return simulate_maneuver(fdml.make_model("steady", "navion"), "3211", duration=8.0, dt=0.02)


@pytest.fixture(scope="module")
def records(tmp_path_factory, clean):
    """A good record and one with alpha and q swapped (the data check's ``channels.swapped``)."""
    folder = tmp_path_factory.mktemp("records")
    good = add_noise(clean, 0.03, np.random.default_rng(0), relative=True)
    s = dict(good.signals)
    s["alpha"], s["q"] = s["q"], s["alpha"]
    swapped = Record(good.t, s, name="swapped", check_units=False)
    good.to_csv(folder / "good.csv")
    swapped.to_csv(folder / "swapped.csv")
    return [folder / "good.csv", folder / "swapped.csv"]


def shown_while(fn):
    """(fn(), warnings that reached the screen), every warning let through by the filter."""
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        out = fn()
    return out, [w for w in shown if issubclass(w.category, fdml.errors.FdmlWarning)]


def test_a_batch_keeps_a_records_data_warning_in_its_row_and_counts_it(tmp_path, records):
    s = run_batch(records, SPEC, tmp_path / "out", engine="serial")
    assert s.n_failed == 0
    with open(s.table_csv, newline="") as fh:
        rows = {r["key"]: r for r in csv.DictReader(fh)}
    assert "DataWarning: [channels.swapped]" in rows["swapped"]["warnings"]
    assert "DataWarning" not in rows["good"]["warnings"]
    assert s.warnings["DataWarning"] == 1  # one record warned, once
    assert "DataWarning" in str(s) and "swapped: DataWarning: [channels.swapped]" in str(s)
    swapped = next(r for r in s.rows if r["key"] == "swapped")
    assert {"category": "DataWarning"}.items() <= swapped["warnings"][0].items()
    # resumed: the reused row brings its warnings back
    again = run_batch(records, SPEC, tmp_path / "out", engine="serial")
    assert again.n_reused == 2 and again.warnings == s.warnings


def test_the_batch_command_shows_the_warnings(tmp_path, records, capsys):
    from fdml.cli import main

    code = main(
        ["batch", *map(str, records), "--aircraft", "navion", "--model", "steady"]
        + ["--output", str(tmp_path / "out"), "--serial"]
    )
    out = capsys.readouterr().out
    assert code == 0 and "swapped: DataWarning: [channels.swapped]" in out


def test_batch_summary_round_trips_through_json(tmp_path, records):
    s = run_batch(records[:1], SPEC, tmp_path / "out", engine="serial")
    back = BatchSummary.from_dict(json.loads(json.dumps(s.to_dict())))
    assert back == s
    with pytest.raises(fdml.FdmlError, match="key 'records' is missing"):
        BatchSummary.from_dict({k: v for k, v in s.to_dict().items() if k != "records"})


def test_a_monte_carlo_study_counts_its_warnings_and_shows_none():
    # one iteration per fit: every run stops before convergence, so every run warns ConvergenceWarning
    n = 3
    res, shown = shown_while(lambda: monte_carlo(SPEC, n=n, duration=6.0, engine="serial", fit_kwargs={"max_iter": 1}))
    assert shown == []  # thousands of trials: counted, not printed
    assert not res.converged.any()
    assert res.warning_counts["ConvergenceWarning"] == n
    assert all(any(w.startswith("ConvergenceWarning: ") for w in res.warnings[i]) for i in range(n))
    res = dataclasses.replace(res, use_converged_only=False)  # statistics over the unconverged runs
    assert f"{n} runs warned (ConvergenceWarning {n}" in res.table()
    back = MonteCarloResult.from_dict(json.loads(res.to_json()))
    assert back.warnings == res.warnings
    # a study saved before warnings were kept reads back with none
    old = {k: v for k, v in res.to_dict().items() if k != "warnings"}
    assert MonteCarloResult.from_dict(old).warnings == {}


def test_a_diagnosis_keeps_the_warnings_of_its_fits(monkeypatch, clean):
    import fdml.diagnose.likelihood as lik

    real = lik.fdml_fit

    def warning_fit(*args, **kw):
        warnings.warn("a warning raised inside the diagnosis's fit", ConvergenceWarning, stacklevel=2)
        return real(*args, **kw)

    monkeypatch.setattr(lik, "fdml_fit", warning_fit)
    model = fdml.make_model("steady", "navion")
    rec = add_noise(clean, 0.03, np.random.default_rng(1), relative=True)
    rep, shown = shown_while(lambda: diagnose(rec, model, library=["time_delay@q"], max_effects=1))
    assert rep.status == "ok"
    assert [str(w.message) for w in shown if w.category is ConvergenceWarning] == []
    assert "ConvergenceWarning: a warning raised inside the diagnosis's fit" in map(str, rep.warnings)
    assert rep.details["base_fit"].warnings  # the fit the report keeps has it too
    assert "a warning raised inside the diagnosis's fit" in rep.summary()
    d = json.loads(rep.to_json())
    assert {"category": "ConvergenceWarning", "message": "a warning raised inside the diagnosis's fit"} in d["warnings"]
    back = DiagnosisReport.from_dict(d)
    assert back.to_dict() == rep.to_dict()
    assert back.verdict == rep.verdict and back.warnings == tuple(rep.warnings)


def test_a_validation_run_counts_the_warnings_of_its_diagnosis(monkeypatch):
    import fdml.diagnose.likelihood as lik
    from fdml.diagnose.validation import Scenario, run_scenario

    real = lik.fdml_fit

    def warning_fit(*args, **kw):
        warnings.warn("a warning raised inside the diagnosis's fit", ConvergenceWarning, stacklevel=2)
        return real(*args, **kw)

    monkeypatch.setattr(lik, "fdml_fit", warning_fit)
    sc = Scenario(None, {}, "-", "3211", 0.03, "white", 11, "none-white")
    row, shown = shown_while(lambda: run_scenario(sc, diagnose_options={"library": ["time_delay@q"], "max_effects": 1}))
    assert row["verdict"] != "error", row["status"]
    assert [w for w in shown if w.category is ConvergenceWarning] == []
    kept = json.loads(row["warnings"])
    assert "ConvergenceWarning: a warning raised inside the diagnosis's fit" in kept
    assert row["n_warnings"] == len(kept)
