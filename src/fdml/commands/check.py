"""``fdml check RECORD``: data quality (and kinematic compatibility) before a fit."""

from __future__ import annotations

from ..io.cli import add_record_arguments, record_options


def register(sub) -> None:
    p = sub.add_parser("check", help="data quality of a record (sampling, dropouts, saturation, excitation, "
                                     "coherence); --compat adds the kinematic compatibility check")
    p.add_argument("record", metavar="RECORD", help="record file (SIDPAC .mat, DLR .asc/.mat, CSV)")
    add_record_arguments(p)
    p.add_argument("--band", default="0.1:10:0.1", metavar="LO:HI:STEP",
                   help="frequency band in rad/s (default 0.1:10:0.1)")
    p.add_argument("--n-params", type=int, default=13, metavar="N",
                   help="quantities the fit will estimate (default 13: dimensional model, biases, boundary)")
    p.add_argument("--compat", action="store_true",
                   help="also estimate sensor biases, scale factors and time shifts from the kinematics")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..io import load_record
    from ..quality import check_quality

    rec = load_record(args.record, **record_options(args))
    report = check_quality(rec, band=args.band, n_params=args.n_params)
    compat = None
    if args.compat:
        from ..compat import check_compatibility

        compat = check_compatibility(rec)
    if args.json:
        from ..cli import print_json

        out = {"record": args.record, "quality": report.to_dict()}
        if compat is not None:
            out["compatibility"] = compat.to_dict()
        print_json(out)
    else:
        print(report.summary())
        if compat is not None:
            print()
            print(compat.summary())
    return 0
