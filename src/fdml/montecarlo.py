"""Monte Carlo studies of the estimator: bias, scatter and efficiency against the Cramer-Rao bound.

:func:`monte_carlo` simulates one manoeuvre of a model with known ("truth")
parameters, adds N independent draws of white measurement noise (run ``i``
uses the stream ``np.random.SeedSequence(seed).spawn(n)[i]``, so any run can
be reproduced alone), fits every noisy record in parallel and returns, per
estimated model parameter,

* ``truth``, ``mean``, ``bias = mean - truth``;
* ``scatter``: the standard deviation of the estimates over the runs;
* ``mean_crb``: the mean of the standard errors the fits reported;
* ``efficiency = scatter / mean_crb``: 1 for an efficient estimator whose
  reported uncertainty is right, above 1 if the fits claim more precision
  than they have.

The tasks run on :func:`fdml.parallel.execute` (process pool, serial, Dask);
each returns one short row, so memory stays flat in N.  The warnings of every
fit are recorded with its run (``warnings``; a study of thousands of fits
shows none on the screen) and counted by category in :meth:`MonteCarloResult.table`.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .batch import ModelSpec, canonical_json, check_fit_kwargs, require_pandas
from .errors import FdmlError
from .jsoncodec import Codec, Fields, Spec, floats, json_text, read_json, texts, to_jsonable
from .parallel import engine_name, execute, one_line
from .record import check_noise
from .warning_log import merged, recording

__all__ = ["monte_carlo", "MonteCarloResult", "load_monte_carlo", "MC_FORMAT"]

#: JSON format identifier and version of a saved study.
MC_FORMAT = ("fdml.MonteCarloResult", 1)

#: Noise-free records simulated in this process, by settings (the same for every run).
_CLEAN_CACHE: dict[str, object] = {}


def _clean_record(task: Mapping):
    key = canonical_json([task["truth"], task["sim"]])
    rec = _CLEAN_CACHE.get(key)
    if rec is None:
        from .simulate import simulate_maneuver

        sim = dict(task["sim"])
        truth = ModelSpec(**task["truth"]).build()
        rec = simulate_maneuver(truth, sim.pop("maneuver"), **sim)
        if len(_CLEAN_CACHE) > 8:
            _CLEAN_CACHE.clear()
        _CLEAN_CACHE[key] = rec
    return rec


def run_trial(task: Mapping) -> dict:
    """One Monte Carlo run: noise draw ``index``, fit, short row (runs in a worker)."""

    from .estimate import fit
    from .record import add_noise

    i = task["index"]
    row = _trial_error(task, "")  # the row of a trial that has not succeeded (yet)
    try:
        rng = np.random.default_rng(np.random.SeedSequence(task["seed"], spawn_key=(i,)))
        noise = task["noise"]
        rec = add_noise(_clean_record(task), noise, rng, relative=not isinstance(noise, Mapping))
        rec = replace(rec, name=f"run{i}")
        model = ModelSpec(**task["fit_model"]).build()
        # records simulated from the model: no adequacy check (fdml.adequacy) unless asked for
        with recording(reemit=False) as log:  # thousands of fits: counted in the result, not shown
            res = fit(rec, model, **{"adequacy": False, **task["fit_kwargs"]})
        p, e = res.params, res.errors
        row.update(
            ok=True,
            warnings=[str(w) for w in merged(log, res.warnings)],
            converged=bool(res.converged),
            iterations=int(res.iterations),
            elapsed=float(res.elapsed),
            values=[p[n] for n in task["names"]],
            stderr=[e[n] for n in task["names"]],
        )
    except Exception as exc:  # one failed run is counted, never fatal
        row["error"] = one_line(exc)
    return row


def _trial_error(task, exc) -> dict:
    return {
        "index": task["index"],
        "ok": False,
        "converged": False,
        "iterations": 0,
        "elapsed": math.nan,
        "values": None,
        "stderr": None,
        "error": exc if isinstance(exc, str) else one_line(exc),
        "warnings": [],
    }


def _nulls(a) -> list:
    """A per-run float array as JSON, a missing value (nan) as null."""
    return to_jsonable(np.asarray(a, float), nonfinite="null")


def _per_run(*shape) -> Spec:
    """A float array, null read as nan, written by :func:`_nulls` (``shape`` as for :func:`fdml.jsoncodec.floats`)."""
    return Spec(floats(*shape, nulls=True).read, write=_nulls)


def _per_run_rows(f, key, done) -> np.ndarray:
    """The estimates or their standard errors, one row per run (``[]`` for a study of no runs)."""
    p = len(done["names"])
    runs = len(done["estimates"]) if "estimates" in done else None  # the standard errors: as many as the estimates
    return np.empty((0, p)) if f.raw(key) == [] and not runs else f.floats(key, (runs, p), nulls=True)


@dataclass(frozen=True)
class MonteCarloResult(Codec):
    """Estimates of N seeded runs and their statistics per parameter.

    Each parameter is the attribute of the same name.

    Parameters
    ----------
    names : tuple of str
        Estimated model parameters.
    truth : ndarray (p,)
        Values that generated the data (nan where the fitted model has a
        parameter the truth model lacks).
    estimates, stderr : ndarray (n, p)
        Per run; nan rows for runs that failed.
    converged : ndarray of bool (n,)
        Whether each run's fit converged.
    iterations : ndarray of int (n,)
        Iterations of each run's fit.
    fit_seconds : ndarray (n,)
        In-process time of each fit, s.
    errors : dict
        Run index -> error of the runs that failed.
    settings : dict
        Models, manoeuvre, noise, seed, fit options, engine.
    wall_time : float
        Seconds for the whole study.
    use_converged_only : bool, optional
        Statistics over converged runs only (default) or over every run that
        returned an estimate.
    units : dict, optional
        Parameter -> unit.
    warnings : dict, optional
        Run index -> the warnings of its fit (``"Category: message"``), for
        every run that warned; :attr:`warning_counts` counts them by category.
    """

    names: tuple
    truth: np.ndarray
    estimates: np.ndarray
    stderr: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    fit_seconds: np.ndarray
    errors: dict
    settings: dict
    wall_time: float
    use_converged_only: bool = True
    units: dict = field(default_factory=dict)
    warnings: dict = field(default_factory=dict)

    json_fields = {
        "names": texts(),
        "truth": _per_run("names"),
        "estimates": Spec(_per_run_rows, write=_nulls),
        "stderr": Spec(_per_run_rows, write=_nulls),
        "converged": Spec(lambda f, k, done: f.flags(k, len(done["estimates"]))),
        "iterations": Spec(lambda f, k, done: f.integers(k, len(done["estimates"]))),
        "fit_seconds": _per_run("estimates"),
        "errors": Spec(lambda f, k, done: _by_run(f, k)),
        "warnings": Spec(lambda f, k, done: {i: tuple(ws) for i, ws in _by_run(f, k).items()}),
    }
    json_source = "fdml Monte Carlo result"
    json_format = MC_FORMAT

    # --- statistics ---------------------------------------------------------------------
    @property
    def n(self) -> int:
        """Runs attempted."""
        return int(self.estimates.shape[0])

    @property
    def used(self) -> np.ndarray:
        """Mask of the runs that enter the statistics."""
        ok = np.all(np.isfinite(self.estimates), axis=1)
        return ok & self.converged if self.use_converged_only else ok

    @property
    def n_used(self) -> int:
        """Runs that enter the statistics."""
        return int(self.used.sum())

    @property
    def mean(self) -> np.ndarray:
        """Mean estimate per parameter over the runs used."""
        return self._over_used(self.estimates, 1, lambda a: a.mean(axis=0))

    @property
    def bias(self) -> np.ndarray:
        """Mean estimate minus truth, per parameter, in its unit."""
        return self.mean - self.truth

    @property
    def scatter(self) -> np.ndarray:
        """Sample standard deviation of the estimates (ddof=1)."""
        return self._over_used(self.estimates, 2, lambda a: a.std(axis=0, ddof=1))

    @property
    def mean_crb(self) -> np.ndarray:
        """Mean reported standard error (Cramer-Rao bound)."""
        return self._over_used(self.stderr, 1, lambda a: a.mean(axis=0))

    def _over_used(self, a: np.ndarray, least: int, stat) -> np.ndarray:
        """``stat`` of the rows of ``a`` the statistics use; nan per parameter with fewer than ``least`` of them."""
        rows = a[self.used]
        return stat(rows) if rows.shape[0] >= least else np.full(a.shape[1], np.nan)

    @property
    def efficiency(self) -> np.ndarray:
        """Scatter / mean CRB per parameter (1 for an efficient estimator with honest error bars)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.scatter / self.mean_crb

    @property
    def bias_z(self) -> np.ndarray:
        """Bias in units of its own standard error, scatter / sqrt(n_used)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.bias / (self.scatter / math.sqrt(max(self.n_used, 1)))

    @property
    def warning_counts(self) -> dict[str, int]:
        """Category -> number of runs whose fit warned with it."""
        from .warning_log import as_recorded

        counts = Counter(cat for ws in self.warnings.values() for cat in {w.category for w in as_recorded(ws)})
        return dict(sorted(counts.items()))

    def stats(self) -> list[dict]:
        """Per parameter: name, truth, mean, bias, scatter, mean_crb, efficiency, bias_z.

        Returns
        -------
        list of dict
            One dict per parameter, in the order of :attr:`names`; values in the parameter's unit.
        """
        cols = {k: getattr(self, k) for k in ("truth", "mean", "bias", "scatter", "mean_crb", "efficiency", "bias_z")}
        return [{"name": n, **{k: float(c[j]) for k, c in cols.items()}} for j, n in enumerate(self.names)]

    # --- presentation -------------------------------------------------------------------------
    def table(self, digits: int = 4) -> str:
        """The statistics as a text table, one line per parameter the fit shares with the truth.

        A parameter of the fitted model that the truth model lacks has no
        truth and no bias; it is named below the table, not tabulated.

        Parameters
        ----------
        digits : int, optional
            Significant digits of the values.

        Returns
        -------
        str
            A heading on the study and one line per shared parameter.
        """
        s = self.settings
        head = (
            f"Monte Carlo: {s.get('truth_kind')} truth, {s.get('fit_kind')} fit, {s.get('maneuver')} "
            f"{s.get('duration'):g} s at {s.get('dt'):g} s, noise {s.get('noise')}, seed {s.get('seed')}\n"
            f"{self.n_used} of {self.n} runs used ({int(self.converged.sum())} converged, "
            f"{len(self.errors)} failed), {self.wall_time:.1f} s wall"
        )
        if self.warnings:
            counts = ", ".join(f"{cat} {k}" for cat, k in self.warning_counts.items())
            head += f"\n{len(self.warnings)} runs warned ({counts}; per run: .warnings)"
        cols = ("parameter", "truth", "mean", "bias", "scatter", "mean CRB", "scatter/CRB", "bias/se")
        rows = [
            [st["name"], *(f"{st[k]:.{digits}g}" for k in ("truth", "mean", "bias", "scatter", "mean_crb"))]
            + [f"{st['efficiency']:.3f}", f"{st['bias_z']:+.2f}"]
            for st in self.stats()
            if math.isfinite(st["truth"])  # a parameter of both models
        ]
        lines = [head]
        if rows:
            widths = [max(len(c), *(len(r[j]) for r in rows)) for j, c in enumerate(cols)]
            lines += [_row(cols, widths), _row(["-" * w for w in widths], widths)] + [_row(r, widths) for r in rows]
        own = [n for n, t in zip(self.names, self.truth) if not math.isfinite(t)]
        if own:
            lines.append(
                f"{'not shown' if rows else 'no parameter shared with the truth model; not shown'}: "
                f"{', '.join(own)} (parameters of the {self.settings.get('fit_kind')} fit that the "
                f"{self.settings.get('truth_kind')} truth does not have, so no truth or bias; their "
                "estimates: .estimates, .stats())"
            )
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def to_frame(self):
        """The statistics as a pandas DataFrame indexed by parameter (pandas is optional).

        Returns
        -------
        pandas.DataFrame
            :meth:`stats`, one row per parameter.
        """
        return require_pandas().DataFrame(self.stats()).set_index("name")

    def plot(self, ax=None):
        """Histogram of the estimates per parameter against N(truth, mean CRB).

        Each panel shows the estimates, the truth, the Gaussian of the mean
        reported CRB about the truth and the Gaussian of the observed mean and
        scatter; the title gives scatter/CRB.  ``ax``: a sequence of at least
        as many axes as parameters (or one Axes for one parameter); default a
        new figure.  Returns ``(figure, axes)``; never calls ``show()``.

        Parameters
        ----------
        ax : matplotlib.axes.Axes or sequence of Axes, optional
            Where to draw, one panel per parameter; default a new figure.

        Returns
        -------
        figure : matplotlib.figure.Figure
            The figure drawn on.
        axes : list of matplotlib.axes.Axes
            One panel per parameter.
        """
        p = len(self.names)
        created = ax is None
        if created:
            import matplotlib.pyplot as plt

            ncol = min(p, 3)
            nrow = math.ceil(p / ncol)
            fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol, 2.8 * nrow), squeeze=False)
            axes = list(axes.ravel())
            for extra in axes[p:]:
                extra.set_visible(False)
        else:
            axes = [ax] if hasattr(ax, "plot") else list(np.ravel(ax))
            if len(axes) < p:
                raise FdmlError(f"plot needs {p} axes (one per parameter), got {len(axes)}")
            fig = axes[0].figure
        est = self.estimates[self.used]
        for j, (name, a) in enumerate(zip(self.names, axes)):
            x = est[:, j]
            a.hist(
                x, bins=max(10, min(50, int(math.sqrt(x.size)))), density=True, alpha=0.5, color="C0", label="estimates"
            )
            lo, hi = np.min(x), np.max(x)
            grid = np.linspace(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), 200)
            for mu, sd, style, label in (
                (self.truth[j], self.mean_crb[j], "C3-", "truth, CRB"),
                (self.mean[j], self.scatter[j], "k--", "mean, scatter"),
            ):
                if math.isfinite(mu) and math.isfinite(sd) and sd > 0:
                    pdf = np.exp(-0.5 * ((grid - mu) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))
                    a.plot(grid, pdf, style, lw=1.2, label=label)
            if math.isfinite(self.truth[j]):
                a.axvline(self.truth[j], color="C3", lw=0.8)
            unit = self.units.get(name, "")
            a.set_xlabel(f"{name} ({unit})" if unit else name)
            a.set_title(f"{name}: scatter/CRB {self.efficiency[j]:.2f}", fontsize=9)
            a.set_yticks([])
        axes[0].legend(fontsize=7)
        if created:
            fig.tight_layout()
        return fig, axes[:p]

    # --- JSON -----------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict (format ``fdml.MonteCarloResult`` version 1); per-run arrays write nan as null.

        Returns
        -------
        dict
            Every field, per-run arrays as lists, then ``stats`` (:meth:`stats`).
        """
        return {**super().to_dict(), "stats": to_jsonable(self.stats())}

    def to_json(self, path: str | Path | None = None, *, inputs=()) -> str:
        """Serialise to JSON text; write it atomically to ``path`` when given (never over ``inputs``).

        Parameters
        ----------
        path : str or Path, optional
            Where to write; None only returns the text.
        inputs : iterable of str or Path, optional
            Files the output must not replace.

        Returns
        -------
        str
            The JSON text.
        """
        return json_text(self.to_dict(), path, inputs=inputs, what="Monte Carlo file")

    @classmethod
    def from_dict(cls, d, *, source: str | None = "fdml Monte Carlo result", **given) -> "MonteCarloResult":
        """Inverse of :meth:`to_dict` (``stats`` is derived, not read).

        A key missing or of the wrong type or shape raises :class:`FdmlError`
        ``"<source>: key '<key>' ..."``.

        Parameters
        ----------
        d : mapping
            A dict as written by :meth:`to_dict`.
        source : str, optional
            What and where, for the messages.
        **given
            Field values the dict does not hold.

        Returns
        -------
        MonteCarloResult
            The study.
        """
        f = Fields(d, cls.json_source if source is None else source)
        fmt = f.raw("format", None)
        if fmt != MC_FORMAT[0]:
            raise f.error(
                "format",
                ("is missing" if fmt is None else f"is {str(fmt)[:40]!r}")
                + f": not an fdml Monte Carlo result ({MC_FORMAT[0]!r})",
            )
        f.version("version", MC_FORMAT[1])
        return cls.from_fields(f, **given)


def _by_run(f, key: str) -> dict:
    """A mapping of run numbers (JSON: strings) to values, read from the study's ``key``."""
    out = {}
    for k, v in f.mapping(key).items():
        if not k.strip().lstrip("-").isdigit():
            raise f.error(key, f"must map run numbers to messages, has the key {k[:40]!r}")
        out[int(k)] = v
    return out


def load_monte_carlo(path: str | Path) -> MonteCarloResult:
    """Read a study saved by :meth:`MonteCarloResult.to_json`.

    Parameters
    ----------
    path : str or Path
        The JSON file.

    Returns
    -------
    MonteCarloResult
        The study.
    """
    path = Path(path)
    return MonteCarloResult.from_dict(read_json(path, what="Monte Carlo file"), source=f"Monte Carlo file {path}")


def _check_noise(noise):
    """The noise level (:func:`fdml.record.check_noise`), refused when it is zero: the runs would all be one."""
    level = check_noise(noise)
    if max(level.values() if isinstance(level, dict) else [level], default=0.0) <= 0:
        raise FdmlError(f"noise must be finite, non-negative and not all zero, got {noise!r}")
    return level


def monte_carlo(
    model,
    truth_values: Mapping[str, float] | None = None,
    n: int = 1000,
    *,
    maneuver: str = "3211",
    duration: float = 10.0,
    dt: float = 0.02,
    amplitude: float | None = None,
    noise=0.03,
    seed: int = 0,
    fit_model=None,
    fit_kwargs: Mapping | None = None,
    engine="process",
    workers: int | None = None,
    progress=None,
) -> MonteCarloResult:
    """Fit N seeded noisy simulations of one manoeuvre; statistics per parameter.

    Parameters
    ----------
    model : Model, ModelSpec or mapping
        The truth model (see :class:`fdml.batch.ModelSpec`).
    truth_values : mapping, optional
        Parameter values of the truth, overriding the model's.
    n : int, optional
        Runs (default 1000).
    maneuver : {"3211", "doublet", "multisine"}, optional
        The elevator manoeuvre (default 3-2-1-1).
    duration, dt : float, optional
        Record length and sample interval, s.
    amplitude : float, optional
        Elevator amplitude, rad (default the generator's).
    noise : float or mapping, optional
        A fraction of each output's RMS (default 0.03), or absolute standard
        deviations ``{"alpha": rad, "q": rad/s, "az": g}``.
    seed : int, optional
        Run ``i`` draws from ``np.random.SeedSequence(seed).spawn(n)[i]``.
    fit_model : Model, ModelSpec or mapping, optional
        The model fitted (default the truth model, started at the truth).
    fit_kwargs : mapping, optional
        Options of :func:`fdml.fit` (plain data).
    engine : {"process", "serial", "dask"}, scheduler address or dask.distributed.Client, optional
        Where the runs go, as in :func:`fdml.batch.run_batch`.
    workers : int, optional
        Local worker processes, as in :func:`fdml.batch.run_batch`.
    progress : None, True or callable, optional
        Progress report, as in :func:`fdml.batch.run_batch`.

    Returns
    -------
    MonteCarloResult
        The estimates of every run and their statistics.
    """
    t_start = time.perf_counter()
    _check_counts(n, seed, workers)
    truth_spec = _truth_spec(model, truth_values)
    truth = truth_spec.build()
    # the fitted model defaults to the truth, started at the truth
    fit_spec = (ModelSpec.from_model(truth) if fit_model is None else ModelSpec.coerce(fit_model)).normalized()
    fmodel = fit_spec.build()
    kw = check_fit_kwargs(fit_kwargs)
    noise = _check_noise(noise)
    names = _reported_names(fmodel, kw)
    tvals = truth.parameters.values
    truth_arr = np.array([tvals.get(nm, math.nan) for nm in names], float)
    sim = _sim_settings(truth, maneuver, duration, dt, amplitude)
    base = {
        "truth": truth_spec.to_dict(),
        "fit_model": fit_spec.to_dict(),
        "sim": sim,
        "noise": noise,
        "seed": int(seed),
        "fit_kwargs": kw,
        "names": names,
    }
    tasks = ({**base, "index": i} for i in range(n))
    rows = execute(
        run_trial,
        tasks,
        engine=engine,
        workers=workers,
        on_error=_trial_error,
        progress=progress,
        total=n,
        desc="fdml montecarlo",
    )
    trials = _collect(rows, n, len(names))
    settings = {
        "truth_kind": truth.kind,
        "fit_kind": fmodel.kind,
        "truth_model": truth_spec.to_dict(),
        "fit_model": fit_spec.to_dict(),
        **sim,
        "noise": noise,
        "noise_relative": not isinstance(noise, Mapping),
        "seed": int(seed),
        "n": int(n),
        "fit_kwargs": kw,
        "engine": engine_name(engine),
        "workers": workers,
    }
    units = {nm: fmodel.parameters[nm].unit for nm in names if nm in fmodel.parameters}
    return MonteCarloResult(
        names=tuple(names),
        truth=truth_arr,
        settings=settings,
        wall_time=time.perf_counter() - t_start,
        units=units,
        **trials,
    )


def _row(cells, widths) -> str:
    """One line of :meth:`MonteCarloResult.table`: the name left-aligned, the numbers right-aligned."""
    return "  ".join(c.rjust(w) if j else c.ljust(w) for j, (c, w) in enumerate(zip(cells, widths)))


def _check_counts(n, seed, workers) -> None:
    if not isinstance(n, (int, np.integer)) or n < 2:
        raise FdmlError(f"n must be an integer >= 2, got {n!r}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise FdmlError(f"seed must be a non-negative integer, got {seed!r}")
    if workers is not None and (not isinstance(workers, (int, np.integer)) or workers < 1):
        raise FdmlError(f"workers must be a positive integer, got {workers!r}")  # as run_batch


def _truth_spec(model, truth_values) -> ModelSpec:
    """The truth model's spec with ``truth_values`` over its own, normalised."""
    spec = ModelSpec.coerce(model)
    if truth_values:
        spec = replace(spec, values={**spec.values, **truth_values})
    return spec.normalized()


def _reported_names(fmodel, kw: dict) -> list:
    """The names the study reports: estimated model parameters, not nuisance terms."""
    pars = fmodel.parameters
    fixed = set(kw.get("fix") or ())
    names = [nm for nm in pars.free_model_names if nm not in fixed]
    names += [nm for nm in (kw.get("free") or ()) if nm not in names and not (nm in pars and pars[nm].role.nuisance)]
    if not names:
        raise FdmlError("the fitted model has no free parameters")
    return names


def _sim_settings(truth, maneuver, duration, dt, amplitude) -> dict[str, Any]:
    """The simulation's settings, checked by one clean simulation here: bad settings fail once, not n times."""
    sim: dict[str, Any] = {"maneuver": maneuver, "duration": float(duration), "dt": float(dt)}
    if amplitude is not None:
        sim["amplitude"] = float(amplitude)
    from .simulate import simulate_maneuver

    simulate_maneuver(truth, maneuver, **{k: v for k, v in sim.items() if k != "maneuver"})
    return sim


def _collect(rows, n: int, p: int) -> dict:
    """The trials' rows as the result's arrays (a failed trial leaves NaN and its error)."""
    # the result's field -> (the row's key, the array over runs)
    arrays = {
        "estimates": ("values", np.full((n, p), math.nan)),
        "stderr": ("stderr", np.full((n, p), math.nan)),
        "converged": ("converged", np.zeros(n, bool)),
        "iterations": ("iterations", np.zeros(n, int)),
        "fit_seconds": ("elapsed", np.full(n, math.nan)),
    }
    errors: dict[int, str] = {}
    warned: dict[int, tuple] = {}
    with contextlib.closing(rows):  # at once on any exception (a signal included): the workers end with the run
        for row in rows:
            i = row["index"]
            if row["ok"]:
                for key, a in arrays.values():
                    a[i] = row[key]
            else:
                errors[i] = row["error"]
            if row.get("warnings"):
                warned[i] = tuple(row["warnings"])
    return {**{name: a for name, (_, a) in arrays.items()}, "errors": errors, "warnings": warned}
