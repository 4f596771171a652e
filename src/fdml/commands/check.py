"""``fdml check RECORD``: data quality (and kinematic compatibility) before a fit."""

from __future__ import annotations

from . import _options as O


def register(sub) -> None:
    p = sub.add_parser(
        "check",
        help="data quality of a record (sampling, dropouts, saturation, excitation, "
        "coherence); --compat adds the kinematic compatibility check",
    )
    p.add_argument("record", metavar="RECORD", help="record file (SIDPAC .mat, DLR .asc/.mat, CSV)")
    O.add_record_options(p)
    O.add_band_option(p)
    p.add_argument(
        "--n-params",
        type=int,
        default=13,
        metavar="N",
        help="quantities the fit will estimate (default 13: dimensional model, biases, boundary)",
    )
    p.add_argument(
        "--compat",
        action="store_true",
        help="also estimate sensor biases, scale factors and time shifts from the kinematics",
    )
    p.add_argument(
        "--estimate",
        metavar="NAME,...",
        help="with --compat: the sensor parameters to estimate, comma-separated (default: those the channels "
        "determine; the check's summary lists the others and why)",
    )
    p.add_argument(
        "--airspeed",
        type=float,
        metavar="U",
        help="true airspeed, m/s, for the a_z slope of the data check (default: the record's)",
    )
    O.add_strict_option(p, "exit with code 2 when the data check finds anything (units, signs, channels, response)")
    O.add_json_option(p)


def run(args) -> int:
    from ..cli import show
    from ..datacheck import check_data
    from ..errors import RecordError
    from ..findings import raise_if_strict
    from ..io import load_record
    from ..io.cli import record_options
    from ..quality import check_quality
    from ._common import check_band_option

    band = args.band
    check_band_option(band)
    rec = load_record(args.record, **record_options(args))
    report = check_quality(rec, band=band, n_params=args.n_params)
    data_check = check_data(rec, band=band, airspeed=args.airspeed)
    if args.estimate and not args.compat:
        raise RecordError("--estimate names the parameters of the compatibility check: give --compat too")
    out = {"record": args.record, "quality": report.to_dict(), "data_check": data_check.to_dict()}
    texts = [report.summary(), data_check.summary()]
    if args.compat:
        from ..flightpath import check_compatibility
        from ..parameters import as_names

        estimate = as_names(args.estimate, "--estimate") or None
        try:
            compat = check_compatibility(rec, estimate=estimate)
        except RecordError as exc:  # a perturbation record: the data check above covers Eq. 5
            if "trim kept" not in str(exc):
                raise
            out["compatibility"] = {"skipped": f"compatibility check skipped: {exc}"}
            texts.append(out["compatibility"]["skipped"])
        else:
            out["compatibility"] = compat.to_dict()
            texts.append(compat.summary())
    show(args, out, "\n\n".join(texts))
    raise_if_strict(data_check.findings, bool(args.strict))
    return 0
