"""The Dask engine: a worker killed in the middle of a batch costs nothing.

A LocalCluster on loopback (two worker processes under nannies, one thread
and 1 GiB each) fits twelve records.  When the first result reaches the
client, the test SIGKILLs the worker process that has tasks in progress.  The
scheduler reruns that worker's tasks elsewhere (its nanny also restarts it);
because a task writes its result by an atomic rename under its own name, a
rerun cannot duplicate it.  Every record must end with exactly one result file
and exactly one table row, and none may fail.
"""

import json
import logging
import os
import signal
import time

import numpy as np
import pytest

pytest.importorskip("distributed")  # the ``dask`` extra; part of the ``test`` extra, so CI runs this

import fdml  # noqa: E402
from fdml.batch import run_batch  # noqa: E402
from fdml.montecarlo import monte_carlo  # noqa: E402
from fdml.record import add_noise  # noqa: E402
from fdml.simulate import simulate_maneuver  # noqa: E402

N_RECORDS = 12


@pytest.fixture(scope="module")
def cluster_client():
    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        memory_limit="1GiB",
        silence_logs=logging.CRITICAL,
    )
    client = Client(cluster)
    try:
        yield cluster, client
    finally:
        client.close()
        cluster.close()


@pytest.mark.slow
def test_killing_a_worker_mid_batch_loses_and_duplicates_nothing(tmp_path, cluster_client):
    cluster, client = cluster_client
    folder = tmp_path / "records"
    folder.mkdir()
    clean = simulate_maneuver(fdml.make_model("steady", "navion"), "3211", duration=20.0, dt=0.02)
    for i in range(N_RECORDS):
        add_noise(clean, 0.03, np.random.default_rng(i), relative=True).to_csv(folder / f"m{i:02d}.csv")
    client.wait_for_workers(2, timeout=30)
    pids = client.run(os.getpid)  # worker address -> process id
    killed = {}

    def kill_on_first_result(done, total, row):
        if killed:
            return
        busy = {a: keys for a, keys in client.processing().items() if keys}
        addr = next(iter(busy), None) or next(iter(pids))
        os.kill(pids[addr], signal.SIGKILL)
        killed.update(addr=addr, pid=pids[addr], done=done, busy=list(busy.get(addr, ())))

    out = tmp_path / "out"
    t0 = time.perf_counter()
    summary = run_batch(
        folder, {"kind": "steady", "aircraft": "navion"}, out, engine=client, progress=kill_on_first_result
    )
    wall = time.perf_counter() - t0
    # the kill happened in the middle: after one result, while the victim had work in progress
    assert killed["done"] == 1 and killed["busy"], killed
    assert summary.engine == "dask"
    # every record: exactly one row, one result file, no error, no leftover temporary
    keys = [f"m{i:02d}" for i in range(N_RECORDS)]
    assert [r["key"] for r in summary.rows] == keys
    assert summary.n_failed == 0 and all(r["status"] == "ok" for r in summary.rows), summary.failed
    files = sorted(p.name for p in (out / "results").iterdir())
    assert files == [f"{k}.json" for k in keys]
    table = (out / "table.csv").read_text().splitlines()
    assert len(table) == 1 + N_RECORDS and sorted(line.split(",")[0] for line in table[1:]) == keys
    assert len(json.loads((out / "table.json").read_text())["rows"]) == N_RECORDS
    for r in summary.rows:
        res = fdml.load_result(out / r["result_file"])
        assert res.records == (r["key"],) and res.converged
        assert res.params == r["params"]  # the row and the file come from the same fit
    # the killed worker is really gone (its nanny starts a new process)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            now = client.run(os.getpid)
        except Exception:
            now = {}
        if len(now) == 2 and killed["pid"] not in now.values():
            break
        time.sleep(0.2)
    assert killed["pid"] not in now.values() and len(now) == 2
    assert wall < 60


@pytest.mark.slow
def test_resume_and_monte_carlo_on_dask(tmp_path, cluster_client):
    _, client = cluster_client
    folder = tmp_path / "records"
    folder.mkdir()
    clean = simulate_maneuver(fdml.make_model("steady", "navion"), "3211", duration=6.0, dt=0.02)
    for i in range(3):
        add_noise(clean, 0.03, np.random.default_rng(10 + i), relative=True).to_csv(folder / f"r{i}.csv")
    (folder / "broken.csv").write_text("t,de\n0,0\n")
    spec = {"kind": "steady", "aircraft": "navion"}
    first = run_batch(folder, spec, tmp_path / "out", engine=client)
    again = run_batch(folder, spec, tmp_path / "out", engine=client)
    assert first.n_fitted == 3 and first.n_failed == 1 and "RecordError" in first.failed[0]["error"]
    assert again.n_reused == 3 and again.n_fitted == 0
    serial = run_batch(folder, spec, tmp_path / "serial", engine="serial")
    assert [r["params"] for r in first.rows] == [r["params"] for r in serial.rows]
    mc = monte_carlo(spec, n=6, duration=6.0, seed=2, engine=client)
    mc_serial = monte_carlo(spec, n=6, duration=6.0, seed=2, engine="serial")
    np.testing.assert_array_equal(mc.estimates, mc_serial.estimates)
