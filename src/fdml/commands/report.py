"""``fdml report RESULT.json``: figures and a Markdown report of a saved fit."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("report", help="write the figures and a Markdown report of a saved fit into a folder")
    p.add_argument("result", metavar="RESULT.json", help="result file written by fdml fit -o")
    from . import _options as O

    O.add_output_option(
        p,
        kind="folder",
        metavar="DIR",
        help="figures and report.md (default RESULT-report beside the file)",
    )
    p.add_argument("--hz", action="store_true", help="frequency axes in Hz (default rad/s)")
    O.add_json_option(p)


def run(args) -> int:
    from ..cli import show
    from ..report import write_report  # draws on Figure objects: no display, no pyplot

    files = write_report(args.result, args.output, freq_unit="Hz" if args.hz else "rad/s")
    show(
        args,
        {"files": {k: str(v) for k, v in files.items()}},
        "\n".join(f"wrote {k:18s} {v}" for k, v in files.items()),
    )
    return 0
