"""Processes: the workers of ``fdml batch`` and ``fdml montecarlo`` end with their parent, and
concurrent batches into one folder do not destroy each other's files.

The commands run as real processes (``python -m fdml ...``, in a new session, output to files
so that an orphaned worker cannot hold a pipe of the test open).  Each task is made long (a
fine band: about 10 s per fit) so that a parent which waits for its running tasks, or leaves
its workers behind, cannot pass; with the fix the parent and every descendant are gone in well
under a second after the signal.
"""

import csv
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import fdml
from fdml.batch import LOCK_NAME, _signals_end_the_run, run_batch
from fdml.errors import FdmlError
from fdml.record import add_noise
from fdml.simulate import simulate_maneuver

psutil = pytest.importorskip("psutil")  # installed with distributed (the ``dask`` extra, part of ``test``)

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and flock")

MODEL = ["--aircraft", "navion", "--model", "steady"]
SPEC = {"kind": "steady", "aircraft": "navion"}
#: A band this fine (99,001 frequencies) makes one fit of a 20 s record take about 10 s on the
#: development machine (measured 12 s), so a task is surely running when the signal comes.
SLOW_BAND = "0.1:10:0.0001"
#: Seconds within which the parent and all its descendants must be gone after the signal.
#: Measured with the fix: under 0.3 s for the local pool, 4 s for a Dask LocalCluster's close.
#: A parent that waits for its running ~10 s tasks (SIGINT before the fix) or orphans its
#: workers (SIGTERM, SIGKILL before the fix) fails it.
ENDS_WITHIN = 5.0
DASK_ENDS_WITHIN = 15.0


@pytest.fixture(scope="module")
def records(tmp_path_factory) -> list[Path]:
    """Four noisy 20 s 3-2-1-1 records of the steady Navion, one CSV each."""
    folder = tmp_path_factory.mktemp("records")
    clean = simulate_maneuver(fdml.make_model("steady", "navion"), "3211", duration=20.0, dt=0.02)
    paths = []
    for i in range(4):
        p = folder / f"r{i}.csv"
        add_noise(clean, 0.03, np.random.default_rng(i), relative=True).to_csv(p)
        paths.append(p)
    return paths


def windows(records, n: int) -> list[str]:
    """n distinct batch items FILE@0:T1 (each its own key and result file)."""
    return [f"{records[i % len(records)]}@0:{12 + 0.1 * (i // len(records)):.1f}" for i in range(n)]


class Launched:
    """Processes this test started; whatever a failed assertion leaves behind is killed by pid."""

    def __init__(self):
        self.procs: list[subprocess.Popen] = []
        self.kids: list = []

    def start(self, args: list[str], cwd: Path, name: str = "run") -> subprocess.Popen:
        with open(cwd / f"{name}.stdout", "w") as out, open(cwd / f"{name}.stderr", "w") as err:
            p = subprocess.Popen([sys.executable, *args], cwd=cwd, stdout=out, stderr=err, start_new_session=True)
        self.procs.append(p)
        return p

    def fdml(self, args: list[str], cwd: Path, name: str = "run") -> subprocess.Popen:
        return self.start(["-m", "fdml", *args], cwd, name)

    def cleanup(self):
        for k in self.kids:
            if alive(k):
                k.kill()
        for p in self.procs:
            if p.poll() is None:
                p.kill()
                p.wait()


@pytest.fixture
def launched():
    runs = Launched()
    try:
        yield runs
    finally:
        runs.cleanup()


def alive(p) -> bool:
    """A process still running (a zombie has ended: only its exit status waits to be read)."""
    try:
        return p.is_running() and p.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def wait_for_workers(
    runs: Launched, proc: subprocess.Popen, n: int, *, match: str = "", settle: float = 0.5, timeout: float = 60.0
) -> list:
    """The descendants of ``proc`` once ``n`` of them (whose command line has ``match``) exist."""
    parent = psutil.Process(proc.pid)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"exited early with {proc.returncode}"
        try:
            kids = [k for k in parent.children(recursive=True) if match in " ".join(k.cmdline())]
        except psutil.NoSuchProcess:  # a child ended while being read
            continue
        if len(kids) >= n:
            time.sleep(settle)  # let the workers take their first tasks
            kids = parent.children(recursive=True)
            runs.kids += kids
            return kids
        time.sleep(0.05)
    pytest.fail(f"{n} worker processes did not appear within {timeout} s")


def assert_all_ended(proc: subprocess.Popen, kids: list, within: float) -> float:
    """The parent and every descendant end within ``within`` s; returns the seconds taken."""
    t0 = time.monotonic()
    try:
        proc.wait(timeout=within)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the parent is still running {within} s after the signal")
    while any(alive(k) for k in kids) and time.monotonic() - t0 < within:
        time.sleep(0.05)
    left = [(k.pid, " ".join(k.cmdline())[-60:]) for k in kids if alive(k)]
    assert not left, f"processes left running {within} s after the parent's signal: {left}"
    return time.monotonic() - t0


def stderr_of(cwd: Path, name: str = "run") -> str:
    return (cwd / f"{name}.stderr").read_text()


def signal_usable(signame: str):
    """Skip when the signal is ignored here (a background job, nohup): the child inherits that."""
    if signal.getsignal(getattr(signal, signame)) == signal.SIG_IGN:
        pytest.skip(f"{signame} is ignored in this test process, so in its children too")


# --- signals to the parent ----------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("signame, status", [("SIGTERM", 128 + 15), ("SIGINT", 130), ("SIGHUP", 128 + 1)])
def test_a_signal_ends_the_batch_and_its_workers(tmp_path, records, launched, signame, status):
    signal_usable(signame)
    out = tmp_path / "out"
    proc = launched.fdml(
        [
            "batch",
            *windows(records, 8),
            *MODEL,
            "--band",
            SLOW_BAND,
            "--output",
            str(out),
            "--workers",
            "2",
            "--no-progress",
        ],
        tmp_path,
    )
    kids = wait_for_workers(launched, proc, 2)
    os.kill(proc.pid, getattr(signal, signame))
    assert_all_ended(proc, kids, ENDS_WITHIN)
    # 128 + 15 is SystemExit from the handler; a parent killed by the signal itself gives -15
    assert proc.returncode == status, stderr_of(tmp_path)
    assert "Traceback" not in stderr_of(tmp_path)
    assert not list(out.glob(".rows-*.tmp"))  # the parent removed its row spool
    assert not (out / "table.csv").exists()  # never a table of a batch that did not finish


@pytest.mark.slow
@pytest.mark.parametrize("signame, status", [("SIGTERM", 128 + 15), ("SIGINT", 130)])
def test_a_signal_ends_the_monte_carlo_study_and_its_workers(tmp_path, launched, signame, status):
    signal_usable(signame)
    proc = launched.fdml(
        ["montecarlo", *MODEL, "-n", "40", "--duration", "20", "--band", SLOW_BAND, "--workers", "2", "--no-progress"],
        tmp_path,
    )
    kids = wait_for_workers(launched, proc, 2)
    os.kill(proc.pid, getattr(signal, signame))
    assert_all_ended(proc, kids, ENDS_WITHIN)
    assert proc.returncode == status, stderr_of(tmp_path)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG) is Linux only")
def test_sigkill_of_the_parent_ends_the_workers(tmp_path, records, launched):
    """SIGKILL runs no handler: the workers notice on their own (the kernel signals them)."""
    proc = launched.fdml(
        [
            "batch",
            *windows(records, 8),
            *MODEL,
            "--band",
            SLOW_BAND,
            "--output",
            str(tmp_path / "out"),
            "--workers",
            "2",
            "--no-progress",
        ],
        tmp_path,
    )
    kids = wait_for_workers(launched, proc, 2)
    os.kill(proc.pid, signal.SIGKILL)
    assert_all_ended(proc, kids, ENDS_WITHIN)
    assert proc.returncode == -signal.SIGKILL


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG) is Linux only")
def test_sigkill_ends_forkserver_workers_too(tmp_path, records, launched):
    """With another thread alive the pool forks from a forkserver, whose exit ends the workers."""
    script = tmp_path / "threaded.py"
    script.write_text(
        textwrap.dedent(f"""
        import threading
        from fdml.batch import run_batch
        from fdml.parallel import pool_context as _pool_context

        if __name__ == "__main__":
            threading.Thread(target=threading.Event().wait, daemon=True).start()
            assert _pool_context().get_start_method() == "forkserver"
            run_batch({[str(r) for r in records]!r}, {SPEC!r}, "out", workers=2,
                      fit_kwargs={{"band": {SLOW_BAND!r}}})
    """)
    )
    proc = launched.start([str(script)], tmp_path)
    # the forkserver and the two workers it forked (they share its command line)
    kids = wait_for_workers(launched, proc, 3, match="forkserver")
    os.kill(proc.pid, signal.SIGKILL)
    assert_all_ended(proc, kids, ENDS_WITHIN)


@pytest.mark.slow
def test_sigterm_closes_the_dask_cluster_the_batch_started(tmp_path, records, launched):
    pytest.importorskip("distributed")
    proc = launched.fdml(
        [
            "batch",
            *windows(records, 8),
            *MODEL,
            "--band",
            SLOW_BAND,
            "--output",
            str(tmp_path / "out"),
            "--workers",
            "2",
            "--no-progress",
            "--scheduler",
            "dask",
        ],
        tmp_path,
    )
    kids = wait_for_workers(launched, proc, 2, match="spawn_main", settle=1.5)
    os.kill(proc.pid, signal.SIGTERM)
    assert_all_ended(proc, kids, DASK_ENDS_WITHIN)
    assert proc.returncode == 128 + 15, stderr_of(tmp_path)[-2000:]


@pytest.mark.slow
def test_a_callers_dask_client_stays_open_and_its_futures_are_cancelled(tmp_path, records, launched):
    """An interrupted run on the caller's Client cancels what it submitted and leaves the Client open.

    In a process of its own: a Dask client leaves a thread behind in its process, after which
    the local pool would no longer fork (test_batch checks that it does).
    """
    pytest.importorskip("distributed")
    items = [(str(r), 0.0, t1) for t1 in (12.0, 13.0) for r in records]  # 8 windows, 0.1 s fits
    script = tmp_path / "client.py"
    script.write_text(
        textwrap.dedent(f"""
        import logging, time
        import distributed
        from fdml.batch import run_batch

        def stop(done, total, row):
            raise KeyboardInterrupt  # what SIGINT raises; SIGTERM raises SystemExit the same way

        if __name__ == "__main__":
            with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                          dashboard_address=None, silence_logs=logging.CRITICAL) as cluster:
                with distributed.Client(cluster) as client:
                    try:
                        run_batch({items!r}, {SPEC!r}, "out", engine=client, progress=stop)
                    except KeyboardInterrupt:
                        pass
                    deadline = time.monotonic() + 20
                    while any(client.processing().values()) and time.monotonic() < deadline:
                        time.sleep(0.05)
                    time.sleep(1.0)  # a task that was not cancelled would write its file meanwhile
                    print(client.status, sum(map(len, client.processing().values())),
                          client.submit(sum, [1, 2]).result())
    """)
    )
    proc = launched.start([str(script)], tmp_path)
    assert proc.wait(timeout=120) == 0, stderr_of(tmp_path)[-2000:]
    assert (tmp_path / "run.stdout").read_text().split() == ["running", "0", "3"]
    written = list((tmp_path / "out" / "results").glob("*.json"))
    # one task finished (the interruption came with its row), one may have been running on the
    # single worker thread; the six still queued were cancelled and never wrote a file
    assert 1 <= len(written) <= 2, [p.name for p in written]


# --- the run, the folder, the rerun ---------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("signame, status", [("SIGTERM", 128 + 15), ("SIGINT", 130)])
def test_a_rerun_after_a_signal_resumes_and_leaves_no_partial_file(tmp_path, records, launched, signame, status):
    signal_usable(signame)
    out = tmp_path / "out"
    items = windows(records, 60)
    args = ["batch", *items, *MODEL, "--output", str(out), "--workers", "2", "--no-progress", "--json"]
    proc = launched.fdml(args, tmp_path, "first")
    deadline = time.monotonic() + 60
    while len(list((out / "results").glob("*.json"))) < 3:
        assert proc.poll() is None and time.monotonic() < deadline, stderr_of(tmp_path, "first")
        time.sleep(0.02)
    kids = psutil.Process(proc.pid).children(recursive=True)
    launched.kids += kids
    os.kill(proc.pid, getattr(signal, signame))
    assert_all_ended(proc, kids, ENDS_WITHIN)
    assert proc.returncode == status, stderr_of(tmp_path, "first")
    finished = sorted(p.name for p in (out / "results").glob("*.json"))
    assert 3 <= len(finished) < len(items)
    for name in finished:  # every file under its real name is whole
        assert fdml.load_result(out / "results" / name).converged
    assert not (out / "table.csv").exists()

    rerun = launched.fdml(args, tmp_path, "rerun")
    assert rerun.wait(timeout=120) == 0, stderr_of(tmp_path, "rerun")
    summary = json.loads((tmp_path / "rerun.stdout").read_text())
    assert summary["reused"] == len(finished) and summary["failed"] == 0
    assert summary["fitted"] == len(items) - len(finished)
    with open(out / "table.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(items) and all(r["status"] == "ok" for r in rows)
    assert not list(out.rglob("*.tmp"))  # the first run's temporaries (if any) are gone as well


@pytest.mark.slow
def test_two_batches_into_one_folder_at_once_both_finish(tmp_path, records, launched):
    """The second batch waits for the first; neither destroys a file of the other.

    Batch A holds the temporary file of its first result open (its write is paused on a
    marker file) while batch B starts on the same folder.  Before the lock, B's start-up
    clean-up deleted that temporary file and A's record failed on the rename.
    """
    out = tmp_path / "out"
    script = tmp_path / "paused.py"
    script.write_text(
        textwrap.dedent(f"""
        import os, sys, time
        from pathlib import Path
        import fdml.batch as b

        real = b.atomic_write_text
        def paused(path, text, *args, **kw):
            path = Path(path)
            if path.parent.name == "results" and not Path("go").exists():
                tmp = path.parent / f".{{path.name}}.paused.tmp"
                tmp.write_text(text)
                Path("ready").touch()
                while not Path("go").exists():
                    time.sleep(0.02)
                os.replace(tmp, path)
                return path
            return real(path, text, *args, **kw)

        b.atomic_write_text = paused
        s = b.run_batch({[str(r) for r in records[:2]]!r}, {SPEC!r}, {str(out)!r}, engine="serial")
        print(s.n_total, s.n_failed)
    """)
    )
    a = launched.start([str(script)], tmp_path, "a")
    deadline = time.monotonic() + 60
    while not (tmp_path / "ready").exists():
        assert a.poll() is None and time.monotonic() < deadline, stderr_of(tmp_path, "a")
        time.sleep(0.02)
    b = launched.fdml(
        ["batch", *map(str, records), *MODEL, "--output", str(out), "--workers", "2", "--no-progress", "--json"],
        tmp_path,
        "b",
    )
    deadline = time.monotonic() + 30
    while "in use by another fdml batch" not in stderr_of(tmp_path, "b") and b.poll() is None:
        assert time.monotonic() < deadline, "batch B neither waited nor finished"
        time.sleep(0.05)
    assert b.poll() is None, "batch B did not wait for batch A"
    (tmp_path / "go").touch()
    assert a.wait(timeout=60) == 0, stderr_of(tmp_path, "a")
    assert (tmp_path / "a.stdout").read_text().split() == ["2", "0"]  # A lost nothing to B
    assert b.wait(timeout=120) == 0, stderr_of(tmp_path, "b")
    summary = json.loads((tmp_path / "b.stdout").read_text())
    assert summary["records"] == 4 and summary["failed"] == 0
    with open(out / "table.csv", newline="") as fh:  # B ran last: its table, whole
        rows = list(csv.DictReader(fh))
    assert [r["key"] for r in rows] == [r.stem for r in records] and all(r["status"] == "ok" for r in rows)
    assert len(json.loads((out / "table.json").read_text())["rows"]) == 4
    for r in records:
        assert fdml.load_result(out / "results" / f"{r.stem}.json").converged
    assert not list(out.rglob("*.tmp"))


def test_only_stale_temporaries_are_removed(tmp_path, records):
    """Temporaries of a batch that is gone go; a live batch's spool and other commands' files stay."""
    out = tmp_path / "out"
    (out / "results").mkdir(parents=True)
    crashed_result = out / "results" / ".r0.json.abc123.tmp"
    crashed_table = out / ".table.csv.def456.tmp"
    crashed_spool = out / ".rows-999999.jsonl.tmp"
    live_spool = out / ".rows-1.jsonl.tmp"  # a batch waiting for the folder holds its spool's lock
    foreign = out / ".notes.json.ghi789.tmp"  # e.g. `fdml fit -o out/notes.json` in progress
    for f in (crashed_result, crashed_table, crashed_spool, live_spool, foreign):
        f.write_text("x")
    import fcntl

    with open(live_spool) as held:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)  # flock: per open file, so it holds against us too
        s = run_batch(records[:1], SPEC, out, engine="serial")
        assert s.n_failed == 0
        assert live_spool.exists() and foreign.exists()
    assert not crashed_result.exists() and not crashed_table.exists() and not crashed_spool.exists()
    assert (out / LOCK_NAME).is_file()


def test_the_lock_file_must_be_a_regular_file(tmp_path, records):
    out = tmp_path / "out"
    (out / LOCK_NAME).mkdir(parents=True)
    with pytest.raises(FdmlError, match=re.escape(f"lock file {out / LOCK_NAME}")):
        run_batch(records[:1], SPEC, out, engine="serial")


def test_a_worker_reimporting_an_unguarded_script_refuses_rather_than_waits(tmp_path, records, monkeypatch):
    """Such a worker would wait for its own parent's lock for ever."""
    import multiprocessing

    monkeypatch.setattr(multiprocessing.current_process(), "_inheriting", True, raising=False)
    with pytest.raises(FdmlError, match="__name__ == '__main__'"):
        run_batch(records[:1], SPEC, tmp_path / "out", engine="serial")


# --- the signal handlers themselves -----------------------------------------------------------------
def test_signal_handlers_are_put_back_and_left_alone_when_not_default():
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}

    def mine(signum, frame):
        return None

    signal.signal(signal.SIGHUP, mine)
    try:
        with _signals_end_the_run():
            assert signal.getsignal(signal.SIGHUP) is mine  # the caller's own handler stays
            if before[signal.SIGTERM] == signal.SIG_DFL:
                assert callable(signal.getsignal(signal.SIGTERM))
                with pytest.raises(SystemExit) as exc:
                    os.kill(os.getpid(), signal.SIGTERM)
                    time.sleep(1)  # the handler runs at the next bytecode; never reached
                assert exc.value.code == 128 + signal.SIGTERM
                assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # a second one kills at once
    finally:
        signal.signal(signal.SIGHUP, before[signal.SIGHUP])
    assert {s: signal.getsignal(s) for s in before} == before


def test_no_handlers_from_another_thread(tmp_path, records):
    """signal.signal works only in the main thread: a batch in a thread installs none and works."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as th:
        summary = th.submit(run_batch, records[:2], SPEC, tmp_path / "out", engine="process", workers=2).result(
            timeout=120
        )
    assert summary.n_failed == 0


# --- records that change under a running batch ----------------------------------------------------
#: A band fine enough that one fit of a 20 s record takes a few seconds (2,476 frequencies;
#: measured 2-4 s): the later records are surely not read yet when the first result appears.
MEDIUM_BAND = "0.1:10:0.004"


def test_a_record_removed_or_truncated_during_the_run_gets_its_error_row(tmp_path, records, launched):
    """Each record is read when its task starts: one removed or cut short meanwhile is an error row
    naming the file (and the batch ends with exit code 1), the others fit as usual."""
    folder = tmp_path / "records"
    folder.mkdir()
    paths = []
    for i, src in enumerate(records):
        p = folder / f"r{i}.csv"
        p.write_bytes(src.read_bytes())  # copies: the module's records stay intact
        paths.append(p)
    out = tmp_path / "out"
    proc = launched.fdml(
        [
            "batch",
            *map(str, paths),
            *MODEL,
            "--band",
            MEDIUM_BAND,
            "--output",
            str(out),
            "--workers",
            "1",
            "--no-progress",
            "--json",
        ],
        tmp_path,
    )
    deadline = time.monotonic() + 120
    while not list((out / "results").glob("r0*.json")):
        assert proc.poll() is None and time.monotonic() < deadline, stderr_of(tmp_path)
        time.sleep(0.02)
    paths[2].unlink()
    data = paths[3].read_bytes()
    paths[3].write_bytes(data[: len(data) // 2])  # cut inside a line, as an interrupted copy leaves it
    assert proc.wait(timeout=180) == 1, stderr_of(tmp_path)
    assert "Traceback" not in stderr_of(tmp_path)
    with open(out / "table.csv", newline="") as fh:
        rows = {r["key"]: r for r in csv.DictReader(fh)}
    assert [rows[f"r{i}"]["status"] for i in range(4)] == ["ok", "ok", "error", "error"]
    assert str(paths[2]) in rows["r2"]["error"] and "does not exist" in rows["r2"]["error"]
    assert str(paths[3]) in rows["r3"]["error"] and "truncated" in rows["r3"]["error"]
    assert (out / "results" / "r2.error.json").exists() and (out / "results" / "r3.error.json").exists()
    assert not list(out.rglob("*.tmp"))
