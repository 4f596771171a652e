"""``fdml batch SOURCE ...``: fit one model to many records, one result file each, plus a table."""

from __future__ import annotations

from ._common import (
    add_model_arguments,
    assignments,
    check_band_option,
    model_spec_from_args,
    positive_int,
)


def register(sub) -> None:
    p = sub.add_parser("batch", help="fit a model to every record of folders, globs or files (resumable)")
    p.add_argument("sources", nargs="+", metavar="SOURCE",
                   help="a folder, a glob, a record file, or FILE@T0:T1 for a manoeuvre window (s)")
    add_model_arguments(p)
    p.add_argument("--band", default="0.1:10:0.1", metavar="LO:HI:STEP",
                   help="frequency band in rad/s (default 0.1:10:0.1)")
    p.add_argument("--outputs", default="alpha,q,az", help="outputs in the fit (default alpha,q,az)")
    p.add_argument("--fix", nargs="*", default=[], metavar="NAME=VALUE", help="fix parameters")
    p.add_argument("--free", nargs="*", default=[], metavar="NAME", help="free parameters")
    p.add_argument("--boundary", default="estimated", choices=("estimated", "measured", "none"))
    p.add_argument("--trim", default="first", choices=("first", "mean", "none"))
    p.add_argument("--method", default="lm", choices=("lm", "gauss-newton"))
    p.add_argument("--out", default="fdml-batch", metavar="DIR",
                   help="output folder: results/KEY.json and table.csv, table.json (default ./fdml-batch)")
    p.add_argument("--workers", type=positive_int, metavar="N", help="local worker processes (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask cluster (tcp://HOST:PORT; needs the 'dask' extra)")
    p.add_argument("--serial", action="store_true", help="fit in this process, one record after another")
    p.add_argument("--no-resume", dest="resume", action="store_false",
                   help="refit everything (default: reuse results whose inputs are unchanged)")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    p.add_argument("--strict", action="store_true",
                   help="a record whose data check finds anything (units, signs, channels, response) "
                        "fails with that finding as its error")
    p.add_argument("--json", action="store_true", help="machine-readable summary")
    p.set_defaults(func=run)


def parse_source(text: str):
    """``FILE@T0:T1`` -> (FILE, t0, t1); anything else unchanged (an existing file wins)."""
    from pathlib import Path

    from ..errors import FdmlError

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
    from pathlib import Path

    from ..batch import collect_sources
    from ..outputs import Inputs, check_output, check_output_dir

    items = collect_sources(sources)
    folders = [s for s in sources if isinstance(s, str) and Path(s).is_dir()]
    inputs = Inputs([it.path for it in items] + folders + [aircraft])  # stat each input once
    out = Path(out_dir)
    check_output_dir(out, inputs)
    check_output_dir(out / "results", inputs)
    for name in ("table.csv", "table.json"):
        check_output(out / name, inputs, what="batch table")
    for it in items:
        for name in (f"{it.key}.json", f"{it.key}.error.json"):
            check_output(out / "results" / name, inputs, what="batch result file")


def run(args) -> int:
    from ..batch import run_batch
    from ..errors import FdmlError

    check_band_option(args.band)  # up front: a bad band would fail every record one by one
    spec = model_spec_from_args(args, fix=assignments(args.fix), free=list(args.free))
    fit_kwargs = {"band": args.band, "outputs": args.outputs, "boundary": args.boundary, "trim": args.trim,
                  "method": args.method}
    if args.strict:
        fit_kwargs["strict"] = True
    if args.serial and args.scheduler:
        raise FdmlError("give --serial or --scheduler, not both")
    engine = "serial" if args.serial else (args.scheduler or "process")
    progress = None
    if args.progress and not args.json:
        import importlib.util

        progress = True if importlib.util.find_spec("tqdm") is not None else None
    sources = [parse_source(s) for s in args.sources]
    check_batch_outputs(sources, args.out, args.aircraft)
    summary = run_batch(sources, spec, args.out, fit_kwargs=fit_kwargs,
                        engine=engine, workers=args.workers, resume=args.resume, progress=progress)
    if args.json:
        from ..cli import print_json

        print_json(summary.to_dict())
    else:
        print(summary)
    return 0 if summary.n_failed == 0 else 1
