"""The one parallel engine (fdml.parallel): every engine gives the same results, in order when
asked, an error stays with its task, and progress is reported once per task."""

import logging
import subprocess
import sys
import time

import pytest

from fdml.errors import FdmlError
from fdml.parallel import engine_name, execute, one_line

N = 12


def triangular(task: dict) -> dict:
    """Sum of 1..n by a loop (checked against the closed form n (n + 1) / 2)."""
    n = task["n"]
    if task.get("fail"):
        raise ValueError(f"bad task {n}")
    if task.get("sleep"):
        time.sleep(task["sleep"])
    return {"n": n, "sum": sum(range(1, n + 1))}


def on_error(task, exc) -> dict:
    return {"n": task["n"], "error": exc if isinstance(exc, str) else one_line(exc)}


def tasks(**extra) -> list[dict]:
    return [{"n": n, **extra} for n in range(N)]


@pytest.fixture(scope="module")
def client():
    """An in-process Dask cluster (threads): the engine's Dask path without starting processes."""
    distributed = pytest.importorskip("distributed")
    with distributed.Client(
        processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None, silence_logs=logging.CRITICAL
    ) as c:
        yield c


def test_serial_pool_and_dask_give_the_same_results(client):
    by_engine = {}
    for engine in ("serial", "process", client):
        out = list(execute(triangular, tasks(), engine=engine, workers=2, on_error=on_error))
        by_engine[engine_name(engine)] = sorted((r["n"], r["sum"]) for r in out)
    expected = [(n, n * (n + 1) // 2) for n in range(N)]  # closed form, independent of the loop
    assert by_engine == {"serial": expected, "process": expected, "dask": expected}


@pytest.mark.parametrize("engine", ["serial", "process", "dask"])
def test_ordered_keeps_task_order_when_early_tasks_finish_last(engine, client):
    # the first tasks sleep longest, so on two workers they finish after the later ones
    work = [{"n": n, "sleep": 0.02 * (N - n) if n < 4 else 0} for n in range(N)]
    out = list(
        execute(
            triangular, work, engine=client if engine == "dask" else engine, workers=2, on_error=on_error, ordered=True
        )
    )
    assert [r["n"] for r in out] == list(range(N))


@pytest.mark.parametrize("engine", ["serial", "process", "dask"])
def test_an_exception_is_reported_for_its_task_only(engine, client):
    work = [{"n": n, "fail": n == 3} for n in range(N)]
    out = list(execute(triangular, work, engine=client if engine == "dask" else engine, workers=2, on_error=on_error))
    failed = [r for r in out if "error" in r]
    assert [r["n"] for r in failed] == [3]
    assert failed[0]["error"] == "ValueError: bad task 3"
    assert sorted(r["n"] for r in out if "error" not in r) == [n for n in range(N) if n != 3]


@pytest.mark.parametrize("engine", ["serial", "process", "dask"])
def test_progress_is_called_once_per_task(engine, client):
    calls = []
    out = list(
        execute(
            triangular,
            tasks(),
            engine=client if engine == "dask" else engine,
            workers=2,
            on_error=on_error,
            progress=lambda done, total, result: calls.append((done, total, result["n"])),
            total=N,
        )
    )
    assert [c[0] for c in calls] == list(range(1, N + 1))  # one call per task, counting up
    assert {c[1] for c in calls} == {N}
    assert [c[2] for c in calls] == [r["n"] for r in out]  # with the result just finished


def test_bad_engine_and_progress_are_one_line_errors():
    with pytest.raises(FdmlError, match="engine must be"):
        list(execute(triangular, tasks(), engine="threads", on_error=on_error))
    with pytest.raises(FdmlError, match="progress must be"):
        list(execute(triangular, tasks(), engine="serial", on_error=on_error, progress=42))


def test_closing_early_stops_the_run():
    run = execute(triangular, tasks(sleep=0.05), engine="process", workers=2, on_error=on_error)
    first = next(run)
    run.close()  # ends the pool at once, leaves nothing running
    assert first["sum"] == first["n"] * (first["n"] + 1) // 2


def test_validate_stays_the_function_after_its_submodule_is_imported():
    """The harness module is fdml.diagnose.validation: importing it cannot replace the function."""
    code = (
        "import inspect, fdml.diagnose.validation, fdml.diagnose\n"
        "from fdml.diagnose import validate\n"
        "assert inspect.isfunction(fdml.diagnose.validate), fdml.diagnose.validate\n"
        "assert validate is fdml.diagnose.validate\n"
        "print('ok')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]
