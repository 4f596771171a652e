"""Peak memory of ``fdml.batch.run_batch`` against the number of records.

For each batch size (default 10, 100, 1000) the script simulates that many
small records (steady Navion, 3-2-1-1, 6 s at 50 Hz, 3 % noise, one CSV
each) into a temporary folder and fits them in a fresh Python process on the
process pool (twice: once for the resident sets, once with the heap traced).  It reports

* the parent's peak resident set (``VmHWM`` of /proc/self/status, which,
  unlike ``getrusage``'s ``ru_maxrss``, does not carry over the peak of the
  process that forked it) and its peak Python heap during the batch
  (``tracemalloc``);
* the largest peak resident set of any worker process (its ``VmHWM``), and the
  peak of the whole process tree (parent, forkserver, workers) sampled every
  20 ms from /proc (psutil when installed);

and whether the figures stay flat: workers write their results to disk and
return one short row, which the parent appends to a spool file; it keeps only
the list of sources and a file offset per record.

    python benchmarks/bench_batch_memory.py [--sizes 10 100 1000] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path


def make_records(folder: Path, n: int) -> None:
    import numpy as np

    import fdml
    from fdml.record import add_noise
    from fdml.simulate import simulate_maneuver

    clean = simulate_maneuver(fdml.make_model("steady", "navion"), "3211", duration=6.0, dt=0.02)
    for i in range(n):
        add_noise(clean, 0.03, np.random.default_rng(i), relative=True).to_csv(folder / f"rec{i:04d}.csv")


def _status_kb(pid: int | str, key: str) -> int:
    """A ``VmHWM``/``VmRSS`` line of /proc/PID/status in kB (0 where there is no /proc)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(key + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def _peak_kb() -> int:
    import resource

    return _status_kb("self", "VmHWM") or resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def child(folder: str, out: str, workers: int, trace: bool) -> None:
    """Run one batch; print JSON with this process's peak figures.

    With ``trace`` the Python heap is traced (tracemalloc's own bookkeeping
    inflates the resident set, so the RSS figures come from a run without it).
    """
    import tracemalloc

    from fdml.batch import run_batch

    base_rss = _peak_kb()
    if trace:
        tracemalloc.start()
    t0 = time.perf_counter()
    s = run_batch(folder, {"kind": "steady", "aircraft": "navion"}, out, workers=workers, resume=False)
    wall = time.perf_counter() - t0
    heap_peak = tracemalloc.get_traced_memory()[1] if trace else 0
    tracemalloc.stop()
    print(
        json.dumps(
            {
                "n": s.n_total,
                "failed": s.n_failed,
                "wall": wall,
                "heap_peak": heap_peak,
                "rss_before_kb": base_rss,
                "parent_maxrss_kb": _peak_kb(),
            }
        )
    )


def _rss_tree(pid: int) -> dict[int, int]:
    """RSS in bytes of ``pid`` and all its descendants."""
    try:
        import psutil

        p = psutil.Process(pid)
        out = {pid: p.memory_info().rss}
        for c in p.children(recursive=True):
            try:
                out[c.pid] = c.memory_info().rss
            except psutil.Error:
                pass
        return out
    except ImportError:
        pass
    except Exception:
        return {}
    out, todo = {}, [pid]
    while todo:
        q = todo.pop()
        try:
            for line in Path(f"/proc/{q}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    out[q] = int(line.split()[1]) * 1024
            for task in Path(f"/proc/{q}/task").iterdir():
                todo.extend(int(c) for c in (task / "children").read_text().split())
        except OSError:
            continue
    return out


def measure(n: int, workers: int, root: Path) -> dict:
    folder = root / f"records{n}"
    folder.mkdir()
    make_records(folder, n)
    cmd = [sys.executable, __file__, "--child", str(folder), str(root / f"out{n}"), str(workers)]
    traced = subprocess.run(cmd + ["1"], stdout=subprocess.PIPE, text=True, check=True)
    heap_peak = json.loads(traced.stdout.strip().splitlines()[-1])["heap_peak"]
    proc = subprocess.Popen(cmd + ["0"], stdout=subprocess.PIPE, text=True)
    peaks: dict[int, int] = {}
    tree_peak = [0]
    stop = threading.Event()

    def sample():
        while not stop.is_set():
            rss = _rss_tree(proc.pid)
            for k, v in rss.items():
                hwm = _status_kb(k, "VmHWM") * 1024  # the true peak, also between samples
                peaks[k] = max(peaks.get(k, 0), v, hwm)
            tree_peak[0] = max(tree_peak[0], sum(rss.values()))
            time.sleep(0.02)

    th = threading.Thread(target=sample, daemon=True)
    th.start()
    out, _ = proc.communicate()
    stop.set()
    th.join()
    if proc.returncode:
        raise SystemExit(f"batch of {n} failed (exit {proc.returncode})")
    d = json.loads(out.strip().splitlines()[-1])
    d["heap_peak"] = heap_peak
    others = [v for k, v in peaks.items() if k != proc.pid]
    d["worker_peak"] = max(others) if others else 0
    d["tree_peak"] = tree_peak[0]
    d["n_processes"] = len(peaks)
    d["results_bytes"] = sum(p.stat().st_size for p in (root / f"out{n}" / "results").iterdir())
    return d


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--child", nargs=4, metavar=("FOLDER", "OUT", "WORKERS", "TRACE"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child[0], args.child[1], int(args.child[2]), args.child[3] == "1")
        return
    rows = []
    with tempfile.TemporaryDirectory(prefix="fdml-batch-mem-") as tmp:
        for n in args.sizes:
            d = measure(n, args.workers, Path(tmp))
            rows.append(d)
            print(f"  {n} records done in {d['wall']:.1f} s", file=sys.stderr)
    mb = 1 / 2**20
    print(f"fdml batch peak memory, {args.workers} workers (steady Navion, 6 s records at 50 Hz)")
    print(
        f"{'records':>8} {'wall s':>7} {'parent RSS MB':>14} {'parent heap MB':>15} {'worker RSS MB':>14} "
        f"{'tree RSS MB':>12} {'results MB':>11}"
    )
    for d in rows:
        print(
            f"{d['n']:>8} {d['wall']:>7.1f} {d['parent_maxrss_kb'] / 1024:>14.1f} {d['heap_peak'] * mb:>15.2f} "
            f"{d['worker_peak'] * mb:>14.1f} {d['tree_peak'] * mb:>12.1f} {d['results_bytes'] * mb:>11.1f}"
        )
    first, last = rows[0], rows[-1]
    growth = {
        "parent RSS": last["parent_maxrss_kb"] / first["parent_maxrss_kb"] - 1,
        "worker RSS": (last["worker_peak"] / first["worker_peak"] - 1) if first["worker_peak"] else 0.0,
        "tree RSS": last["tree_peak"] / first["tree_peak"] - 1,
    }
    per_record_heap = (last["heap_peak"] - first["heap_peak"]) / max(last["n"] - first["n"], 1)
    flat = all(abs(g) < 0.10 for g in growth.values())
    print(
        f"from {first['n']} to {last['n']} records ({last['n'] / first['n']:.0f}x): "
        + ", ".join(f"{k} {100 * g:+.1f} %" for k, g in growth.items())
        + f"; parent heap {per_record_heap:.0f} bytes per record (its source entry and spool offset)"
    )
    print("peak memory is flat in the number of records" if flat else "peak memory GROWS with the number of records")


if __name__ == "__main__":
    main()
