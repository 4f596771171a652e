"""Progress: callbacks for :func:`fdml.fit` (``callback=``) and for runs of many tasks.

:func:`fdml.fit` calls ``callback(info)`` after every iteration with an
:class:`~fdml.results.IterationInfo` (iteration, cost J = det R, params,
step_in_stderr); a callback that returns True stops the fit cleanly (the
result has ``stopped=True`` and says so in its message).  This module has
ready-made callbacks and a way to combine them:

========================  ============================================================
:class:`TqdmProgress`     a tqdm bar (optional extra ``progress``)
:class:`PrintProgress`    one line per iteration on a stream (stderr by default)
:class:`HistoryRecorder`  keeps every IterationInfo (cost and parameter paths)
:class:`StopAfter`        stops after N iterations, a time limit, or once the
                          step falls below a size
:func:`chain`             several callbacks as one (stops if any asks to)
========================  ============================================================

Runs of many tasks (:func:`fdml.parallel.execute`: a batch, a Monte Carlo
study, the diagnosis validation) report their progress through
:func:`task_progress`: a tqdm bar, or the caller's ``progress(done, total,
result)`` once per finished task.

One callback object can serve many fits (a Monte Carlo, several manoeuvres):
:class:`HistoryRecorder` and :class:`StopAfter` start afresh whenever the
iteration counter restarts at 1; :class:`TqdmProgress` counts every iteration
of every fit on one bar unless ``reset_each_fit=True``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np

__all__ = ["TqdmProgress", "PrintProgress", "HistoryRecorder", "StopAfter", "chain", "tqdm_available", "task_progress"]


def tqdm_available() -> bool:
    """True if tqdm (the ``progress`` extra) can be imported.

    Returns
    -------
    bool
        Whether ``import tqdm`` works.
    """
    try:
        import tqdm  # noqa: F401
    except ImportError:
        return False
    return True


def task_progress(progress, total: int | None, desc: str):
    """``(update(result, done), close())`` for the ``progress`` argument of a run of many tasks.

    Parameters
    ----------
    progress : None, False, True or callable
        None/False: nothing; True: a tqdm bar of ``total`` tasks (the
        ``progress`` extra); a callable is called as ``progress(done, total,
        result)`` after every task.
    total : int or None
        Number of tasks.
    desc : str
        Label of the bar.

    Returns
    -------
    update : callable
        ``update(result, done)``, to call after each task with its result and
        the number of tasks done.
    close : callable
        ``close()``, to call once at the end.

    Raises
    ------
    FdmlError
        ``progress`` is none of these, or tqdm is missing.
    """
    from .errors import FdmlError

    if progress is None or progress is False:
        return (lambda result, done: None), (lambda: None)
    if progress is True or progress == "tqdm":
        try:
            from tqdm.auto import tqdm
        except ImportError:
            raise FdmlError("progress=True needs tqdm: pip install 'fdml[progress]'") from None
        bar = tqdm(total=total, desc=desc, unit="task")
        return (lambda result, done: bar.update(1)), bar.close
    if callable(progress):
        return (lambda result, done: progress(done, total, result)), (lambda: None)
    raise FdmlError(f"progress must be None, True or a callable(done, total, result), got {progress!r}")


class TqdmProgress:
    """A tqdm progress bar over fit iterations, with the cost and step as postfix.

    Parameters
    ----------
    total : int, optional
        Expected iterations (e.g. ``max_iter``, or fits x iterations); None
        shows a counter without a bar.
    desc : str, optional
        Bar label.
    file : file-like, optional
        Where the bar is drawn (default stderr).
    leave : bool, optional
        Keep the bar after :meth:`close`.
    reset_each_fit : bool, optional
        Restart the bar when a new fit starts (iteration 1).
    disable : bool, optional
        Draw nothing (tqdm's own switch).

    Raises
    ------
    ImportError
        tqdm is missing (``pip install 'fdml[progress]'``).

    Examples
    --------
    >>> with TqdmProgress(desc="fit") as bar:          # doctest: +SKIP
    ...     res = fdml.fit(rec, model, callback=bar)
    """

    def __init__(
        self,
        total: int | None = None,
        *,
        desc: str = "fdml fit",
        file=None,
        leave: bool = True,
        reset_each_fit: bool = False,
        disable: bool = False,
    ):
        try:
            from tqdm.auto import tqdm
        except ImportError:
            raise ImportError(
                "TqdmProgress needs tqdm; install the optional extra: pip install 'fdml[progress]'"
            ) from None
        self.reset_each_fit = reset_each_fit
        stream = file if file is not None else sys.stderr
        self.bar = tqdm(total=total, desc=desc, file=stream, leave=leave, unit="it", disable=disable)

    def __call__(self, info) -> None:
        if self.reset_each_fit and info.iteration == 1 and self.bar.n:
            self.bar.reset()
        self.bar.set_postfix(cost=f"{info.cost:.4g}", step=f"{info.step_in_stderr:.3g} se", refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        """Close the bar after drawing its final count.

        tqdm redraws at most every 0.1 s, so without this last drawing a fast
        fit's bar would end on the count of its first iteration ("1it").
        """
        if not self.bar.disable:
            self.bar.refresh()
        self.bar.close()

    def __enter__(self) -> "TqdmProgress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class PrintProgress:
    """One line per iteration: iteration, cost, largest step in standard errors.

    Parameters
    ----------
    file : file-like, optional
        Default ``sys.stderr`` (looked up at each call).
    every : int, optional
        Print every ``every``-th iteration (default 1).
    """

    def __init__(self, file=None, every: int = 1):
        if int(every) != every or every < 1:
            raise ValueError(f"every must be a positive integer, got {every!r}")
        self.file = file
        self.every = int(every)

    def __call__(self, info) -> None:
        if info.iteration % self.every == 0:
            out = self.file if self.file is not None else sys.stderr
            out.write(
                f"iteration {info.iteration:3d}  J = det R = {info.cost:.6g}  "
                f"largest step {info.step_in_stderr:.3g} standard errors\n"
            )


class HistoryRecorder:
    """Keeps the :class:`~fdml.results.IterationInfo` of every iteration.

    Attributes
    ----------
    history : list of IterationInfo
        Of the current (last) fit.
    fits : list of list of IterationInfo
        Of every fit seen, in order (a new one starts at iteration 1).
    """

    def __init__(self):
        self.fits: list[list] = []

    @property
    def history(self) -> list:
        """The iterations of the latest fit (empty before the first)."""
        return self.fits[-1] if self.fits else []

    def __call__(self, info) -> None:
        if info.iteration == 1 or not self.fits:
            self.fits.append([])
        self.fits[-1].append(info)

    @property
    def costs(self) -> np.ndarray:
        """J = det R after each iteration of the last fit."""
        return np.array([h.cost for h in self.history], float)

    @property
    def steps(self) -> np.ndarray:
        """Largest step (in standard errors) of each iteration of the last fit."""
        return np.array([h.step_in_stderr for h in self.history], float)

    def path(self, name: str) -> np.ndarray:
        """Estimate of ``name`` after each iteration of the last fit.

        Parameters
        ----------
        name : str
            A parameter estimated in the recorded fit.

        Returns
        -------
        numpy.ndarray
            Its value after each iteration, shape ``(n_iterations,)``, in the
            parameter's own units.
        """
        try:
            return np.array([h.params[name] for h in self.history], float)
        except KeyError:
            raise KeyError(f"{name!r} was not estimated in the recorded fit") from None


class StopAfter:
    """Stop a fit cleanly after some iterations, some seconds, or once steps are small.

    Parameters
    ----------
    iterations : int, optional
        Stop after this many iterations.
    seconds : float, optional
        Stop at the first iteration that ends later than this after the fit's
        first iteration started being counted (the clock starts when the
        callback first sees iteration 1).
    step_below : float, optional
        Stop once the largest step is below this many standard errors (a
        looser convergence test than the fit's own).
    clock : callable, optional
        Time source in seconds (default ``time.monotonic``; for tests).

    Attributes
    ----------
    reason : str or None
        Why the last fit was stopped (None if it was not).
    """

    def __init__(
        self,
        iterations: int | None = None,
        *,
        seconds: float | None = None,
        step_below: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ):
        if iterations is None and seconds is None and step_below is None:
            raise ValueError("StopAfter needs iterations, seconds or step_below")
        if iterations is not None and (int(iterations) != iterations or iterations < 1):
            raise ValueError(f"iterations must be a positive integer, got {iterations!r}")
        if seconds is not None and not seconds > 0:
            raise ValueError(f"seconds must be > 0, got {seconds!r}")
        self.iterations = iterations
        self.seconds = seconds
        self.step_below = step_below
        self._clock = clock
        self._t0: float | None = None
        self.reason: str | None = None

    def __call__(self, info) -> bool:
        if info.iteration == 1 or self._t0 is None:
            self._t0 = self._clock()
            self.reason = None
        if self.iterations is not None and info.iteration >= self.iterations:
            self.reason = f"iteration limit {self.iterations}"
        elif self.seconds is not None and self._clock() - self._t0 >= self.seconds:
            self.reason = f"time limit {self.seconds:g} s"
        elif self.step_below is not None and info.step_in_stderr < self.step_below:
            self.reason = f"step below {self.step_below:g} standard errors"
        return self.reason is not None


def chain(*callbacks):
    """Combine callbacks: each is called every iteration; the fit stops if any returns True.

    None entries are skipped, so ``chain(bar if show else None, stopper)`` works.

    Parameters
    ----------
    *callbacks : callable or None
        Iteration callbacks ``callback(info) -> bool or None``.

    Returns
    -------
    callable
        ``combined(info) -> bool``, which calls them all; its ``callbacks``
        attribute holds them.
    """
    cbs = [c for c in callbacks if c is not None]
    for c in cbs:
        if not callable(c):
            raise TypeError(f"callbacks must be callable, got {type(c).__name__}")

    def combined(info) -> bool:
        return any([c(info) for c in cbs])  # a list, not a generator: every callback is called

    combined.callbacks = tuple(cbs)
    return combined
