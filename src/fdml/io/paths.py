"""Where the shared flight records live.

The real flight records are not part of fdml (none carries an open licence).
The environment variable ``FDML_DATA`` names the folder that holds them (for
example ``FDML_DATA=../shared/data``); otherwise pass a record's path
explicitly.  fdml never searches the directory tree for a data folder: a
package that finds data by where it happens to be installed or run from
reads different files on different machines.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import RecordError

__all__ = ["data_dir", "data_path", "DATA_ENV"]

#: Environment variable naming the data folder.
DATA_ENV = "FDML_DATA"


def data_dir() -> Path:
    """The shared data folder: ``$FDML_DATA``, which must be a directory.

    Returns
    -------
    pathlib.Path
        The folder, with ``~`` expanded.

    Raises
    ------
    RecordError
        ``FDML_DATA`` is unset, or not a directory; the message names it.
    """
    env = os.environ.get(DATA_ENV)
    if not env:
        raise RecordError(
            f"{DATA_ENV} is not set: set {DATA_ENV}=/path/to/shared/data (the folder of the "
            "flight records), or pass a record's path explicitly"
        )
    p = Path(env).expanduser()
    if not p.is_dir():
        raise RecordError(f"{DATA_ENV}={env} is not a directory")
    return p


def data_path(relative: str) -> Path:
    """Path of a file in the shared data folder, which must exist.

    Parameters
    ----------
    relative : str
        Path inside the data folder, e.g. ``"twin_otter/totter_lon_020213f1_017.mat"``.

    Returns
    -------
    pathlib.Path
        The file's path.

    Raises
    ------
    RecordError
        Naming the file and where it was looked for.
    """
    try:
        root = data_dir()
    except RecordError as exc:
        raise RecordError(f"flight record {relative} not found: {exc}") from None
    p = root / relative
    if not p.is_file():
        raise RecordError(f"flight record {relative} not found: looked for {p} ({DATA_ENV}={os.environ[DATA_ENV]})")
    return p
