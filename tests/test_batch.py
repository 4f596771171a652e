"""Batch fitting: isolation of failures, resume, atomic results, engines that agree, the command."""

import csv
import functools
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import fdml
import fdml.estimate
from fdml.batch import ModelSpec, collect_sources, execute, run_batch
from fdml.cli import main
from fdml.record import add_noise
from fdml.simulate import simulate_maneuver

SPEC = {"kind": "steady", "aircraft": "navion"}
TRUTH = fdml.make_model("steady", "navion").parameters.values


def make_records(folder: Path, n: int, *, duration: float = 6.0, seed: int = 0) -> list[Path]:
    """n noisy 3-2-1-1 records of the steady Navion (3 % of RMS), one CSV each."""
    folder.mkdir(parents=True, exist_ok=True)
    clean = simulate_maneuver(fdml.make_model("steady", "navion"), "3211", duration=duration, dt=0.02)
    paths = []
    for i in range(n):
        p = folder / f"rec{i:02d}.csv"
        add_noise(clean, 0.03, np.random.default_rng(seed + i), relative=True).to_csv(p)
        paths.append(p)
    return paths


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    return make_records(tmp_path_factory.mktemp("records"), 5)


def read_table(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


class FitCounter:
    """Wraps fdml.estimate.fit (serial engine) and counts the fits."""

    def __init__(self, monkeypatch):
        self.calls = []
        real = fdml.estimate.fit

        @functools.wraps(real)
        def counting(rec, model, **kw):
            self.calls.append(rec.name)
            return real(rec, model, **kw)

        monkeypatch.setattr(fdml.estimate, "fit", counting)


def test_failing_records_are_isolated_with_their_error(tmp_path, records):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,de,alpha,q,az\n0,0,0,0,0\n0.02,0,0,0\n")  # truncated line
    deg = tmp_path / "degrees.csv"
    r = fdml.read_csv(records[0])
    fdml.Record(r.t, {**r.signals, "alpha": np.degrees(r["alpha"]) + 3.0}, check_units=False).to_csv(deg)
    missing = tmp_path / "missing.csv"
    out = tmp_path / "out"
    s = run_batch([records[0], bad, records[1], deg, missing, records[2]], SPEC, out, engine="serial")
    assert s.n_total == 6 and s.n_failed == 3 and s.n_fitted == 3
    by_key = {row["key"]: row for row in s.rows}
    assert [row["key"] for row in s.rows] == ["rec00", "bad", "rec01", "degrees", "missing", "rec02"]
    assert by_key["bad"]["error"].startswith("RecordError:") and "line 3" in by_key["bad"]["error"]
    assert "degrees" in by_key["degrees"]["error"] or "deg" in by_key["degrees"]["error"]
    assert by_key["missing"]["error"].startswith("RecordError:") and "does not exist" in by_key["missing"]["error"]
    for key in ("rec00", "rec01", "rec02"):
        row = by_key[key]
        assert row["status"] == "ok" and row["error"] == "" and row["converged"]
        assert abs(row["params"]["Cm_de"] - TRUTH["Cm_de"]) < 4 * row["stderr"]["Cm_de"]
        assert fdml.load_result(out / row["result_file"]).records == (key,)
    # the table: one row each, the errors in it, one line per error
    table = read_table(out / "table.csv")
    assert [t["key"] for t in table] == [row["key"] for row in s.rows]
    assert table[1]["status"] == "error" and table[1]["error"] == by_key["bad"]["error"]
    assert "\n" not in by_key["bad"]["error"]
    assert table[0]["Cm_de"] != "" and table[1]["Cm_de"] == ""
    doc = json.loads((out / "table.json").read_text())
    assert doc["format"] == "fdml.BatchTable" and len(doc["rows"]) == 6
    # each failure has its error file, never a result file
    assert (out / "results" / "bad.error.json").exists() and not (out / "results" / "bad.json").exists()
    assert json.loads((out / "results" / "bad.error.json").read_text())["error"] == by_key["bad"]["error"]


def test_resume_skips_finished_work_and_refits_when_inputs_change(tmp_path, records, monkeypatch):
    counter = FitCounter(monkeypatch)
    out = tmp_path / "out"
    folder = records[0].parent
    s1 = run_batch(folder, SPEC, out, engine="serial", fit_kwargs={"band": "0.2:8:0.1"})
    assert len(counter.calls) == 5 and s1.n_fitted == 5
    mtimes = {p.name: p.stat().st_mtime_ns for p in (out / "results").iterdir()}
    s2 = run_batch(folder, SPEC, out, engine="serial", fit_kwargs={"band": "0.2:8:0.1"})
    assert len(counter.calls) == 5, "a finished record was refitted"
    assert s2.n_reused == 5 and s2.n_fitted == 0 and all(r["reused"] for r in s2.rows)
    assert {p.name: p.stat().st_mtime_ns for p in (out / "results").iterdir()} == mtimes
    assert [r["params"] for r in s2.rows] == [r["params"] for r in s1.rows]
    # other fit options: everything is refitted
    s3 = run_batch(folder, SPEC, out, engine="serial", fit_kwargs={"band": "0.2:6:0.1"})
    assert len(counter.calls) == 10 and s3.n_fitted == 5 and s3.rows[0]["n_freq"] != s1.rows[0]["n_freq"]
    # another model spec: refitted too
    run_batch(folder, {**SPEC, "fix": {"Cz_de": -0.51}}, out, engine="serial", fit_kwargs={"band": "0.2:6:0.1"})
    assert len(counter.calls) == 15
    # no resume: refitted although nothing changed
    run_batch(
        folder, {**SPEC, "fix": {"Cz_de": -0.51}}, out, engine="serial", resume=False, fit_kwargs={"band": "0.2:6:0.1"}
    )
    assert len(counter.calls) == 20


def test_resume_refits_a_record_whose_file_changed(tmp_path, monkeypatch):
    paths = make_records(tmp_path / "recs", 3, seed=50)
    counter = FitCounter(monkeypatch)
    out = tmp_path / "out"
    run_batch(paths, SPEC, out, engine="serial")
    r = fdml.read_csv(paths[1])
    add_noise(r, 0.01, np.random.default_rng(99), relative=True).to_csv(paths[1])
    s = run_batch(paths, SPEC, out, engine="serial")
    assert counter.calls == ["rec00", "rec01", "rec02", "rec01"]
    assert [r["reused"] for r in s.rows] == [True, False, True]


def test_no_partial_file_when_the_write_fails(tmp_path, records, monkeypatch):
    real_replace = os.replace

    def failing_replace(src, dst):
        if Path(dst).name == "rec01.json":
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", failing_replace)
    out = tmp_path / "out"
    s = run_batch(records[:3], SPEC, out, engine="serial")
    names = sorted(p.name for p in (out / "results").iterdir())
    assert names == ["rec00.json", "rec01.error.json", "rec02.json"]  # no temporary left, no half file
    assert s.rows[1]["status"] == "error" and "No space left" in s.rows[1]["error"]
    for name in ("rec00.json", "rec02.json"):
        fdml.load_result(out / "results" / name)


CRASH = textwrap.dedent("""
    import os, sys
    from pathlib import Path
    from fdml.batch import run_batch
    real_replace = os.replace
    def crash(src, dst):
        if Path(dst).name == "rec02.json":
            os._exit(17)          # the process dies between writing and renaming
        return real_replace(src, dst)
    os.replace = crash
    run_batch(sys.argv[1], {"kind": "steady", "aircraft": "navion"}, sys.argv[2], engine="serial")
""")


def test_a_crash_mid_write_leaves_no_partial_result_and_resume_finishes(tmp_path, records, monkeypatch):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-c", CRASH, str(records[0].parent), str(out)], capture_output=True)
    assert proc.returncode == 17
    results = out / "results"
    finished = sorted(p.name for p in results.glob("*.json"))
    assert finished == ["rec00.json", "rec01.json"]
    assert len(list(results.glob(".*.tmp"))) == 1  # the temporary of rec02, never under its real name
    mtimes = {n: (results / n).stat().st_mtime_ns for n in finished}
    counter = FitCounter(monkeypatch)
    s = run_batch(records[0].parent, SPEC, out, engine="serial")
    assert counter.calls == ["rec02", "rec03", "rec04"]
    assert [r["reused"] for r in s.rows] == [True, True, False, False, False]
    assert {n: (results / n).stat().st_mtime_ns for n in finished} == mtimes
    assert not list(out.rglob(".*.tmp"))  # neither the result temporary nor the crashed run's row spool
    assert sorted(p.name for p in results.iterdir()) == [f"rec0{i}.json" for i in range(5)]
    for p in results.iterdir():
        assert fdml.load_result(p).converged


def test_process_pool_and_serial_give_identical_numbers(tmp_path, records):
    a = run_batch(records, SPEC, tmp_path / "serial", engine="serial")
    b = run_batch(records, SPEC, tmp_path / "pool", engine="process", workers=2)
    assert b.engine == "process" and b.n_fitted == 5
    for ra, rb in zip(a.rows, b.rows):
        assert ra["key"] == rb["key"]
        assert ra["params"] == rb["params"] and ra["stderr"] == rb["stderr"]
        assert ra["cost"] == rb["cost"] and ra["iterations"] == rb["iterations"]
    ta, tb = read_table(a.table_csv), read_table(b.table_csv)
    drop = ("source", "elapsed", "result_file")
    assert [{k: v for k, v in r.items() if k not in drop} for r in ta] == [
        {k: v for k, v in r.items() if k not in drop} for r in tb
    ]


@pytest.mark.slow
def test_process_pool_beside_threads_and_in_unguarded_scripts(tmp_path, records):
    """With another thread alive the pool uses forkserver; a script without a main guard works."""
    import threading

    from fdml.parallel import pool_context as _pool_context

    assert _pool_context().get_start_method() == "fork"
    stop = threading.Event()
    th = threading.Thread(target=stop.wait, daemon=True)
    th.start()
    try:
        assert _pool_context().get_start_method() == "forkserver"
        b = run_batch(records[:2], SPEC, tmp_path / "threads", engine="process", workers=2)
    finally:
        stop.set()
        th.join()
    a = run_batch(records[:2], SPEC, tmp_path / "serial", engine="serial")
    assert [r["params"] for r in a.rows] == [r["params"] for r in b.rows]
    script = tmp_path / "unguarded.py"
    script.write_text(
        "from fdml.batch import run_batch\n"
        f"s = run_batch({[str(p) for p in records[:3]]!r}, {SPEC!r}, {str(tmp_path / 'script')!r}, workers=2)\n"
        "print(s.n_fitted, s.n_failed)\n"
    )
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.split() == ["3", "0"], proc.stderr[-2000:]


def test_manoeuvre_windows_within_records(tmp_path, records):
    s = run_batch(
        [(records[0], 0.5, 4.5), (records[0], 1.0, None), records[0]], SPEC, tmp_path / "out", engine="serial"
    )
    assert [r["key"] for r in s.rows] == ["rec00@0.5-4.5", "rec00@1-", "rec00"]
    assert s.n_failed == 0
    res = fdml.load_result(tmp_path / "out" / s.rows[0]["result_file"])
    assert res.record().duration == pytest.approx(4.0)
    assert fdml.load_result(tmp_path / "out" / s.rows[1]["result_file"]).record().duration == pytest.approx(5.0)
    # a window outside the record is that window's error only
    s = run_batch([(records[0], 2.0, 60.0), records[1]], SPEC, tmp_path / "out2", engine="serial")
    assert s.rows[0]["status"] == "error" and "outside" in s.rows[0]["error"] and s.rows[1]["status"] == "ok"


def test_sources_folder_glob_and_duplicate_names(tmp_path, records):
    other = tmp_path / "other"
    make_records(other, 1, seed=7)
    items = collect_sources([records[0].parent, str(records[0].parent / "rec0[01].csv"), other / "rec00.csv"])
    keys = [i.key for i in items]
    assert len(items) == 6  # the glob's files are already in the folder
    assert keys[1:5] == ["rec01", "rec02", "rec03", "rec04"]
    assert keys[0].startswith("rec00-") and keys[5].startswith("rec00-") and keys[0] != keys[5]
    with pytest.raises(fdml.FdmlError, match="no records match"):
        collect_sources(str(tmp_path / "nothing*.csv"))


def test_bad_options_fail_once_before_any_fit(tmp_path, records):
    with pytest.raises(fdml.FdmlError, match="unknown fit option"):
        run_batch(records, SPEC, tmp_path, fit_kwargs={"bnad": "0.1:10:0.1"})
    with pytest.raises(fdml.FdmlError, match="plain data"):
        run_batch(records, SPEC, tmp_path, fit_kwargs={"omega": object()})
    with pytest.raises(fdml.AircraftError):
        run_batch(records, {"kind": "steady", "aircraft": "concorde"}, tmp_path)
    with pytest.raises(fdml.FdmlError, match="engine"):
        run_batch(records, SPEC, tmp_path, engine="threads")


def test_model_spec_round_trip():
    m = fdml.make_model("unsteady", "sundowner").with_values({"Cm_de": -1.1}).fix(["deps_da"])
    spec = ModelSpec.from_model(m).normalized()
    rebuilt = spec.build()
    assert rebuilt.parameters.values == m.parameters.values
    assert rebuilt.parameters.free_names == m.parameters.free_names
    s2 = ModelSpec.coerce({"kind": "steady", "aircraft": "navion", "values": {"Cm_de": -1.3}, "fix": ["Cz_de"]})
    built = s2.normalized().build()
    assert built.parameters["Cm_de"].value == -1.3 and "Cz_de" not in built.parameters.free_names


# --- worker processes that die ---------------------------------------------------------------
def die_once(task):
    """Kill the worker process the first time task 1 runs (a marker file remembers)."""
    marker = Path(task["marker"])
    if task["index"] == 1 and not marker.exists():
        marker.write_text("died")
        os._exit(1)
    return {"index": task["index"], "ok": True}


def always_die(task):
    if task["index"] == 2:
        os._exit(1)
    return {"index": task["index"], "ok": True}


@pytest.mark.slow
def test_process_engine_survives_dead_workers(tmp_path):
    def on_error(task, exc):
        return {"index": task["index"], "ok": False, "error": str(exc)}

    tasks = [{"index": i, "marker": str(tmp_path / "m")} for i in range(8)]
    out = list(execute(die_once, tasks, engine="process", workers=2, on_error=on_error))
    assert sorted(o["index"] for o in out) == list(range(8)) and all(o["ok"] for o in out)
    assert (tmp_path / "m").exists()
    # a task that always kills its worker is blamed alone; every other task still succeeds
    out = list(execute(always_die, [{"index": i} for i in range(6)], engine="process", workers=2, on_error=on_error))
    assert sorted(o["index"] for o in out) == list(range(6))
    assert [o["index"] for o in out if not o["ok"]] == [2]
    assert "WorkerDied" in next(o["error"] for o in out if not o["ok"])


# --- the command ---------------------------------------------------------------------------------
def test_batch_command(tmp_path, records, capsys):
    out = tmp_path / "out"
    bad = tmp_path / "bad.csv"
    bad.write_text("t,de,alpha\n")
    code = main(
        [
            "batch",
            str(records[0].parent),
            str(bad),
            f"{records[0]}@0.5:4.5",
            "--aircraft",
            "navion",
            "--model",
            "steady",
            "--output",
            str(out),
            "--serial",
            "--json",
        ]
    )
    d = json.loads(capsys.readouterr().out)
    assert code == 1 and d["records"] == 7 and d["failed"] == 1 and d["fitted"] == 6
    assert list(d["errors"]) == ["bad"]
    assert (out / "results" / "rec00@0.5-4.5.json").exists()
    code = main(
        [
            "batch",
            str(records[0].parent),
            "--aircraft",
            "navion",
            "--model",
            "steady",
            "--output",
            str(out),
            "--serial",
            "--json",
        ]
    )
    d = json.loads(capsys.readouterr().out)
    assert code == 0 and d["reused"] == 5 and d["fitted"] == 0
    assert main(["batch", str(records[0]), "--model", "steady", "--output", str(out)]) == 2
    assert "--aircraft" in capsys.readouterr().err


def test_optional_extras_are_named_when_missing(tmp_path, records, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if the dask extra were not installed
    with pytest.raises(fdml.FdmlError, match=r"fdml\[dask\]"):
        run_batch(records[:1], SPEC, tmp_path / "a", engine="tcp://127.0.0.1:8786")
    monkeypatch.setitem(sys.modules, "tqdm", None)
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    with pytest.raises(fdml.FdmlError, match=r"fdml\[progress\]"):
        run_batch(records[:1], SPEC, tmp_path / "b", engine="serial", progress=True)
