"""``fdml fit RECORD ...``: maximum-likelihood fit of a model to CSV records."""

from __future__ import annotations

from . import _options as O
from ._common import assignments, check_band_option, fit_spectra, model_for_records


def register(sub) -> None:
    p = sub.add_parser(
        "fit",
        help="fit a model to one or more records (CSV: t,de,alpha,q,az[,alpha_w])",
        description="Fit a model to one or more records.  Model rule, when --model is not given: " + O.MODEL_RULE + ".",
    )
    p.add_argument(
        "records",
        nargs="+",
        metavar="RECORD",
        help="record file(s): CSV, SIDPAC .mat, DLR .asc/.mat; several are fitted jointly",
    )
    O.add_model_options(p)
    O.add_record_options(p)
    O.add_band_option(p)
    O.add_fit_options(p)
    O.add_output_option(p, kind="file", metavar="RESULT.json", help="save the full result as JSON")
    O.add_strict_option(
        p,
        "exit with code 2 before fitting when the data check finds anything "
        "(units, signs, swapped channels, no response); estimation warnings stay warnings",
    )
    O.add_json_option(p)
    O.add_progress_option(p, default_on=False)
    p.set_defaults(parsers=sub)  # the parsers: for the commands the adequacy warning quotes (_commands)


#: Options the quoted commands leave out: where results go and how they are shown.
_NOT_QUOTED = ("output", "json", "progress", "func", "parsers", "command", "verbose")


def _argv_of(parser, args) -> list:
    """``args`` as the argv of ``parser``: positionals, then every option not at its default.

    Options ``parser`` does not have are left out.
    """
    vals = {k: v for k, v in vars(args).items() if k not in _NOT_QUOTED}
    pos, opt = [], []
    for a in parser._actions:
        if a.dest not in vals or a.dest == "help" or a.help == "==SUPPRESS==":  # not hidden aliases
            continue
        v = vals[a.dest]
        items = [str(x) for x in (v if isinstance(v, list) else [v])]
        if not a.option_strings:
            pos += items
        elif v != a.default and v is not None and not (a.choices and v not in a.choices):
            flag = max(a.option_strings, key=len)
            # a repeatable option once per value (--effect a --effect b): every parser reads that form
            opt += [flag] if a.nargs == 0 else [x for item in items for x in (flag, item)]
    return pos + opt


def _commands(args) -> tuple[list, list | None]:
    """(this ``fdml fit`` command, the ``fdml diagnose`` command for the same records and model)."""
    fit_argv = ["fdml", "fit", *_argv_of(args.parsers.choices["fit"], args)]
    diag = args.parsers.choices.get("diagnose")
    diag_argv = None if diag is None else ["fdml", "diagnose", *_argv_of(diag, args)]
    return fit_argv, diag_argv


def _progress_callback(enabled: bool):
    """A tqdm bar for --progress, or None (with a one-line note when tqdm is missing)."""
    if not enabled:
        return None
    import sys

    from ..progress import TqdmProgress, tqdm_available

    if not tqdm_available():
        sys.stderr.write(
            "fdml: note: --progress needs tqdm (pip install 'fdml[progress]'); fitting without a progress bar\n"
        )
        return None
    return TqdmProgress(desc="fdml fit", leave=True)  # the last state stays: N iterations


def run(args) -> int:
    import contextlib
    import time

    t0 = time.perf_counter()
    from ..adequacy import reworded
    from ..cli import show
    from ..conditions import attach_conditions
    from ..estimate import fit
    from ..io import load_records
    from ..io.cli import record_options

    if args.output:  # before any work: the result must not replace an input, a folder or a device
        from ..outputs import check_output

        check_output(args.output, [*args.records, args.aircraft], what="result file")
    check_band_option(args.band)
    kwargs = O.fit_kwargs(args)  # a bad --outputs before reading
    records = load_records(args.records, **record_options(args))
    t_read = time.perf_counter()
    model, provenance = model_for_records(args, records)
    fixed = assignments(args.fix)
    data = fit_spectra(records, args.band, kwargs)  # the front end
    t_transform = time.perf_counter()
    bar = _progress_callback(O.progress_wanted(args, default_on=False))
    with bar or contextlib.nullcontext():  # the bar closes on its last count
        res = fit(data, model, fix=fixed, free=args.free or [], callback=bar, strict=bool(args.strict), **kwargs)
    fit_argv, diagnose_argv = _commands(args)
    res = reworded(res, fit_argv=fit_argv, diagnose_argv=diagnose_argv)  # the advice quotes this command
    res = attach_conditions(res, model, records, provenance)
    t_fit = time.perf_counter()
    if args.output:
        res.to_json(args.output)
    out = res.brief()
    # seconds: reading (imports of the loaders included), the Fourier front end, the estimator
    out["timing"] = {"read": t_read - t0, "transform": t_transform - t_read, "estimate": t_fit - t_transform}
    if args.output:
        out["result_file"] = args.output
    # the summary's header gives the airspeed and where it came from
    show(args, out, res.summary() + (f"\n\nwrote {args.output}" if args.output else ""))
    return 0 if res.converged else 1
