"""What a record file looks like from its content: the format a wrong ``--format`` is told about.

:func:`check_format_fits` runs before a loader when the format is given: a
MATLAB file read as text (``--format csv`` on a .mat) or a text table read as a
MATLAB file fails deep in the reader with a codec or "corrupt file" message;
instead the user is told, in one line, the format the file looks like.
"""

from __future__ import annotations

from pathlib import Path

from ..channels import REQUIRED
from ..errors import RecordError
from ._common import check_path
from .dlr import LAYOUTS

__all__ = ["check_format_fits", "first_numeric_width", "mat_format", "sniff_format"]

#: The two families of record files: what a format's loader reads.
_FAMILY = {"sidpac": "mat", "dlr-mat": "mat", "dlr-asc": "text", "csv": "text", "csv-map": "text"}
#: Formats whose loader reads what another format's file holds (a fdml CSV can be column-mapped).
_ALSO_READS = {"csv-map": {"csv"}}
_DESCRIBE = {
    "sidpac": "a SIDPAC fdata .mat file",
    "dlr-mat": "a DLR .mat record",
    "dlr-asc": "a DLR text table",
    "csv": "fdml's CSV (t,de,alpha,q,az)",
    "csv-map": "a CSV with its own column names",
}


def first_numeric_width(p: Path) -> int:
    """The number of values on the first all-numeric line of a text file (comments ``%``/``#`` skipped).

    Parameters
    ----------
    p : Path
        The file.

    Returns
    -------
    int
        The number of values on that line.

    Raises
    ------
    RecordError
        No numeric line.
    """
    with open(p, errors="replace") as fh:
        for line in fh:
            parts = line.replace(",", " ").split()
            if not parts or parts[0][0] in "%#":
                continue
            try:
                [float(x) for x in parts]
            except ValueError:
                continue
            return len(parts)
    raise RecordError(f"{p}: no numeric data line (empty or not a record)")


def mat_format(p: Path, **kw) -> tuple[str, dict]:
    """``("sidpac", {})`` when the MAT file holds ``fdata``, else ``("dlr-mat", {"layout": ...})`` by column count.

    Parameters
    ----------
    p : Path
        The MAT file.
    **kw
        Loader options given so far (``layout``: not guessed).

    Returns
    -------
    format : str
        ``"sidpac"`` or ``"dlr-mat"``.
    options : dict
        Options the file implies (``layout``).

    Raises
    ------
    RecordError
        Neither (naming the variables), or not a readable MAT file.
    """
    from ._common import read_mat

    info = read_mat(p, names_only=True)
    names = {n: shape for n, shape, _cls in info}
    if "fdata" in names:
        return "sidpac", {}
    if "layout" in kw:
        return "dlr-mat", {}
    for shape in names.values():
        for lay, spec in LAYOUTS.items():
            if len(shape) == 2 and shape[1] == spec["n_columns"] and shape[0] > 1:
                return "dlr-mat", {"layout": lay}
    listing = ", ".join(f"{n} {shape}" for n, shape in names.items()) or "none"
    raise RecordError(
        f"{p}: a .mat file without SIDPAC's fdata or a known DLR layout "
        f"(variables: {listing}); give --format and --layout (Python: format=, layout=)"
    )


def _family(p: Path) -> str:
    """``"mat"`` (a MATLAB v5/v7.3 header), ``"binary"`` (NUL bytes: a MATLAB v4 file or no record) or ``"text"``."""
    with open(p, "rb") as fh:
        head = fh.read(4096)
    if head.startswith(b"MATLAB"):
        return "mat"
    return "binary" if b"\0" in head else "text"  # text in any 8-bit encoding (a Latin-1 degree sign) stays text


def _text_format(p: Path) -> tuple[str | None, dict]:
    """The format of a text record and its options: ``csv``/``csv-map`` by the header, ``dlr-asc`` by column count."""
    with open(p, errors="replace") as fh:
        first = next((ln for ln in fh if ln.strip() and ln.lstrip()[0] not in "%#"), "")
    cells = [c.strip() for c in first.replace(";", ",").replace("\t", ",").split(",")]
    try:
        [float(c) for c in first.replace(",", " ").split()]
    except ValueError:  # a header line
        return ("csv" if set(REQUIRED) <= set(cells) else "csv-map"), {}
    try:
        width = first_numeric_width(p)
    except RecordError:
        return None, {}
    layouts = [lay for lay, spec in LAYOUTS.items() if spec["n_columns"] == width]
    return ("dlr-asc", {"layout": layouts[0]}) if layouts else (None, {})


def _sniff(p: Path) -> tuple[str, str | None, dict, str]:
    """(family ``"mat"``, ``"text"`` or ``"binary"``; format or None; the options it implies; description)."""
    family = _family(p)
    if family == "text":
        fmt, implied = _text_format(p)
        return family, fmt, implied, _DESCRIBE[fmt] if fmt else "a text file that is not a known record layout"
    try:
        fmt, implied = mat_format(p)  # a MATLAB v4 file has no header: scipy tells
    except RecordError:
        if family == "mat":
            return family, None, {}, "a MATLAB .mat file without SIDPAC's fdata or a known DLR layout"
        return family, None, {}, "a binary file that is not a MATLAB .mat file"
    return "mat", fmt, implied, _DESCRIBE[fmt]


def sniff_format(path) -> tuple[str | None, str]:
    """The format a record file looks like from its content, and a description of it.

    Parameters
    ----------
    path : str or Path
        The record file.

    Returns
    -------
    format : str or None
        ``"sidpac"``, ``"dlr-mat"``, ``"dlr-asc"``, ``"csv"``, ``"csv-map"``, or None
        when the content fits none of them.
    description : str
        What the file looks like, for a message.
    """
    _, fmt, _, description = _sniff(check_path(path))
    return fmt, description


def check_format_fits(path, format: str, **kw) -> dict:
    """Refuse, in one line, a given format that does not fit the file, naming the format it looks like.

    Parameters
    ----------
    path : str or Path
        The record file.
    format : str
        The format given (not ``"auto"``).
    **kw
        The loader options given (``columns`` for ``csv-map``).

    Returns
    -------
    dict
        The options the file implies for that format (a DLR ``layout`` by column count),
        those given in ``kw`` left out.

    Raises
    ------
    RecordError
        The file's family (MATLAB or text) is not the format's, or its content is another
        known format; or ``csv-map`` without a column map.
    """
    if format == "csv-map" and not kw.get("columns"):
        raise RecordError(f"{path}: --format csv-map needs --columns SIG=COL,... (Python: columns=)")
    family, looks, implied, description = _sniff(check_path(path))
    if looks == format:
        return {k: v for k, v in implied.items() if k not in kw}
    if looks in _ALSO_READS.get(format, ()) or (looks is None and family == _FAMILY[format]):
        return {}
    if looks == "csv-map":
        advice = "give --columns SIG=COL,... (it implies --format csv-map)"
    elif looks:
        options = "".join(f" --{k} {v}" for k, v in implied.items())
        advice = f"give --format {looks}{options} or leave --format out"
    else:
        advice = "leave --format out"
    raise RecordError(
        f"{path}: --format {format} does not fit this file, which looks like {description}; {advice} (Python: format=)"
    )
