"""Command-line options for reading records (``fdml fit``, ``check``, ``diagnose``, ``batch``).

Kept free of heavy imports: ``fdml --help`` builds every parser.
"""

from __future__ import annotations

import argparse

from ..channels import FORMATS
from ..errors import RecordError

__all__ = ["add_record_arguments", "record_options", "parse_mapping"]


def add_record_arguments(p: argparse.ArgumentParser) -> None:
    """Add --format, --t0, --t1, --columns, --units, --sign, --layout, --variable, --delimiter, --no-unit-check.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser; the options go in a group "reading records".
    """
    g = p.add_argument_group("reading records")
    g.add_argument(
        "--format", default=None, choices=FORMATS, help="record format (default auto: by extension and content)"
    )
    g.add_argument("--t0", type=float, metavar="S", help="window start, s")
    g.add_argument("--t1", type=float, metavar="S", help="window end, s")
    g.add_argument(
        "--columns",
        metavar="SIG=COL,...",
        help="CSV column map, e.g. t=time,de=elev,alpha=AOA,q=q,az=nz (implies --format csv-map)",
    )
    g.add_argument(
        "--units", metavar="SIG=UNIT,...", help="units of the mapped columns, e.g. de=deg,alpha=deg,q=deg/s,az=g"
    )
    g.add_argument("--sign", metavar="SIG=+-1,...", help="sign flips of mapped columns, e.g. az=-1 for n_z up")
    g.add_argument("--layout", choices=("hfb320", "attas"), help="DLR column layout (default: by column count)")
    g.add_argument("--variable", metavar="NAME", help="DLR .mat: the record matrix's name (default: the only one)")
    g.add_argument(
        "--delimiter",
        metavar="CHAR",
        help="column-mapped CSV: the field separator (default: found from the header; 'whitespace' for spaces)",
    )
    g.add_argument(
        "--no-unit-check",
        dest="check_units",
        action="store_false",
        default=None,
        help="accept angles that look like degrees (a real record with large angles)",
    )


def parse_mapping(text: str | None, what: str) -> dict[str, str]:
    """``"a=b,c=d"`` -> ``{"a": "b", "c": "d"}``; a RecordError names a malformed item.

    Parameters
    ----------
    text : str or None
        The option's value; None or empty gives an empty dict.
    what : str
        The option's name without dashes, for the error message.

    Returns
    -------
    dict of str to str
        The items, names and values stripped.
    """
    out: dict[str, str] = {}
    for item in text.split(",") if text else []:
        k, sep, v = item.partition("=")
        if not sep or not k.strip() or not v.strip():
            raise RecordError(f"--{what}: expected NAME=VALUE items separated by commas, got {item!r}")
        out[k.strip()] = v.strip()
    return out


def _sign(signal: str, text: str) -> int:
    """``"-1"`` -> -1; anything but exactly +1 or -1 (``-1.9``, ``2``, ``x``) is a RecordError."""
    try:
        value = float(text)
    except ValueError:
        value = None
    if value not in (1.0, -1.0):
        raise RecordError(
            f"--sign {signal}={text}: a sign must be +1 or -1; scale factors go in --units (e.g. az=m/s^2)"
        )
    return int(value)


def record_options(args) -> dict:
    """Keyword arguments for :func:`fdml.io.load_record` from parsed arguments.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of a command with :func:`add_record_arguments`.

    Returns
    -------
    dict
        ``format``, ``t0``, ``t1`` and, where given, ``columns``, ``units``,
        ``sign``, ``layout``, ``variable``, ``delimiter`` and ``check_units``.
    """
    opts: dict = {"format": args.format or ("csv-map" if args.columns else "auto"), "t0": args.t0, "t1": args.t1}
    columns, units, signs = (parse_mapping(getattr(args, key), key) for key in ("columns", "units", "sign"))
    if (units or signs) and not columns:
        raise RecordError("--units and --sign apply to a column-mapped CSV: give --columns too")
    given = {
        "columns": columns,
        "units": units,
        "sign": {k: _sign(k, v) for k, v in signs.items()},
        "layout": args.layout,
        "variable": args.variable,
        "delimiter": args.delimiter,
    }
    opts.update({k: v for k, v in given.items() if v})
    if args.check_units is False:
        opts["check_units"] = False
    return opts
