"""One parallel engine: a function over many tasks, serially, on a local process pool or on Dask.

:func:`execute` is the one place fdml runs work in parallel; the batch
(:func:`fdml.batch.run_batch`), the Monte Carlo studies
(:func:`fdml.montecarlo.monte_carlo`) and the diagnosis validation
(:func:`fdml.diagnose.validate`) all use it.  Engines:

``"serial"``
    in this process, one task after the other;
``"process"`` (default)
    a local process pool (:func:`pool_context` chooses the start method) that
    survives worker processes that die (the tasks in flight are rerun one at
    a time, so only the task that kills its worker is blamed);
``"dask"``, a scheduler address or a ``dask.distributed.Client``
    Dask (the optional ``dask`` extra); ``"dask"`` starts a local cluster for
    the run and closes it after.

A task that raises, or whose execution fails outside it (a worker that died
under it twice while running alone; a Dask ``KilledWorker``), yields
``on_error(task, exc)`` in its place: an error belongs to its task only.
At most a few tasks per worker are in flight, so memory stays flat in the
number of tasks.  The run ends with this process, whatever ends it: SIGTERM
and SIGHUP raise here while a run is going (:func:`signals_end_the_run`), the
``finally`` blocks end the workers at once, and local workers also die with
SIGKILL of this process (:func:`_die_with_parent`, Linux).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
from collections import deque
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping
from typing import Any

from .errors import FdmlError

__all__ = ["execute", "engine_name", "one_line", "pool_context", "signals_end_the_run"]

logger = logging.getLogger(__name__)

#: Deaths of a local worker process, running a task alone, after which the task is given up.
_LONE_DEATHS = 2
#: Signals that, at their default disposition, end a run by an exception (so its ``finally`` runs).
_ENDING_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")
#: Seconds a terminated worker process gets to exit before it is killed.
_STOP_GRACE = 2.0
#: ``prctl`` option: the signal this process gets when its parent ends (``linux/prctl.h``).
_PR_SET_PDEATHSIG = 1
#: Modules a forkserver imports once, so that its forks start warm.
_PRELOAD = ["fdml.parallel", "fdml.batch", "fdml.montecarlo", "fdml.estimate", "fdml.io"]


def one_line(exc: BaseException) -> str:
    """``"Type: first line of the message"`` of an exception (a task's error in a table row).

    Parameters
    ----------
    exc : BaseException
        The exception.

    Returns
    -------
    str
        Its class name, and the first line of its message if it has one.
    """
    lines = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__


# --- the engine --------------------------------------------------------------------------------------
def execute(
    fn: Callable[[Any], Any],
    tasks: Iterable,
    *,
    engine="process",
    workers: int | None = None,
    on_error: Callable[[Any, BaseException | str], Any],
    progress=None,
    total: int | None = None,
    desc: str = "fdml",
    ordered: bool = False,
) -> Generator[Any, None, None]:
    """Run ``fn(task)`` for every task on ``engine``; yield the results.

    Parameters
    ----------
    fn : callable
        A module-level function (it is pickled by reference for the process
        pool and Dask) returning a small, picklable result.
    tasks : iterable
        Picklable tasks, consumed lazily.
    engine : {"process", "serial", "dask"}, scheduler address or dask.distributed.Client
        See the module docstring.
    workers : int, optional
        Local worker processes (default all cores); for ``"dask"`` the local
        cluster's.
    on_error : callable
        ``on_error(task, exc)`` is yielded in place of the result of a task
        that failed (``exc``: the exception, or a message for a worker that
        died).
    progress : None, True or callable, optional
        True: a tqdm bar; a callable is called as ``progress(done, total,
        result)`` in this process once per task (:func:`fdml.progress.task_progress`).
    total : int, optional
        Number of tasks, for the progress bar.
    desc : str, optional
        Label of the progress bar.
    ordered : bool, optional
        Yield the results in task order (results that finish early wait in
        memory for the ones before them); default: as they finish.

    Yields
    ------
    object
        One result (or ``on_error``'s value) per task.

    Notes
    -----
    Close the generator when stopping early (``contextlib.closing``): local
    workers are then terminated at once (not left to finish their task), a
    Dask cluster started here is closed and the futures of a caller's Client
    are cancelled (the Client stays open).
    """
    from .progress import task_progress

    update, close = task_progress(progress, total, desc)
    with signals_end_the_run():
        kind, client, owned = _resolve_engine(engine, workers)
        try:
            if kind == "serial":
                pairs = _serial_map(fn, tasks, on_error)
            elif kind == "process":
                pairs = _process_map(fn, tasks, workers or os.cpu_count() or 1, on_error)
            else:
                pairs = _dask_map(client, fn, tasks, on_error)
            with contextlib.closing(pairs):
                for done, (_, out) in enumerate(_in_order(pairs) if ordered else pairs, 1):
                    update(out, done)
                    yield out
        finally:
            close()
            if owned:
                cluster = getattr(client, "cluster", None)
                client.close()
                if cluster is not None:
                    cluster.close()


def _in_order(pairs: Iterator[tuple[int, Any]]) -> Iterator[tuple[int, Any]]:
    """(position, result) pairs in position order; early ones wait for those before them."""
    waiting: dict[int, Any] = {}
    nxt = 0
    for i, out in pairs:
        waiting[i] = out
        while nxt in waiting:
            yield nxt, waiting.pop(nxt)
            nxt += 1


def _serial_map(fn, tasks, on_error) -> Generator[tuple[int, Any], None, None]:
    """Each task in this process, with one BLAS thread as in a pool worker (:func:`_worker_init`): the
    order of a multi-threaded BLAS's sums would change the last digits, and the engines give the same
    numbers."""
    from threadpoolctl import threadpool_limits

    for i, task in enumerate(tasks):
        with threadpool_limits(limits=1, user_api="blas"):
            try:
                out = fn(task)
            except Exception as exc:  # this task's failure, never the run's
                out = on_error(task, exc)
        yield i, out


def _label(task, i: int):
    """How the log names a task: its ``key`` (batch tasks), else its position."""
    return task.get("key", i) if isinstance(task, Mapping) else i


def _is_dask_client(engine) -> bool:
    return type(engine).__module__.split(".")[0] == "distributed" and hasattr(engine, "submit")


def _dask_missing() -> FdmlError:
    return FdmlError("the Dask engine needs the optional 'dask' extra: pip install 'fdml[dask]'")


def engine_name(engine) -> str:
    """``"process"``, ``"serial"`` or ``"dask"`` for an ``engine`` argument (as results record it).

    Parameters
    ----------
    engine : None, str or dask.distributed.Client
        The ``engine`` argument of a run (None is the local process pool).

    Returns
    -------
    str
        The engine's name (another object's class name).
    """
    if engine in (None, "process", "serial"):
        return engine or "process"
    return "dask" if isinstance(engine, str) or _is_dask_client(engine) else type(engine).__name__


def _resolve_engine(engine, workers):
    """(kind, client, owned) for an engine argument."""
    if engine in (None, "process", "serial"):
        return engine or "process", None, False
    if _is_dask_client(engine):
        return "dask", engine, False
    if isinstance(engine, str) and (engine == "dask" or "://" in engine):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise _dask_missing() from None
        if engine == "dask":
            cluster = LocalCluster(
                n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True, dashboard_address=None
            )
            return "dask", Client(cluster), True
        return "dask", Client(engine), True
    raise FdmlError(
        f"engine must be 'process', 'serial', 'dask', a scheduler address or a dask.distributed.Client, got {engine!r}"
    )


def pool_context():
    """The multiprocessing context of the local pool.

    ``fork`` on Linux while this process has a single thread: no re-import of
    the caller's ``__main__`` (a script without an ``if __name__ ==
    "__main__"`` guard works) and nothing to import in the workers.  With
    other threads alive (a Dask client, a progress bar's monitor) forking is
    unsafe, so ``forkserver`` (fdml preloaded once, cheap forks after); ``spawn``
    where neither exists.

    Returns
    -------
    multiprocessing.context.BaseContext
        The context to make the pool with.
    """
    import multiprocessing as mp
    import threading

    methods = mp.get_all_start_methods()
    if sys.platform.startswith("linux") and "fork" in methods and threading.active_count() == 1:
        return mp.get_context("fork")
    if "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
        return ctx
    return mp.get_context("spawn")


# --- processes: a run ends with its parent --------------------------------------------------------
@contextlib.contextmanager
def signals_end_the_run() -> Iterator[None]:
    """While the block runs, SIGTERM and SIGHUP raise ``SystemExit(128 + signal number)`` here.

    At their default disposition they would kill this process at once and skip
    the ``finally`` blocks that cancel the tasks, end the worker processes,
    close the Dask cluster fdml started and remove temporary files; raising
    runs them, and the exit status is still the shell's 128 + signal number
    (143 for SIGTERM).  SIGINT raises KeyboardInterrupt as Python's own handler
    does (only installed where SIGINT is at its default).  A signal that is
    ignored (SIGHUP under ``nohup``) or has the caller's own handler is left
    alone, so nested runs install nothing.  The first signal puts the previous
    handlers back: a second one during the clean-up kills at once (the workers
    then end by :func:`_die_with_parent`).  Handlers can only be installed from
    the main thread; in any other thread this does nothing.

    Yields
    ------
    None
        Control to the block, with the handlers installed.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous: dict = {}

    def restore() -> None:
        for sig, old in previous.items():
            if signal.getsignal(sig) is handler:  # not a handler someone installed since
                signal.signal(sig, old)

    def handler(signum, frame):
        restore()
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise SystemExit(128 + signum)

    for name in _ENDING_SIGNALS:
        sig = getattr(signal, name, None)
        if sig is not None and signal.getsignal(sig) == signal.SIG_DFL:
            previous[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        restore()


def _die_with_parent(owner: int, start_method: str) -> None:
    """End this worker process when the process that owns its pool ends, even by SIGKILL.

    SIGKILL of the owner runs no clean-up, so the workers must notice on their
    own.  On Linux with ``fork`` or ``spawn`` (the owner is the parent):
    ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (:func:`_kill_with_parent`), chosen
    over a thread that polls :func:`os.getppid` because the kernel delivers it
    at once, even while the worker is deep in a numpy/LAPACK call that holds
    the GIL, and it costs nothing while the worker works.  With
    ``forkserver`` the parent is the forkserver, which exits only when no
    process holds the owner's "alive" pipe, and every worker holds it (to be a
    forkserver client itself): the forkserver outlives the owner and the
    parent-death signal never comes.  There, and where prctl does not exist
    (macOS), a daemon thread blocks on :func:`multiprocessing.parent_process`'s
    sentinel (readable once the owner has ended; no polling) and then ends the
    worker (:func:`_watch_parent`).

    Parameters
    ----------
    owner : int
        Process id of the process that created the pool.
    start_method : str
        Its multiprocessing start method.
    """
    if start_method != "forkserver" and _kill_with_parent(owner):
        return
    _watch_parent()


def _kill_with_parent(owner: int) -> bool:
    """Ask Linux to SIGKILL this process when its parent ends; False where that is not possible.

    The signal follows the *thread* that forked the worker: the pool is
    created and fed by the thread that iterates :func:`execute`, which lives as
    long as the run.
    """
    import ctypes
    import signal

    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        zero = ctypes.c_ulong(0)
        if libc.prctl(_PR_SET_PDEATHSIG, ctypes.c_ulong(signal.SIGKILL), zero, zero, zero) != 0:
            return False
    except (OSError, AttributeError):  # no libc symbol table or no prctl
        return False
    if os.getppid() != owner:  # the owner died before prctl took effect: no signal will come
        os._exit(1)
    return True


def _watch_parent() -> None:
    """A daemon thread that ends this process once the owner's sentinel says it has ended."""
    import multiprocessing
    import multiprocessing.connection
    import threading

    sentinel = getattr(multiprocessing.parent_process(), "sentinel", None)
    if sentinel is None:  # not a multiprocessing child: nothing to watch
        return

    def watch() -> None:
        multiprocessing.connection.wait([sentinel])  # blocks, GIL released, until the owner ends
        os._exit(1)

    threading.Thread(target=watch, name="fdml-parent-watch", daemon=True).start()


def _worker_init(owner: int, start_method: str) -> None:
    """Initializer of a local pool worker: it ends with the process that owns the pool.

    Ctrl-C reaches the whole process group, so SIGINT is ignored here and the
    owner ends the workers itself; SIGTERM and SIGHUP handlers inherited from
    the owner by ``fork`` (those of :func:`signals_end_the_run`) go back to
    the default, which ends the worker; then :func:`_die_with_parent`.  Each worker's BLAS keeps
    one thread (threadpoolctl): the workers already fill the cores, and a multi-threaded BLAS in
    every one of them contends for the same cores (Monte Carlo fits 2-3 times slower, issue 20).
    """
    import signal

    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")
    with contextlib.suppress(ValueError, OSError):  # never break the pool over this
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        for name in ("SIGTERM", "SIGHUP"):
            sig = getattr(signal, name, None)
            if sig is not None and callable(signal.getsignal(sig)):
                signal.signal(sig, signal.SIG_DFL)
    _die_with_parent(owner, start_method)


def _stop_pool(ex) -> None:
    """Cancel the tasks not started and end the worker processes now (a run that did not finish).

    ``shutdown(cancel_futures=True)`` alone lets every worker finish the task it
    runs, minutes for a long fit, and keeps the owner waiting for them at exit.
    Python 3.14 has the public ``terminate_workers()``; before it the worker
    processes are reachable only through the executor's private ``_processes``
    (process id -> :class:`multiprocessing.Process`), read here before
    ``shutdown`` drops it.  A worker still alive :data:`_STOP_GRACE` s after
    SIGTERM is killed.
    """
    procs = list((getattr(ex, "_processes", None) or {}).values())
    terminate = getattr(ex, "terminate_workers", None)
    if terminate is not None:
        terminate()
    else:
        ex.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            with contextlib.suppress(ValueError, OSError):  # closed, or already gone
                p.terminate()
    deadline = time.monotonic() + _STOP_GRACE
    for p in procs:
        with contextlib.suppress(ValueError, OSError):
            p.join(max(0.0, deadline - time.monotonic()))
            if p.exitcode is None:
                p.kill()
                p.join(_STOP_GRACE)


# --- the local process pool -------------------------------------------------------------------------
class _PoolRun:
    """The state of a local pool run across the pools it needs (a dead worker breaks a pool).

    ``suspects`` are the tasks in flight when a pool broke: each is rerun
    alone in a fresh pool, so an innocent task is never blamed; ``deaths``
    counts, per task position, the deaths of a worker running it alone.
    """

    def __init__(self, tasks: Iterable, workers: int):
        self.it = enumerate(tasks)
        self.workers = workers
        self.suspects: deque = deque()
        self.deaths: dict[int, int] = {}
        self.exhausted = False

    def next_task(self, inflight: dict):
        """(position, task, alone) to submit next, or None (window full, suspect waiting, or none left)."""
        if any(alone for _, _, alone in inflight.values()):
            return None
        if self.suspects:
            return None if inflight else (*self.suspects.popleft(), True)  # a suspect runs alone
        if len(inflight) >= 2 * self.workers or self.exhausted:
            return None
        nxt = next(self.it, None)
        self.exhausted = nxt is None
        return None if nxt is None else (*nxt, False)

    def died(self, i: int, task, alone: bool, on_error):
        """The worker running task ``i`` died: its error result, or None when it is to be rerun alone."""
        if alone:
            self.deaths[i] = self.deaths.get(i, 0) + 1
        if self.deaths.get(i, 0) >= _LONE_DEATHS:
            return on_error(task, f"WorkerDied: the worker process died {self.deaths[i]} times running this task alone")
        logger.warning("a worker process died; rerunning task %s on its own", _label(task, i))
        self.suspects.append((i, task))
        return None


def _process_map(fn, tasks, workers: int, on_error) -> Generator[tuple[int, Any], None, None]:
    """Local process pool with a bounded window; survives worker processes that die (:class:`_PoolRun`).

    A dead worker breaks the whole pool, failing every task in flight; the
    pool is replaced and those tasks are rerun one at a time.  A task that
    kills its worker while running alone :data:`_LONE_DEATHS` times yields
    ``on_error``.
    """
    from concurrent.futures import ProcessPoolExecutor

    run = _PoolRun(tasks, workers)
    while True:
        ctx = pool_context()
        ex = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=ctx,
            initializer=_worker_init,
            initargs=(os.getpid(), ctx.get_start_method()),
        )
        state = {"broken": False}
        try:
            yield from _one_pool(ex, fn, run, on_error, state)
        except BaseException:  # a signal, an error, or the caller stopped early: end the workers now
            _stop_pool(ex)
            raise
        ex.shutdown(wait=not state["broken"], cancel_futures=True)
        if not state["broken"]:
            return


def _one_pool(ex, fn, run: _PoolRun, on_error, state: dict) -> Iterator[tuple[int, Any]]:
    """Feed one pool until the tasks run out or it breaks (``state["broken"]``)."""
    from concurrent.futures import FIRST_COMPLETED, wait
    from concurrent.futures.process import BrokenProcessPool

    inflight: dict = {}  # future -> (position, task, ran alone)
    while True:
        while not state["broken"] and (nxt := run.next_task(inflight)) is not None:
            try:
                inflight[ex.submit(fn, nxt[1])] = nxt
            except BrokenProcessPool:
                run.suspects.appendleft(nxt[:2])
                state["broken"] = True
        if not inflight:
            return
        done, _ = wait(inflight, return_when=FIRST_COMPLETED)
        for fut in done:
            i, task, alone = inflight.pop(fut)
            try:
                out = fut.result()
            except BrokenProcessPool:
                state["broken"] = True
                out = run.died(i, task, alone, on_error)
                if out is None:
                    continue
            except Exception as exc:  # the task raised: its error, never the run's
                out = on_error(task, exc)
            yield i, out
        if state["broken"] and not inflight:
            return


# --- Dask -----------------------------------------------------------------------------------------------
def _dask_map(client, fn, tasks, on_error) -> Generator[tuple[int, Any], None, None]:
    try:
        from distributed import as_completed
    except ImportError:  # pragma: no cover - a Client exists, so distributed does
        raise _dask_missing() from None
    nthreads = sum(client.nthreads().values()) or 1
    window = max(4 * nthreads, 16)
    it = enumerate(tasks)
    ac = as_completed()
    pending: dict = {}

    def submit() -> bool:
        nxt = next(it, None)
        if nxt is None:
            return False
        fut = client.submit(fn, nxt[1], pure=False)
        pending[fut.key] = (*nxt, fut)
        ac.add(fut)
        return True

    try:
        for _ in range(window):
            if not submit():
                break
        for fut in ac:
            i, task, _ = pending.pop(fut.key)
            try:
                out = fut.result()
            except Exception as exc:  # KilledWorker after repeated deaths, a lost connection...
                out = on_error(task, exc)
            fut.release()
            yield i, out
            submit()
    finally:
        if pending:  # stopped early: drop what has not run
            client.cancel([f for _, _, f in pending.values()])
