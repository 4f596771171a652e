"""``fdml fit RECORD ...``: maximum-likelihood fit of a model to CSV records."""

from __future__ import annotations

from ..io.cli import add_record_arguments, record_options
from ._common import add_model_arguments, assignments, check_band_option, make_model_from_args


def register(sub) -> None:
    p = sub.add_parser("fit", help="fit a model to one or more records (CSV: t,de,alpha,q,az[,alpha_w])")
    p.add_argument("records", nargs="+", metavar="RECORD",
                   help="record file(s): CSV, SIDPAC .mat, DLR .asc/.mat; several are fitted jointly")
    add_model_arguments(p)
    add_record_arguments(p)
    p.add_argument("--band", default="0.1:10:0.1", metavar="LO:HI:STEP",
                   help="frequency band in rad/s (default 0.1:10:0.1)")
    p.add_argument("--outputs", default="alpha,q,az", help="outputs in the fit (default alpha,q,az)")
    p.add_argument("--fix", nargs="*", default=[], metavar="NAME=VALUE", help="fix parameters")
    p.add_argument("--free", nargs="*", default=[], metavar="NAME", help="free parameters")
    p.add_argument("--boundary", default="estimated", choices=("estimated", "measured", "none"),
                   help="boundary terms x(0) - x(T)exp(-jwT) (default estimated)")
    p.add_argument("--biases", default="auto", choices=("auto", "yes", "no"),
                   help="estimate output biases (default auto: when trim is removed)")
    p.add_argument("--trim", default="first", choices=("first", "mean", "none"),
                   help="trim removal (default: first sample)")
    p.add_argument("--method", default="lm", choices=("lm", "gauss-newton"))
    p.add_argument("--stop", default="converge", choices=("converge", "paper"),
                   help="run to convergence (default) or the paper's 1 %% rule")
    p.add_argument("-o", "--output", metavar="RESULT.json", help="save the full result as JSON")
    p.add_argument("--strict", action="store_true",
                   help="exit with code 2 before fitting when the data check finds anything "
                        "(units, signs, swapped channels, no response); estimation warnings stay warnings")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--progress", action="store_true",
                   help="show a progress bar on stderr (needs tqdm: pip install 'fdml[progress]')")
    p.set_defaults(func=run)
    global _SUBPARSERS
    _SUBPARSERS = sub  # for the commands quoted by the adequacy warning (_commands)


_SUBPARSERS = None
#: Options the quoted commands leave out: where results go and how they are shown.
_NOT_QUOTED = ("output", "json", "progress", "func", "command", "verbose")


def _argv_of(parser, args, *, rename=None) -> list:
    """``args`` as the argv of ``parser``: positionals, then every option not at its default.

    ``rename`` maps an attribute of ``args`` to the dest of ``parser`` (fit's model -> diagnose's base);
    options ``parser`` does not have are left out.
    """
    rename = rename or {}
    vals = {rename.get(k, k): v for k, v in vars(args).items() if k not in _NOT_QUOTED}
    pos, opt = [], []
    for a in parser._actions:
        if a.dest not in vals or a.dest == "help":
            continue
        v = vals[a.dest]
        if not a.option_strings:
            pos += [str(x) for x in (v if isinstance(v, list) else [v])]
        elif v != a.default and v is not None and not (a.choices and v not in a.choices):
            flag = max(a.option_strings, key=len)
            opt += [flag] if a.nargs == 0 else [flag, *(str(x) for x in (v if isinstance(v, list) else [v]))]
    return pos + opt


def _commands(args) -> tuple[list, list | None]:
    """(this ``fdml fit`` command, the ``fdml diagnose`` command for the same records and model)."""
    fit_argv = ["fdml", "fit", *_argv_of(_SUBPARSERS.choices["fit"], args)]
    diag = _SUBPARSERS.choices.get("diagnose")
    diag_argv = None if diag is None else ["fdml", "diagnose", *_argv_of(diag, args, rename={"model": "base"})]
    return fit_argv, diag_argv


def _progress_callback(enabled: bool):
    """A tqdm bar for --progress, or None (with a one-line note when tqdm is missing)."""
    if not enabled:
        return None
    import sys

    from ..progress import TqdmProgress, tqdm_available

    if not tqdm_available():
        sys.stderr.write("fdml: note: --progress needs tqdm (pip install 'fdml[progress]'); "
                         "fitting without a progress bar\n")
        return None
    return TqdmProgress(desc="fdml fit", leave=False)


def run(args) -> int:
    import time

    t0 = time.perf_counter()
    from ..estimate import fit
    from ..io import load_records

    from ..spectra import spectra

    if args.output:  # before any work: the result must not replace an input, a folder or a device
        from ..outputs import check_output

        check_output(args.output, [*args.records, args.aircraft], what="result file")
    check_band_option(args.band)
    records = load_records(args.records, **record_options(args))
    t_read = time.perf_counter()
    model = make_model_from_args(args)
    fixed = assignments(args.fix)
    biases = {"auto": "auto", "yes": True, "no": False}[args.biases]
    data = [spectra(r, band=args.band, trim=args.trim) for r in records]  # the Fourier front end
    t_transform = time.perf_counter()
    bar = _progress_callback(getattr(args, "progress", False))
    from ..adequacy import invocation

    try:
        with invocation(*_commands(args)):  # the adequacy warning quotes this command with --effect added
            res = fit(data if len(data) > 1 else data[0], model, outputs=args.outputs,
                      fix=fixed, free=args.free, boundary=args.boundary, biases=biases,
                      method=args.method, stop=args.stop, callback=bar, strict=args.strict)
    finally:
        if bar is not None:
            bar.close()
    t_fit = time.perf_counter()
    if args.output:
        res.to_json(args.output)
    if args.json:
        from ..cli import print_json

        out = res.brief()
        # seconds: reading (imports of the loaders included), the Fourier front end, the estimator
        out["timing"] = {"read": t_read - t0, "transform": t_transform - t_read, "estimate": t_fit - t_transform}
        if args.output:
            out["result_file"] = args.output
        print_json(out)
    else:
        print(res.summary())
        if args.output:
            print(f"\nwrote {args.output}")
    return 0 if res.converged else 1
