"""``fdml batch SOURCE ...``: fit one model to many records, one result file each, plus a table."""

from __future__ import annotations

from pathlib import Path

from ..errors import FdmlError
from . import _options as O
from ._common import assignments, check_band_option, model_spec_from_args


def register(sub) -> None:
    p = sub.add_parser(
        "batch",
        help="fit a model to every record of folders, globs or files (resumable)",
        description="Fit one model to many records, one result file each.  Model rule, when --model is not given: "
        + O.MODEL_RULE
        + " (each record's own, as fdml fit).",
    )
    p.add_argument(
        "sources",
        nargs="+",
        metavar="SOURCE",
        help="a folder, a glob, a record file, or FILE@T0:T1 for a manoeuvre window (s)",
    )
    O.add_model_options(p)
    O.add_record_options(p)
    O.add_band_option(p)
    O.add_fit_options(p)
    O.add_output_option(
        p,
        kind="folder",
        metavar="DIR",
        help="results/KEY.json and table.csv, table.json (default ./fdml-batch)",
    )
    O.add_workers_option(p)
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="run on a Dask cluster (tcp://HOST:PORT; needs the 'dask' extra)"
    )
    p.add_argument("--serial", action="store_true", help="fit in this process, one record after another")
    p.add_argument(
        "--no-resume",
        dest="resume",
        action="store_false",
        help="refit everything (default: reuse results whose inputs are unchanged)",
    )
    O.add_progress_option(p, default_on=True)
    O.add_strict_option(
        p,
        "a record whose data check finds anything (units, signs, channels, response) "
        "fails with that finding as its error",
    )
    O.add_json_option(p, "machine-readable summary")


#: Where the batch writes when -o is not given.
DEFAULT_OUTPUT = "fdml-batch"


def parse_source(text: str):
    """``FILE@T0:T1`` -> (FILE, t0, t1); anything else unchanged (an existing file wins)."""
    path, sep, window = text.rpartition("@")
    if not sep or Path(text).exists():
        return text
    lo, colon, hi = window.partition(":")
    if not colon:
        raise FdmlError(f"{text!r}: a window is FILE@T0:T1 (seconds; either may be empty)")
    try:
        t0 = float(lo) if lo.strip() else None
        t1 = float(hi) if hi.strip() else None
    except ValueError:
        raise FdmlError(f"{text!r}: window bounds must be numbers of seconds") from None
    return (path, t0, t1)


def check_batch_outputs(sources, out_dir, aircraft=None) -> None:
    """Refuse, before any fit, an output folder or file that is a source, a folder or a device.

    The outputs are ``out_dir``, ``out_dir/results``, the two tables and every
    record's result and error file; the inputs are the record files, the source
    folders and the aircraft JSON.
    """
    from ..batch import collect_sources
    from ..outputs import Inputs, check_output_folder

    items = collect_sources(sources)
    folders = [s for s in sources if isinstance(s, str) and Path(s).is_dir()]
    inputs = Inputs([it.path for it in items] + folders + [aircraft])  # stat each input once
    out = check_output_folder(out_dir, dict.fromkeys(("table.csv", "table.json"), "batch table"), inputs)
    results = {f"{it.key}{end}": "batch result file" for it in items for end in (".json", ".error.json")}
    check_output_folder(out / "results", results, inputs)


def _read_kwargs(args) -> dict:
    """The record-reading options of ``fdml fit`` (format, columns, units, signs, layout) for every source.

    --t0/--t1 are the window of a source given without its own ``@T0:T1``.
    """
    from ..io.cli import record_options

    opts = {k: v for k, v in record_options(args).items() if k not in ("t0", "t1")}
    if opts["format"] == "auto":
        del opts["format"]
    return opts


def _windowed(source, args):
    """A source with the --t0/--t1 window when it has none of its own."""
    if isinstance(source, tuple) or (args.t0 is None and args.t1 is None):
        return source
    if Path(source).is_dir() or any(c in str(source) for c in "*?["):
        raise FdmlError(f"--t0/--t1 apply to record files; {source!r} is a folder or a glob: give FILE@T0:T1")
    return (source, args.t0, args.t1)


def run(args) -> int:
    import importlib.util

    from ..batch import run_batch
    from ..cli import show

    check_band_option(args.band)  # up front: a bad band would fail every record one by one
    spec = model_spec_from_args(args, reads_records=True, fix=assignments(args.fix), free=list(args.free or []))
    fit_kwargs = O.fit_kwargs(args)
    if args.band is not None:
        fit_kwargs["band"] = args.band
    if args.strict:
        fit_kwargs["strict"] = True
    if args.serial and args.scheduler:
        raise FdmlError("give --serial or --scheduler, not both")
    engine = "serial" if args.serial else (args.scheduler or "process")
    progress = True if O.progress_wanted(args, default_on=True) and importlib.util.find_spec("tqdm") else None
    out = args.output or DEFAULT_OUTPUT
    sources = [_windowed(parse_source(s), args) for s in args.sources]
    check_batch_outputs(sources, out, args.aircraft)
    summary = run_batch(
        sources,
        spec,
        out,
        fit_kwargs=fit_kwargs,
        read_kwargs=_read_kwargs(args),
        engine=engine,
        workers=args.workers,
        resume=args.resume,
        progress=progress,
    )
    show(args, summary.to_dict(), summary)
    return 0 if summary.n_failed == 0 else 1
