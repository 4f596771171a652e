"""``fdml aircraft list|show NAME``: the bundled presets and their sources."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("aircraft", help="list the aircraft presets or show one with its sources")
    p.add_argument("action", choices=("list", "show"))
    p.add_argument("name", nargs="?", help="preset name or aircraft JSON file (for show)")
    from . import _options as O

    O.add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..aircraft import list_aircraft, load_aircraft
    from ..cli import print_json
    from ..errors import AircraftError

    if args.action == "list":
        names = list_aircraft()
        if args.json:
            print_json(names)
        else:
            print("\n".join(names))
        return 0
    if not args.name:
        raise AircraftError("fdml aircraft show needs a NAME (or FILE.json)")
    ac = load_aircraft(args.name)
    if args.json:
        print_json(ac.to_dict())
    else:
        print(ac.describe())
    return 0
