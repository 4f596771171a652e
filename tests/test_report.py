"""Reports (library and ``fdml report``), and the progress callbacks with ``fdml fit --progress``."""

import dataclasses
import io
import json

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import fdml  # noqa: E402
from fdml.cli import main  # noqa: E402
from fdml.progress import HistoryRecorder, PrintProgress, StopAfter, TqdmProgress, chain  # noqa: E402
from fdml.record import Record, add_noise  # noqa: E402
from fdml.report import write_report  # noqa: E402
from fdml.simulate import simulate_maneuver  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def rec():
    r = simulate_maneuver(fdml.make_model("derivatives", "navion"), "3211", duration=10.0, dt=0.02)
    r = add_noise(r, 0.02, np.random.default_rng(3), relative=True)
    return Record(r.t, r.signals, name="nav", meta=r.meta, check_units=False)


@pytest.fixture(scope="module")
def res(rec):
    return fdml.fit(rec, fdml.make_model("derivatives", "navion"), band=(0.2, 8, 0.2))


@pytest.fixture(autouse=True)
def no_show(monkeypatch):
    import matplotlib.pyplot as plt

    def fail(*a, **k):
        raise AssertionError("show() called")

    monkeypatch.setattr(plt, "show", fail)


# --- reports ------------------------------------------------------------------------------------


@pytest.mark.slow
def test_report_from_saved_json(res, tmp_path):
    path = tmp_path / "fit.json"
    res.to_json(path)
    files = write_report(path, dpi=40)
    out = tmp_path / "fit-report"
    assert set(files) == {"report", "spectra", "time_histories", "residual_spectra", "correlation"}
    for key, p in files.items():
        assert p.parent == out and p.exists()
        if p.suffix == ".png":
            assert p.read_bytes()[:8] == PNG
    assert sorted(x.name for x in out.iterdir()) == sorted(p.name for p in files.values())  # no temp files
    md = files["report"].read_text()
    for name in res.names + tuple(res.derived):
        assert f"| {name} |" in md, name
    for p in files.values():
        if p.suffix == ".png":
            assert f"]({p.name})" in md
    for section in ("## Summary", "## Convergence", "## Warnings", "## Figures", "Derived set"):
        assert section in md
    i = res.names.index("Cm_q")
    row = next(line for line in md.splitlines() if line.startswith("| Cm_q |"))
    assert float(row.split("|")[2]) == pytest.approx(res.values[i], rel=5e-6)
    assert f"| {len(res.cost_history) - 1} | {res.cost_history[-1]:.6g} |" in md


def test_report_is_atomic(res, tmp_path, monkeypatch):
    def broken(*a, **k):
        raise RuntimeError("disk full")

    import fdml.plotting

    monkeypatch.setattr(fdml.plotting, "plot_residual_spectra", broken)  # after two figures were saved
    with pytest.raises(RuntimeError, match="disk full"):
        write_report(res, tmp_path / "r", dpi=40)
    assert list((tmp_path / "r").iterdir()) == []


@pytest.mark.slow
def test_report_without_time_records_says_why(res, tmp_path):
    files = write_report(res.without_records(), tmp_path / "r", freq_unit="Hz", dpi=40)
    assert "time_histories" not in files
    assert "time histories not drawn" in files["report"].read_text()


@pytest.mark.slow
def test_cli_report(res, tmp_path, capsys):
    path = tmp_path / "fit.json"
    res.to_json(path)
    code = main(["report", str(path), "-o", str(tmp_path / "out"), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    files = json.loads(out)["files"]
    assert files["report"].endswith("report.md") and (tmp_path / "out" / "correlation.png").exists()
    code = main(["report", str(tmp_path / "missing.json")])
    out, err = capsys.readouterr()
    assert code == 2 and err.startswith("fdml: error:") and "missing.json" in err and err.count("\n") == 1


@pytest.mark.slow
def test_report_gives_the_airspeed_and_its_source_and_each_warning_once(rec, tmp_path, capsys):
    """A fit whose adequacy check warns (a 40 ms alpha delay): report.md lists that warning once."""
    late = rec.with_signals(alpha=np.concatenate([np.full(2, rec["alpha"][0]), rec["alpha"][:-2]]))
    csv, fit_json = tmp_path / "late.csv", tmp_path / "fit.json"
    late.to_csv(csv)
    code = main(["fit", str(csv), "--airspeed", "53.6448", "--band", "0.2:8:0.2", "-o", str(fit_json)])
    out, _ = capsys.readouterr()
    assert code in (0, 1) and "airspeed: 53.64 m/s (given with --airspeed)" in out
    res = fdml.load_result(fit_json)
    assert res.warnings, "the delayed alpha should make the adequacy check warn"
    md = write_report(fit_json, tmp_path / "rep", dpi=40)["report"].read_text()
    assert "**airspeed**: 53.64 m/s (given with --airspeed)" in md
    for w in res.warnings:
        assert md.count(w.message) == 1, w
    # a library fit without provenance: the airspeed is the model's, and it says whose
    md = write_report(dataclasses.replace(res, provenance={}), tmp_path / "rep2", dpi=40)["report"].read_text()
    assert "**airspeed**: 53.64 m/s (given to the model)" in md


def test_report_on_a_diagnosis_report_points_to_the_recommended_fit(tmp_path, capsys):
    from fdml.diagnose import JSON_KEYS

    diag = {k: [] for k in JSON_KEYS} | {"verdict": "time_delay", "recommended": {"model": "dimensional"}}
    diag["settings"] = {"records": ["r017", "r018"]}
    path = tmp_path / "diag.json"
    path.write_text(json.dumps(diag))
    code = main(["report", str(path)])
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1
    assert "diagnosis report" in err and "--recommended-output FIT.json" in err and "r017, r018" in err


# --- progress callbacks ------------------------------------------------------------------------


def test_history_and_print(rec):
    hist = HistoryRecorder()
    buf = io.StringIO()
    res = fdml.fit(
        rec,
        fdml.make_model("derivatives", "navion"),
        band=(0.2, 8, 0.2),
        callback=chain(hist, PrintProgress(buf), None),
    )
    steps = len(res.cost_history) - 1  # one callback per step taken
    assert len(hist.history) == steps >= 2
    np.testing.assert_allclose(hist.costs, res.cost_history[1:])
    assert hist.path("Cm_a")[-1] == pytest.approx(res["Cm_a"])
    assert buf.getvalue().count("\n") == steps and "J = det R" in buf.getvalue()
    fdml.fit(rec, fdml.make_model("derivatives", "navion"), band=(0.2, 8, 0.2), callback=hist)
    assert len(hist.fits) == 2
    with pytest.raises(KeyError, match="not estimated"):
        hist.path("nope")


def test_stop_after_stops_cleanly(rec):
    stop = StopAfter(2)
    res = fdml.fit(rec, fdml.make_model("derivatives", "navion"), band=(0.2, 8, 0.2), callback=stop)
    assert res.stopped and not res.converged and res.iterations == 2 and "callback" in res.message
    assert stop.reason == "iteration limit 2"
    t = iter([0.0, 0.0, 10.0, 20.0])
    stop = StopAfter(seconds=5.0, clock=lambda: next(t))
    res = fdml.fit(rec, fdml.make_model("derivatives", "navion"), band=(0.2, 8, 0.2), callback=stop)
    assert res.stopped and res.iterations == 2 and stop.reason == "time limit 5 s"
    with pytest.raises(ValueError, match="needs"):
        StopAfter()


def test_tqdm_progress(rec):
    pytest.importorskip("tqdm")
    buf = io.StringIO()
    with TqdmProgress(desc="test", file=buf) as bar:
        res = fdml.fit(rec, fdml.make_model("derivatives", "navion"), band=(0.2, 8, 0.2), callback=bar)
        assert bar.bar.n == len(res.cost_history) - 1
    assert "test" in buf.getvalue()


def test_fit_progress_option(rec, tmp_path, capsys, monkeypatch):
    csv = tmp_path / "r.csv"
    rec.to_csv(csv)
    args = [
        "fit",
        str(csv),
        "--aircraft",
        "navion",
        "--model",
        "derivatives",
        "--band",
        "0.2:8:0.2",
        "--json",
        "--progress",
    ]
    code = main(args)
    out, err = capsys.readouterr()
    assert code == 0 and json.loads(out)["converged"]
    # without tqdm: a one-line note, and the fit still runs
    import fdml.progress

    monkeypatch.setattr(fdml.progress, "tqdm_available", lambda: False)
    code = main(args)
    out, err = capsys.readouterr()
    assert code == 0 and json.loads(out)["converged"]
    assert err.count("\n") == 1 and "tqdm" in err and "fdml[progress]" in err
