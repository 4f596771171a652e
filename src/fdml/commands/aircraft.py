"""``fdml aircraft list|show NAME|init RECORD``: presets, one aircraft with its sources, a file from a record."""

from __future__ import annotations

from ..errors import AircraftError


def register(sub) -> None:
    p = sub.add_parser(
        "aircraft",
        help="list the aircraft presets, show one with its sources, or start an aircraft file from a record",
        description="list: the bundled presets.  show NAME|FILE.json: every value with its unit and source.  "
        "init RECORD -o FILE.json: an aircraft file filled with what the record carries (areas, chord, span, "
        "mass, Iy, density, airspeed), each with its source, and null for what it does not (tail geometry).",
    )
    p.add_argument("action", choices=("list", "show", "init"))
    p.add_argument("name", nargs="?", help="preset name or aircraft JSON file (show); flight record (init)")
    p.add_argument(
        "--name", dest="aircraft_name", metavar="NAME", help="the aircraft's name (init; default: the record's)"
    )
    from . import _options as O

    O.add_record_options(p)
    O.add_output_option(p, kind="file", metavar="FILE.json", help="the aircraft file started by init")
    O.add_json_option(p)


def run(args) -> int:
    from ..aircraft import list_aircraft, load_aircraft
    from ..cli import show

    if args.action == "init":
        return _init(args)
    if args.action == "list":
        names = list_aircraft()
        show(args, names, "\n".join(names))
        return 0
    if not args.name:
        raise AircraftError("fdml aircraft show needs a NAME (or FILE.json)")
    ac = load_aircraft(args.name)
    show(args, ac.to_dict(), ac.describe())
    return 0


def _init(args) -> int:
    """Start an aircraft file from a record: write it (-o) or print it (JSON on stdout)."""
    from ..aircraft import aircraft_template
    from ..cli import print_json, show
    from ..io import load_record
    from ..io.cli import record_options
    from ..jsoncodec import write_json
    from ..outputs import check_output

    if not args.name:
        raise AircraftError("fdml aircraft init needs a RECORD (fdml aircraft init RECORD -o FILE.json)")
    if args.output:
        check_output(args.output, [args.name], what="aircraft file")  # never over the record
    tpl = aircraft_template(load_record(args.name, **record_options(args)), name=args.aircraft_name)
    if not args.output:
        print_json(tpl.as_file())
        return 0
    write_json(args.output, tpl.as_file())
    show(
        args,
        {"aircraft_file": str(args.output), "missing": tpl.missing},
        f"{tpl.describe()}\n\nwrote {args.output}; fill the null values, then: fdml aircraft show {args.output}",
    )
    return 0
