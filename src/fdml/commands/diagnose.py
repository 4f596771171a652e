"""``fdml diagnose RECORD ... --model MODEL``: where the model misses, which effect causes it, how far it shrinks.

``fdml diagnose --validate`` runs the validation harness instead (records
simulated with one withheld effect; see :mod:`fdml.diagnose.validation`).
"""

from __future__ import annotations

import sys

from ..cli import show
from ..outputs import check_output
from . import _options as O


def register(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        help="diagnose the model-to-data gap: locate it, attribute it to an "
        "unmodelled effect, measure how far it shrinks",
        description="Diagnose the model-to-data gap of a base model.  Model rule: " + O.MODEL_RULE + ".",
    )
    p.add_argument("records", nargs="*", metavar="RECORD", help="record file(s), fitted jointly")
    O.add_model_options(p, what="base model the effects are added to")
    O.add_record_options(p)
    lo_hi = O.DEFAULT_BAND_TEXT.rsplit(":", 1)[0]  # fdml's default band (fdml.diagnose.data.DEFAULT_DIAG_BAND)
    O.add_band_option(
        p,
        help=f"analysis band, rad/s (default {lo_hi}; a :STEP is ignored: the "
        "diagnosis uses each record's spacing 2 pi/(K T))",
    )
    p.add_argument("--bands", metavar="E0,E1,...", help="edges of the gap map's bands, rad/s")
    O.accumulating(
        p,
        "--holdout",
        metavar="RECORD",
        help="record(s) of the same flight condition kept out of the fit, to judge the shrink (repeatable)",
    )
    p.add_argument(
        "--outputs",
        metavar="NAME,...",
        default=None,
        help="outputs in the fit, comma-separated, each once (default alpha,q,az)",
    )
    O.add_fit_option(
        p,
        "input_edges",
        help="timing of elevator steps between two samples, one term per step within +-dt/2 (default: "
        "estimated when it explains the gap better than the effects, by BIC; none; estimated; auto as fdml fit)",
    )
    p.add_argument("--library", metavar="NAME,...", help="candidate effects (default: all registered)")
    p.add_argument(
        "--alpha", type=float, default=None, help="family-wise level (default: every fit's adequacy check's, 0.01)"
    )
    p.add_argument("--max-effects", type=int, default=2, help="greedy forward selection limit (default 2)")
    p.add_argument(
        "--noise-model", choices=("band", "white"), default=None, help="noise model of the likelihood (default band)"
    )
    O.add_strict_option(
        p,
        "exit with code 2 before fitting when the data check finds anything "
        "(units, signs, swapped channels, no response)",
    )
    O.add_json_option(p)
    O.add_output_option(
        p,
        kind="file",
        metavar="REPORT.json",
        help="the full report (or validation) as JSON; its 'recommended' is the fit of the base "
        "model plus the accepted effects, as fdml fit --json prints it",
    )
    p.add_argument(
        "--recommended-output",
        metavar="FIT.json",
        help="write the recommended fit (the base model plus the accepted effects, fitted by fdml fit on "
        "the analysis grid) as a fit result file, which fdml report reads",
    )
    p.add_argument("--figure", metavar="FIG.png", help="write the figure (gap map before/after, Bode overlays)")
    v = p.add_argument_group("validation harness")
    v.add_argument(
        "--validate", action="store_true", help="run the withheld-effect validation instead of diagnosing records"
    )
    v.add_argument("--quick", action="store_true", help="validation with 1 seed per cell and 6 per null case")
    v.add_argument("--n-effect", type=int, default=4, help="seeds per truth/size/manoeuvre/noise cell (default 4)")
    v.add_argument("--n-null", type=int, default=34, help="seeds per null/manoeuvre/noise cell (default 34)")
    v.add_argument(
        "--seed-base", type=int, default=None, help="first seed (default: the report range; 0 is the tuning range)"
    )
    O.add_workers_option(v)
    O.add_progress_option(v, default_on=True)


def _validate(args) -> int:
    from ..diagnose.validation import REPORT_SEED_BASE, validate

    n_e, n_n = (1, 6) if args.quick else (args.n_effect, args.n_null)
    if args.output:  # before the (long) work
        check_output(args.output, what="validation file")

    def progress(done, total):
        sys.stderr.write(f"\rfdml diagnose --validate: {done}/{total}")
        if done == total:
            sys.stderr.write("\n")

    res = validate(
        n_effect=n_e,
        n_null=n_n,
        seed_base=REPORT_SEED_BASE if args.seed_base is None else args.seed_base,
        processes=args.workers,
        progress=progress if O.progress_wanted(args, default_on=True) else None,
    )
    if args.output:
        res.to_json(args.output)
    show(args, {"settings": res.settings, "scores": res.scores}, res.table())
    return 0


def _check_outputs(args) -> None:
    """-o and --figure: not an input (records, hold-out records, aircraft JSON), a folder or a device."""
    inputs = [*args.records, *(args.holdout or []), args.aircraft]
    for path, what in ((args.output, "report file"), (args.figure, "figure"), (args.recommended_output, "result file")):
        if path:
            check_output(path, inputs, what=what)


def run(args) -> int:
    if args.validate:
        return _validate(args)
    from ..diagnose import diagnose
    from ..errors import ParameterError, RecordError
    from ..estimate import parse_outputs
    from ..io import load_records
    from ..io.cli import record_options
    from ..verdict import LEVEL
    from ._common import model_for_records

    if not args.records:
        raise RecordError("give at least one RECORD to diagnose (or --validate)")
    _check_outputs(args)
    opts = record_options(args)
    records = load_records(args.records, **opts)
    holdout = load_records(args.holdout, **opts) if args.holdout else None
    model, _ = model_for_records(args, records)
    bands = None
    if args.bands:
        try:
            bands = [float(x) for x in args.bands.split(",")]
        except ValueError:
            raise ParameterError(f"--bands must be numbers separated by commas, got {args.bands!r}") from None
    rep = diagnose(
        records,
        model,
        holdout=holdout,
        band=args.band,
        bands=bands,
        library=[x.strip() for x in args.library.split(",")] if args.library else None,
        alpha=args.alpha if args.alpha is not None else LEVEL,
        max_effects=args.max_effects,
        outputs=list(parse_outputs(args.outputs, what="--outputs")),
        input_edges=args.input_edges,
        trim="first",
        strict=bool(args.strict),
        **({} if args.noise_model is None else {"noise": args.noise_model}),
    )
    if args.output:
        rep.to_json(args.output)
    if args.recommended_output and rep.recommended is not None:
        rep.recommended.to_json(args.recommended_output)
    if args.figure and rep.status == "ok":
        rep.plot(args.figure)
    show(args, rep.to_dict(), rep.summary())
    if rep.status != "ok":
        sys.stderr.write(f"fdml: error: no verdict: {'; '.join(rep.problems)}\n")
        return 2
    if args.recommended_output and rep.recommended is None:
        sys.stderr.write(
            f"fdml: error: the recommended model could not be fitted; {args.recommended_output} was not written\n"
        )
        return 2
    return 0
