"""Fit many records: one result file per record, a combined table, resumable, parallel.

:func:`run_batch` fits one model to every record (or manoeuvre window within
a record) of a folder, a glob or a list, each on its own, and writes

``OUT/results/KEY.json``
    the full :class:`~fdml.results.FitResult` (readable with
    :func:`fdml.load_result`) plus a ``batch`` block: the source, the window,
    the hash of the inputs and the table row;
``OUT/results/KEY.error.json``
    instead, for a record that failed: its error (type and one-line message);
``OUT/table.csv``, ``OUT/table.json``
    one row per record, in source order: estimates, standard errors, cost,
    convergence, iterations, fit time, error, warnings.

Every file is written under a temporary name and renamed into place, so no
result file is ever half-written.  A result file whose input hash (record
file bytes, window, model specification, fit options, fdml version) matches
is reused, so an interrupted batch resumes without refitting what finished.
Workers write their result and return only a short row, which the parent
appends to a spool file; it keeps the list of sources and a file offset per
record, so peak memory stays flat in the number of records.

Engines (:mod:`fdml.parallel`, the one engine of fdml): ``"process"`` (a
local process pool, default), ``"serial"`` (in this process) or a
``dask.distributed.Client`` (optional ``dask`` extra; the record paths and
``OUT`` must then be visible to every worker, e.g. on a shared file system).
The warnings of every fit are kept, with their category, in its row (column
``warnings``) and result file, and counted in :class:`BatchSummary`; the
workers print none.  A task is idempotent: run twice (Dask
reruns a task whose worker died), it writes the same file by the same atomic
rename, so every record ends with exactly one result file and one row.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import glob
import hashlib
import logging
import math
import os
import re
import time
from collections import Counter
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

from .errors import FdmlError
from .jsoncodec import Codec, Spec, integer, mapping, number_map, renamed, texts
from .jsoncodec import dumps as _dumps
from .jsoncodec import loads as _loads
from .outputs import atomic_open, atomic_write_text
from .parallel import engine_name, execute, one_line
from .parallel import signals_end_the_run as _signals_end_the_run
from .warning_log import RecordedWarning, merged, recording

__all__ = [
    "run_batch",
    "BatchSummary",
    "ModelSpec",
    "collect_sources",
    "load_source",
    "BatchItem",
    "TABLE_FORMAT",
    "check_fit_kwargs",
    "canonical_json",
]

logger = logging.getLogger(__name__)

#: JSON format identifier and version of the combined table.
TABLE_FORMAT = ("fdml.BatchTable", 1)
#: Identifier of the error file written for a record that failed.
ERROR_FORMAT = ("fdml.BatchError", 1)
#: File endings picked up when a source is a folder.
RECORD_SUFFIXES = (".csv", ".mat", ".asc", ".dat")
_GLOB_CHARS = re.compile(r"[*?\[]")


# --- the model specification ----------------------------------------------------------------
def _aircraft_field(f, key: str, done: dict):
    """A model spec's aircraft: a preset name, a file, an aircraft object or null."""
    ac = f.raw(key)
    if ac is not None and not isinstance(ac, (str, Mapping)):
        raise f.error(key, "must be a preset name, a file or an aircraft object")
    return f.mapping(key) if isinstance(ac, Mapping) else ac


def _fix_field(f, key: str, done: dict):
    """Parameters to fix: ``{name: value}`` or a list of names."""
    return f.number_map(key) if isinstance(f.raw(key), Mapping) else list(f.strings(key))


def _parameters_field(f, key: str, done: dict):
    """A whole parameter set (a list of parameter objects) or null."""
    return None if f.raw(key) is None else [dict(p.doc) for p in f.items(key)]


@dataclass(frozen=True)
class ModelSpec(Codec):
    """A picklable description of a model, rebuilt in every worker.

    Parameters
    ----------
    kind : {"unsteady", "steady", "derivatives", "dimensional"}
        The model kind (:func:`fdml.make_model`).
    aircraft : str or mapping, optional
        Preset name, aircraft JSON file or aircraft dict (as
        :meth:`fdml.Aircraft.to_dict`).  :meth:`normalized` turns names and
        files into the dict, so workers need no access to the file and the
        input hash changes when the aircraft does.
    options : mapping, optional
        Model options (``gust``, ``airspeed``, ...; see :func:`fdml.make_model`).  A
        dimensional spec with neither ``airspeed`` nor an aircraft takes each record's
        mean airspeed, m/s (the model rule of ``fdml fit``; :meth:`build`).
    values : mapping, optional
        Parameter values (the fit's starting point).
    fix : mapping or sequence of str, optional
        Parameters to fix (a mapping also sets their values).
    free : sequence of str, optional
        Parameters to free.
    parameters : list of dict, optional
        A whole parameter set (:meth:`fdml.Parameters.to_list`), as
        :meth:`from_model` stores it; applied before ``values``, ``fix``, ``free``.
    effects : sequence of str, optional
        Effects made part of the model (``"time_delay@alpha"``; see
        :func:`fdml.make_model`), in order.
    """

    kind: str
    aircraft: str | Mapping | None = None
    options: Mapping = field(default_factory=dict)
    values: Mapping = field(default_factory=dict)
    fix: Mapping | Sequence = ()
    free: Sequence = ()
    parameters: Sequence | None = None
    effects: Sequence = ()

    json_fields = {
        "aircraft": Spec(_aircraft_field),
        "options": mapping(),
        "values": number_map(),
        "fix": Spec(_fix_field),
        "free": texts(),
        "parameters": Spec(_parameters_field),
        "effects": texts(),
    }
    json_source = "model spec"

    @classmethod
    def from_model(cls, model) -> "ModelSpec":
        """The specification of an existing :class:`~fdml.models.Model` (parameters included).

        Parameters
        ----------
        model : Model
            The model.

        Returns
        -------
        ModelSpec
            Its specification.
        """
        from .models import model_to_dict

        d = model_to_dict(model)
        return cls(
            **{k: d[k] for k in ("kind", "aircraft", "options", "parameters")}, effects=tuple(d.get("effects", ()))
        )

    @classmethod
    def coerce(cls, spec) -> "ModelSpec":
        """A ModelSpec from a ModelSpec, a mapping with its fields, or a Model.

        Parameters
        ----------
        spec : ModelSpec, mapping or Model
            The specification.

        Returns
        -------
        ModelSpec
            The specification (``spec`` itself when it is one).
        """
        if isinstance(spec, cls):
            return spec
        if isinstance(spec, Mapping):
            known = [f.name for f in fields(cls)]
            unknown = set(spec) - set(known)
            if unknown:
                raise FdmlError(f"model spec: unknown key(s) {sorted(unknown)}; known: {', '.join(known)}")
            if "kind" not in spec:
                raise FdmlError("model spec: 'kind' is required (unsteady, steady, derivatives, dimensional)")
            return cls(**spec)
        from .models import Model

        if isinstance(spec, Model):
            return cls.from_model(spec)
        raise FdmlError(f"model spec must be a ModelSpec, a mapping or a Model, got {type(spec).__name__}")

    def normalized(self) -> "ModelSpec":
        """Aircraft resolved to its dict, containers made plain (JSON-ready, stable hash).

        Returns
        -------
        ModelSpec
            The normalised copy.
        """
        ac = self.aircraft
        if ac is not None:
            from .aircraft import Aircraft, load_aircraft

            ac = Aircraft.from_dict(ac).to_dict() if isinstance(ac, Mapping) else load_aircraft(ac).to_dict()
        from .parameters import as_names, check_fix_free, fixed_values

        check_fix_free(self.fix, self.free)  # a str is one name; both fixed and freed is an error
        return ModelSpec(
            kind=str(self.kind),
            aircraft=ac,
            options=dict(self.options),
            values={str(k): float(v) for k, v in self.values.items()},
            fix=fixed_values(self.fix),
            free=as_names(self.free, "free"),
            parameters=None if self.parameters is None else [dict(p) for p in self.parameters],
            effects=_effect_keys(self.effects),
        )

    @property
    def airspeed_from_records(self) -> bool:
        """True when the model takes the records' mean airspeed: dimensional, without an aircraft or an airspeed.

        The model rule of ``fdml fit`` (:func:`fdml.conditions.airspeed_rule`): such a spec is
        built per record, with the airspeed that record carries.
        """
        return (
            self.parameters is None
            and self.kind == "dimensional"
            and self.aircraft is None
            and ("airspeed" not in self.options)
        )

    def check(self) -> None:
        """Build the model once, to refuse a bad spec (unknown effect, parameter or option) before any work.

        A spec whose airspeed comes from each record is built at a nominal
        airspeed (1 m/s), on which no name, effect or option depends.
        """
        (replace(self, options={**self.options, "airspeed": 1.0}) if self.airspeed_from_records else self).build()

    def build(self, records=None):
        """The :class:`~fdml.models.Model` described.

        Parameters
        ----------
        records : sequence of Record, optional
            The records the model is fitted to; a spec whose airspeed comes from
            the records (:attr:`airspeed_from_records`) takes their mean airspeed (m/s).

        Returns
        -------
        Model
            The model, its values, fixed and free parameters applied.
        """
        from .aircraft import Aircraft, aircraft_for_lags
        from .models import make_model
        from .parameters import Parameters

        ac = self.aircraft
        if isinstance(ac, Mapping):
            ac = Aircraft.from_dict(ac, origin="model spec")
        if self.kind == "unsteady" and ac is not None:  # lag constants by values, fix or free count as given
            given = {**self.values, **(self.fix if isinstance(self.fix, Mapping) else {})}
            ac = aircraft_for_lags(ac, self.free, given, source="the model spec's values or fix")
        model = make_model(self.kind, ac, **self._options_for(records))
        from .models.effects import assemble, with_effects

        if self.parameters is not None:  # a saved model: its base kind plus its effects, as model_to_dict
            model = assemble(model, self.effects).with_parameters(Parameters.from_list(self.parameters))
        elif self.effects:
            model = with_effects(model, list(self.effects))
        if self.values:
            model.parameters.check_names(self.values)
            model = model.with_values(self.values)
        if self.fix:
            model.parameters.check_names(self.fix)
            model = model.fix(self.fix)
        if self.free:
            model.parameters.check_names(self.free)
            model = model.with_parameters(model.parameters.free(self.free))
        return model

    def _options_for(self, records) -> dict:
        """The model options, with the records' mean airspeed where the spec takes it from them."""
        options = dict(self.options)
        if self.airspeed_from_records:
            from .conditions import record_airspeed

            U = record_airspeed(records or ())
            if U is None:
                names = ", ".join(str(getattr(r, "name", r)) for r in records or ()) or "no record given"
                raise FdmlError(
                    f"the dimensional model needs an airspeed and the record carries none ({names}): "
                    "give --airspeed U (m/s) or --aircraft"
                )
            options["airspeed"] = U
        return options

    def provenance(self, model, records) -> dict:
        """The provenance of a fit of ``model`` (built by :meth:`build`) to ``records``.

        Parameters
        ----------
        model : Model
            The model built from this spec.
        records : sequence of Record
            The records fitted.

        Returns
        -------
        dict
            As :func:`fdml.conditions.model_provenance`; the airspeed's source is
            ``"given"`` (the spec's options), ``"aircraft"`` or ``"record"``.
        """
        from .conditions import airspeed_rule, model_provenance

        _, source = airspeed_rule(self.kind, self.aircraft, self.options.get("airspeed"), records)
        return model_provenance(self.kind, "model spec", model, source, records)


def _effect_keys(effects) -> list:
    """Effect names as canonical ``name@channel`` keys (a stable hash; an unknown name fails here)."""
    from .errors import ParameterError
    from .models.effects import resolve_effect

    if isinstance(effects, str):
        effects = [effects]
    out = []
    for e in effects:
        try:
            out.append(resolve_effect(e).key)
        except ParameterError:  # NAME alone with several variants: resolved against the model in build()
            out.append(str(e).strip())
    return out


# --- sources --------------------------------------------------------------------------------
@dataclass(frozen=True)
class BatchItem:
    """One unit of work: a record file, optionally a window [t0, t1] s within it.

    ``key`` names its result file and its table row; it is unique in a batch.

    Parameters
    ----------
    path : str
        The record file.
    t0, t1 : float or None, optional
        Start and end of the window, s; None for the record's own.
    key : str, optional
        The item's unique name in the batch.
    """

    path: str
    t0: float | None = None
    t1: float | None = None
    key: str = ""


def _is_window(x) -> bool:
    return (
        isinstance(x, tuple)
        and len(x) in (3, 4)
        and isinstance(x[0], (str, os.PathLike))
        and all(v is None or isinstance(v, (int, float)) for v in x[1:3])
    )


def _expand(src) -> list[tuple[str, float | None, float | None, str | None]]:
    if _is_window(src):
        t0, t1 = (None if v is None else float(v) for v in src[1:3])
        name = str(src[3]) if len(src) == 4 and src[3] is not None else None
        return [(str(Path(src[0]).absolute()), t0, t1, name)]
    if isinstance(src, BatchItem):
        return [(str(Path(src.path).absolute()), src.t0, src.t1, src.key or None)]
    if not isinstance(src, (str, os.PathLike)):
        raise FdmlError(f"batch source must be a path, a glob or (path, t0, t1), got {src!r}")
    p = Path(src)
    if p.is_dir():
        files = sorted(
            f for f in p.iterdir() if f.is_file() and f.suffix.lower() in RECORD_SUFFIXES and not f.name.startswith(".")
        )
        if not files:
            raise FdmlError(f"folder {p} holds no records ({', '.join(RECORD_SUFFIXES)})")
    elif not p.exists() and _GLOB_CHARS.search(str(src)):
        files = [Path(f) for f in sorted(glob.glob(str(src), recursive=True)) if Path(f).is_file()]
        if not files:
            raise FdmlError(f"no records match {src}")
    else:  # a single file; a missing one becomes an error row, like any other bad record
        files = [p]
    return [(str(f.absolute()), None, None, None) for f in files]


def collect_sources(sources) -> list[BatchItem]:
    """Expand ``sources`` into batch items with unique keys, in order.

    Parameters
    ----------
    sources : path, glob, (path, t0, t1) or a list of them
        A folder (its ``*.csv``, ``*.mat``, ``*.asc``, ``*.dat`` files, sorted), a glob
        pattern, a record file, or a manoeuvre window ``(path, t0, t1)`` (s;
        None for an open end), optionally ``(path, t0, t1, name)``.

    Returns
    -------
    list of BatchItem
        Keys are the file stem, with ``@T0-T1`` for a window; names that
        collide get a short hash of their path.  A record listed twice (same
        file and window) is kept once.
    """
    if isinstance(sources, (str, os.PathLike, BatchItem)) or _is_window(sources):
        sources = [sources]
    entries: dict[tuple, str | None] = {}  # (path, t0, t1) -> the name given, if any
    for src in sources:
        for path, t0, t1, name in _expand(src):
            entries.setdefault((path, t0, t1), name)  # a record named twice (a folder and a glob) is fitted once
    if not entries:
        raise FdmlError("no records to fit")
    keys = []
    for (path, t0, t1), name in entries.items():
        if name is None:
            name = Path(path).stem
            if t0 is not None or t1 is not None:
                name += f"@{'' if t0 is None else f'{t0:g}'}-{'' if t1 is None else f'{t1:g}'}"
        keys.append(re.sub(r"[^A-Za-z0-9._@+-]", "_", name).lstrip(".") or "record")  # a safe file name
    count = Counter(keys)
    items = []
    for (path, t0, t1), k in zip(entries, keys):
        if count[k] > 1:
            k = f"{k}-{hashlib.sha1(f'{path}|{t0}|{t1}'.encode()).hexdigest()[:8]}"
        items.append(BatchItem(path, t0, t1, k))
    return items


def load_source(path, t0: float | None = None, t1: float | None = None, *, name: str | None = None, **read):
    """Read one record file (and cut a window): the one place the batch reads records.

    Uses :func:`fdml.io.load_record` (any supported format; ``read`` are its
    options: ``format``, ``columns``, ``units``, ``sign``, ``layout``).

    Parameters
    ----------
    path : str or Path
        The record file.
    t0, t1 : float, optional
        Start and end of the window, s.
    name : str, optional
        The record's name (default the loader's).
    **read
        Options of :func:`fdml.io.load_record`.

    Returns
    -------
    Record
        The record (cut to the window).
    """
    from .io import load_record

    rec = load_record(path, t0=t0, t1=t1, **read)
    return replace(rec, name=name) if name else rec


# --- hashing --------------------------------------------------------------------------------
def canonical_json(obj) -> str:
    """Stable JSON text of plain data (numbers, strings, lists, dicts): what input hashes are of.

    Parameters
    ----------
    obj : object
        Plain data.

    Returns
    -------
    str
        Compact JSON with sorted keys.

    Raises
    ------
    FdmlError
        ``obj`` holds something else (options must be shipped to workers and hashed).
    """
    try:
        return _dumps(obj, compact=True, sort_keys=True, default=None)
    except TypeError as exc:
        raise FdmlError(f"batch options must be plain data (numbers, strings, lists, dicts); {exc}") from None


def check_fit_kwargs(fit_kwargs: Mapping | None) -> dict:
    """``fit_kwargs`` as a dict of :func:`fdml.fit` options, checked once before any task runs.

    Parameters
    ----------
    fit_kwargs : mapping or None
        Options of :func:`fdml.fit` (the fields of :class:`fdml.fit_options.FitOptions`).

    Returns
    -------
    dict
        The options (empty for None).

    Raises
    ------
    FdmlError
        An unknown option, a bad value (a bad band among them), or a value that is not plain data.
    """
    from .fit_options import FitOptions

    kw = dict(fit_kwargs or {})
    canonical_json(kw)  # plain data only: it is shipped to workers
    FitOptions.of(**kw)  # every option checked: a bad one would fail every task
    return kw


def _fit_options_key(fit_kwargs: Mapping) -> dict:
    """What the input hash holds of the fit's options: all of them, as :class:`~fdml.fit_options.FitOptions` has them.

    Two spellings of the same options (``band="0.2:8"`` and ``band=[0.2, 8, 0.1]``, a default given
    or left out) hash the same.

    Parameters
    ----------
    fit_kwargs : mapping
        Checked options (:func:`check_fit_kwargs`).

    Returns
    -------
    dict
        Plain data.
    """
    from .fit_options import FitOptions

    return FitOptions.of(**fit_kwargs).to_dict()


# --- the task (runs in a worker) ------------------------------------------------------------
def _num(x: float):
    x = float(x)
    return x if math.isfinite(x) else str(x)


def _base_row(task: Mapping) -> dict:
    """The row of a task that has not succeeded (yet): its table columns, in order, then its estimates."""
    row = {"index": task["index"], **dict.fromkeys(_FIXED_COLUMNS), "params": {}, "stderr": {}}
    row.update(key=task["key"], source=task["path"], t0=task["t0"], t1=task["t1"], status="error", reused=False)
    row.update(error="", warnings=[], findings="", result_file="")
    return row


def error_row(task: Mapping, exc: BaseException | str) -> dict:
    """The table row of a record that failed with ``exc``."""
    return {**_base_row(task), "error": exc if isinstance(exc, str) else one_line(exc)}


def _reusable(path: Path, input_hash: str) -> dict | None:
    try:
        d = _loads(path.read_text())
    except (OSError, ValueError):
        return None
    b = d.get("batch") if isinstance(d, dict) else None
    if not isinstance(b, dict) or b.get("input_hash") != input_hash or not isinstance(b.get("row"), dict):
        return None
    return b["row"]


def run_task(task: Mapping) -> dict:
    """Fit one batch item and write its result file; return its table row.

    Never raises for a bad record: the error goes into the row (and an
    ``.error.json`` file).  Idempotent: a rerun writes the same file name by
    an atomic rename.
    """
    from . import __version__

    t_start = time.perf_counter()
    res_path, err_path = (Path(task["out_dir"]) / "results" / f"{task['key']}{end}" for end in (".json", ".error.json"))
    row = _base_row(task)
    key = {"t0": task["t0"], "t1": task["t1"], "spec": task["spec"], "fit": task["fit_key"], "fdml": __version__}
    if task.get("read"):  # absent when empty: the hash of a batch without reading options is unchanged
        key["read"] = task["read"]
    try:
        with open(task["path"], "rb") as fh:
            file_hash = hashlib.file_digest(fh, "sha256").hexdigest()
        input_hash = hashlib.sha256((file_hash + canonical_json(key)).encode()).hexdigest()
    except OSError as exc:
        from .errors import RecordError

        msg = (
            f"record file {task['path']} does not exist"
            if isinstance(exc, FileNotFoundError)
            else f"cannot read record file {task['path']}: {exc.strerror or exc}"
        )
        return _write_error(task, row, RecordError(msg), err_path, res_path, None)
    if task["resume"]:
        old = _reusable(res_path, input_hash)
        if old is not None:
            err_path.unlink(missing_ok=True)
            return {**old, **{k: row[k] for k in ("index", "key", "source", "t0", "t1")}, "reused": True}
    try:
        from .conditions import attach_conditions
        from .estimate import fit

        rec = load_source(task["path"], task["t0"], task["t1"], name=task["key"], **task.get("read", {}))
        spec = ModelSpec(**task["spec"])
        model = spec.build([rec])  # the model rule of fdml fit: the record's own airspeed where the spec has none
        with recording(reemit=False) as log:  # a worker shows nothing: the row and the result keep them
            res = fit(rec, model, **task["fit_kwargs"])
            res = attach_conditions(res, model, [rec], spec.provenance(model, [rec]))
        row.update(
            status="ok",
            converged=bool(res.converged),
            iterations=int(res.iterations),
            cost=_num(res.cost),
            elapsed=float(res.elapsed),
            n_freq=int(res.n_freq),
            warnings=[w.to_dict() for w in merged(log, res.warnings)],
            findings=" ".join(f.code for f in res.findings),
            result_file=str(Path("results") / res_path.name),
            params={n: float(v) for n, v in zip(res.names, res.values)},
            stderr={n: _num(s) for n, s in zip(res.names, res.stderr)},
        )
        d = res.to_dict()
        del res, rec
        row["task_seconds"] = time.perf_counter() - t_start
        block = _task_block(task, input_hash, spec=task["spec"], fit_kwargs=task["fit_kwargs"], row=row)
        d["batch"] = {"format": TABLE_FORMAT[0], **block}
        text = _dumps(d, compact=True)
        del d
        atomic_write_text(res_path, text)
        err_path.unlink(missing_ok=True)
        return row
    except Exception as exc:  # any failure of this record stays with this record
        return _write_error(task, row, exc, err_path, res_path, input_hash, t_start)


def _task_block(task: Mapping, input_hash, **more) -> dict:
    """What a result or error file says of its task: key, source, window, input hash, then ``more``."""
    return {
        "key": task["key"],
        "source": task["path"],
        "window": [task["t0"], task["t1"]],
        "input_hash": input_hash,
        **more,
    }


def _write_error(task, row, exc, err_path: Path, res_path: Path, input_hash, t_start=None) -> dict:
    row.update(
        status="error",
        error=one_line(exc),
        result_file=str(Path("results") / err_path.name),
        converged=None,
        params={},
        stderr={},
    )
    if t_start is not None:
        row["task_seconds"] = time.perf_counter() - t_start
    doc = {
        "format": ERROR_FORMAT[0],
        "version": ERROR_FORMAT[1],
        **_task_block(task, input_hash, error=row["error"], row=row),
    }
    try:
        res_path.unlink(missing_ok=True)  # a stale result for other inputs must not stand beside the error
        atomic_write_text(err_path, _dumps(doc, indent=1))
    except Exception as exc2:  # the row still carries the error
        row["error"] += f" (and the error file could not be written: {one_line(exc2)})"
        row["result_file"] = ""
    return row


# --- summary ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class BatchSummary(Codec):
    """What :func:`run_batch` did.

    The rows themselves stay on disk (memory flat in the number of records);
    :attr:`rows` reads them from ``table.json``.  Each parameter is the
    attribute of the same name.

    Parameters
    ----------
    out_dir : Path
        The output folder.
    table_csv, table_json : Path
        The table of every record, as CSV and JSON.
    n_total, n_fitted, n_reused, n_failed : int
        Records in the batch; fitted now, reused from an earlier run, failed.
    errors : dict
        Key -> error (type: one-line message) of every record that failed.
    wall_time : float
        Wall-clock time of the batch, s.
    engine : str
        The engine that ran the tasks (``"process"``, ``"serial"``, ``"dask"``).
    findings : dict, optional
        Key -> the codes (space-separated) of the data check's findings, for
        every record fitted with findings (:mod:`fdml.datacheck`).
    warnings : dict, optional
        Category (``"DataWarning"``, ...) -> number of warnings of that
        category over every record; each row's own are in its ``warnings``
        column (``"Category: message"``, joined by ``"; "``).
    """

    out_dir: Path
    table_csv: Path
    table_json: Path
    n_total: int
    n_fitted: int
    n_reused: int
    n_failed: int
    errors: dict
    wall_time: float
    engine: str
    findings: dict = field(default_factory=dict)
    warnings: dict = field(default_factory=dict)

    json_fields = {
        "n_total": renamed(integer(0), "records"),  # the short names of ``fdml batch --json``
        "n_fitted": renamed(integer(0), "fitted"),
        "n_reused": renamed(integer(0), "reused"),
        "n_failed": renamed(integer(0), "failed"),
    }
    json_source = "fdml batch summary"

    @functools.cached_property
    def rows(self) -> list[dict]:
        """One row per record, in source order, as in ``table.json``."""
        return _loads(self.table_json.read_text())["rows"]

    @property
    def n_ok(self) -> int:
        """Records fitted without error."""
        return self.n_total - self.n_failed

    @property
    def failed(self) -> list[dict]:
        """Rows of the records that failed."""
        return [r for r in self.rows if r["status"] != "ok"]

    def to_frame(self):
        """The table as a pandas DataFrame (pandas is optional).

        Returns
        -------
        pandas.DataFrame
            One row per record, read from ``table.csv``.
        """
        return require_pandas().read_csv(self.table_csv)

    def __str__(self) -> str:
        lines = [
            f"{self.n_total} records: {self.n_fitted} fitted, {self.n_reused} reused, "
            f"{self.n_failed} failed in {self.wall_time:.1f} s ({self.engine})",
            f"table: {self.table_csv}",
        ]
        lines.extend(f"  {key}: {err}" for key, err in self.errors.items())
        if self.findings:
            lines.append(
                f"data check: {len(self.findings)} record(s) with findings (column 'findings'; "
                "--strict makes them errors)"
            )
            lines.extend(f"  {key}: {codes}" for key, codes in self.findings.items())
        if self.warnings:
            counts = ", ".join(f"{n} {cat}" for cat, n in sorted(self.warnings.items()))
            lines.append(f"warnings: {counts} (column 'warnings')")
            lines.extend(f"  {r['key']}: {_warnings_text(r['warnings'])}" for r in self.rows if r.get("warnings"))
        return "\n".join(lines)


def require_pandas():
    """The pandas module (an optional extra), or a one-line error saying how to install it."""
    try:
        import pandas as pd
    except ImportError:
        raise FdmlError("to_frame needs pandas: pip install 'fdml[pandas]'") from None
    return pd


#: The table's columns before the estimates and their standard errors, in order.
_FIXED_COLUMNS = tuple(
    "key source t0 t1 status reused converged iterations cost elapsed n_freq error warnings findings "
    "result_file".split()
)


class _RowSpool:
    """Rows as they finish, appended to a file; read back in source order for the tables.

    In memory per record: one file offset (8 bytes).
    """

    def __init__(self, path: Path, n: int):
        from array import array

        self.path = path
        self.fh = open(path, "w+b")
        self.offsets = array("q", [-1]) * n
        self.names: dict[str, None] = {}  # ordered union of parameter names
        self.warnings: Counter = Counter()  # warnings by category, over every record

    def add(self, row: dict) -> bool:
        """Store ``row``; True if its record had no row yet."""
        i = row["index"]
        row["warnings"] = _row_warnings(row.get("warnings"))
        self.fh.seek(0, os.SEEK_END)
        first = self.offsets[i] < 0
        if first:
            self.warnings.update(w["category"] for w in row["warnings"])
        self.offsets[i] = self.fh.tell()
        self.fh.write(_dumps(row, compact=True).encode() + b"\n")
        self.names.update(dict.fromkeys(row["params"]))
        return first

    def rows(self) -> Iterator[dict]:
        """The rows in source order."""
        for off in self.offsets:
            if off >= 0:
                self.fh.seek(off)
                yield _loads(self.fh.readline())

    def close(self) -> None:
        self.fh.close()
        self.path.unlink(missing_ok=True)


def _row_warnings(value) -> list[dict]:
    """A row's warnings as ``[{"category", "message"}]``; an older row's ``"; "``-joined text is split."""
    if isinstance(value, str):
        value = [v for v in value.split("; ") if v]
    return [RecordedWarning.from_value(v).to_dict() for v in value or ()]


def _warnings_text(warnings: list) -> str:
    """A row's warnings as its CSV cell: ``"Category: message"``, joined by ``"; "``."""
    return "; ".join(str(RecordedWarning.from_value(w)) for w in warnings)


def _write_tables(out_dir: Path, spool: _RowSpool, spec: dict, fit_kwargs: dict) -> tuple[Path, Path]:
    """table.csv and table.json, streamed row by row from the spool."""
    names = list(spool.names)
    csv_path, json_path = out_dir / "table.csv", out_dir / "table.json"
    with atomic_open(csv_path, "w", what="batch table") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(list(_FIXED_COLUMNS) + [c for n in names for c in (n, f"{n}_stderr")])
        for r in spool.rows():
            fixed = ["" if r.get(c) is None else r.get(c) for c in _FIXED_COLUMNS]
            fixed[_FIXED_COLUMNS.index("warnings")] = _warnings_text(r["warnings"])
            w.writerow(fixed + [v for n in names for v in (r["params"].get(n, ""), r["stderr"].get(n, ""))])
    head = {"format": TABLE_FORMAT[0], "version": TABLE_FORMAT[1], "model": spec, "fit_kwargs": fit_kwargs}
    with atomic_open(json_path, "w", what="batch table") as fh:
        fh.write(_dumps(head, indent=1)[:-2] + ',\n "rows": [')
        for i, r in enumerate(spool.rows()):
            r.pop("index", None)
            fh.write(("\n  " if i == 0 else ",\n  ") + _dumps(r, indent=None))
        fh.write("\n ]\n}\n")
    return csv_path, json_path


#: Lock file of a batch output folder: the batch writing into the folder holds its ``flock``.
LOCK_NAME = ".fdml-batch.lock"


def _try_flock(fd) -> bool:
    """Lock ``fd`` (a descriptor or a file) exclusively without waiting; False if another holds it."""
    import fcntl

    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def _clean_stale(out: Path, own: Path) -> None:
    """Remove the temporary files of batches that are gone; call with the folder lock held.

    With the lock held no other batch writes a result or a table here, so
    every ``results/.*.tmp`` and ``.table.csv.*.tmp``/``.table.json.*.tmp`` was
    left by a batch that crashed.  A row spool (``.rows-PID.jsonl.tmp``) is
    stale only when no process holds its ``flock``: a batch waiting for this
    folder already holds its own.  Other ``.*.tmp`` files in the folder (an
    ``fdml fit -o`` into it in progress) are not the batch's and are left alone.
    """
    stale = [*(out / "results").glob(".*.tmp"), *out.glob(".table.csv.*.tmp"), *out.glob(".table.json.*.tmp")]
    for f in stale:
        f.unlink(missing_ok=True)
    for f in out.glob(".rows-*.jsonl.tmp"):
        if f == own:
            continue
        try:
            fd = os.open(f, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        except OSError:  # gone meanwhile, or not ours to open: leave it
            continue
        try:
            if _try_flock(fd):  # nobody holds it: its batch is gone
                f.unlink(missing_ok=True)
        except OSError:
            pass
        finally:
            os.close(fd)


@contextlib.contextmanager
def _folder_lock(out: Path, spool: _RowSpool) -> Iterator[None]:
    """Hold the output folder ``out`` for a whole batch; a second batch into it waits.

    The lock is an ``flock`` on ``out/.fdml-batch.lock`` (the file stays; the
    kernel releases the lock when the holder ends, however it ends, so a crash
    never leaves the folder locked).  A second batch into the same folder
    waits for the first to finish, saying so once on the log, then runs (and
    reuses what the first fitted, if its inputs are the same): two batches
    into one folder give the same files as one after the other.  Once held,
    the temporary files of batches that are gone are removed
    (:func:`_clean_stale`).  ``spool``'s file is locked first, so that a batch
    taking the folder meanwhile sees it is live.  Where ``fcntl`` does not
    exist (Windows), or the file system refuses locks, the batch runs unlocked
    (with a warning for the latter) and removes no temporary file.

    Raises
    ------
    OutputError
        The lock file cannot be created or is not a regular file.
    """
    import multiprocessing

    if getattr(multiprocessing.current_process(), "_inheriting", False):
        # a worker re-running an unguarded main script (spawn, forkserver) would wait for
        # its own parent's lock forever; multiprocessing reads the same private flag
        raise FdmlError(
            "run_batch was called while a worker process imports the main script: put the "
            "call under `if __name__ == '__main__':`"
        )
    try:
        import fcntl
    except ImportError:
        yield
        return
    import socket
    import stat

    from .errors import OutputError

    with contextlib.suppress(OSError):
        _try_flock(spool.fh)
    path = out / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o666)
    except OSError as exc:
        raise OutputError(f"cannot open the batch lock file {path}: {exc.strerror or exc}") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OutputError(f"batch lock file {path} exists and is not a regular file")
        try:
            if not _try_flock(fd):
                holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "unknown process"
                logger.warning("%s is in use by another fdml batch (%s); waiting for it to finish", out, holder)
                fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError as exc:  # a file system without locks (some network or FUSE mounts)
            logger.warning(
                "cannot lock %s (%s): a concurrent batch into it is not detected and temporary "
                "files of earlier runs are kept",
                out,
                exc.strerror or exc,
            )
        else:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode(), 0)
            _clean_stale(out, spool.path)
        yield
    finally:
        os.close(fd)  # releases the lock


# --- the batch ----------------------------------------------------------------------------------
def run_batch(
    sources,
    model_spec,
    out_dir,
    *,
    fit_kwargs: Mapping | None = None,
    engine="process",
    workers: int | None = None,
    resume: bool = True,
    progress=None,
    read_kwargs: Mapping | None = None,
) -> BatchSummary:
    """Fit one model to many records, each on its own; stream results to disk.

    Parameters
    ----------
    sources : path, glob, (path, t0, t1) or a list of them
        See :func:`collect_sources`; windows are in s.
    model_spec : ModelSpec, mapping or Model
        The model, rebuilt in every worker (see :class:`ModelSpec`).
    out_dir : path
        Results go to ``out_dir/results/KEY.json`` (or ``KEY.error.json``), the
        table to ``out_dir/table.csv`` and ``out_dir/table.json``.
    fit_kwargs : mapping, optional
        Options of :func:`fdml.fit` (``band``, ``outputs``, ``boundary``, ...),
        plain data; they are part of the input hash.
    engine : {"process", "serial", "dask"}, scheduler address or dask.distributed.Client
        ``process`` (default): a local process pool of ``workers`` (default
        all cores); ``serial``: in this process; a Client (or an address, or
        ``"dask"`` for a local cluster) runs the tasks on Dask (``dask`` extra).
    workers : int, optional
        Local worker processes.
    resume : bool, optional
        Reuse result files whose input hash matches (default True); False
        refits everything.
    progress : None, True or callable, optional
        True: a tqdm bar (``progress`` extra); a callable is called as
        ``progress(done, total, row)`` in this process after every record.
    read_kwargs : mapping, optional
        Options of :func:`fdml.io.load_record` for every record (``format``,
        ``columns``, ``units``, ``sign``, ``layout``), plain data; part of the
        input hash.

    Returns
    -------
    BatchSummary
        A failed record is a row with its error; it never stops the others.

    Notes
    -----
    One batch at a time writes into ``out_dir``: a second batch into the same
    folder *waits* for the first to finish (it logs that it waits), then runs,
    so concurrent batches give what the same batches one after the other give;
    see :func:`_folder_lock`.  SIGTERM, SIGHUP or SIGINT to this process end
    the run cleanly: the workers are ended, no partial file is left, and a
    rerun resumes (see :func:`fdml.parallel.execute`).
    """
    t_start = time.perf_counter()
    items = collect_sources(sources)
    spec = ModelSpec.coerce(model_spec).normalized()
    spec.check()  # a bad model spec is one error now, not one per record
    spec_d = spec.to_dict()
    kw = check_fit_kwargs(fit_kwargs)
    read = dict(read_kwargs or {})
    canonical_json(read)  # plain data only: it is hashed and shipped to workers
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise FdmlError(f"workers must be a positive integer, got {workers!r}")
    out = Path(out_dir).absolute()
    (out / "results").mkdir(parents=True, exist_ok=True)
    common = {"spec": spec_d, "fit_kwargs": kw, "fit_key": _fit_options_key(kw), "read": read, "out_dir": str(out)}
    tasks = ({"index": i, **asdict(it), **common, "resume": bool(resume)} for i, it in enumerate(items))
    spool = _RowSpool(out / f".rows-{os.getpid()}.jsonl.tmp", len(items))
    done = 0
    with contextlib.ExitStack() as run:  # closed in reverse: the engine, the folder lock, signal handlers, the spool
        run.callback(spool.close)
        run.enter_context(_signals_end_the_run())
        run.enter_context(_folder_lock(out, spool))
        rows = execute(
            run_task, tasks, engine=engine, workers=workers, on_error=error_row, progress=progress, total=len(items)
        )
        for row in run.enter_context(contextlib.closing(rows)):
            done += spool.add(row)
        csv_path, json_path = _write_tables(out, spool, spec_d, kw)
        errors, findings, n_reused = {}, {}, 0
        for r in spool.rows():
            n_reused += bool(r.get("reused"))
            if r["status"] != "ok":
                errors[r["key"]] = r["error"]
            if r.get("findings"):
                findings[r["key"]] = r["findings"]
        warned = dict(spool.warnings)
    return BatchSummary(
        out_dir=out,
        table_csv=csv_path,
        table_json=json_path,
        n_total=done,
        n_fitted=done - len(errors) - n_reused,
        n_reused=n_reused,
        n_failed=len(errors),
        errors=errors,
        wall_time=time.perf_counter() - t_start,
        engine=engine_name(engine),
        findings=findings,
        warnings=warned,
    )
