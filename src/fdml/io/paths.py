"""Where the shared flight records live.

The real flight records are not part of fdml (none carries an open licence);
they sit in ``../shared/data`` beside the checkout, or wherever the
environment variable ``FDML_DATA`` points.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import RecordError

__all__ = ["data_dir", "data_path", "DATA_ENV"]

#: Environment variable naming the data folder.
DATA_ENV = "FDML_DATA"


def _candidates() -> list[Path]:
    out = []
    for start in (Path.cwd(), Path(__file__).resolve().parent):
        for d in (start, *start.parents):
            c = d / "shared" / "data"
            if c not in out:
                out.append(c)
    return out


def data_dir() -> Path:
    """The shared data folder.

    ``$FDML_DATA`` when set (it must be a directory); otherwise the first
    ``shared/data`` found walking up from the current directory, then from
    the installed package.

    Raises
    ------
    RecordError
        Saying where it looked.
    """
    env = os.environ.get(DATA_ENV)
    if env:
        p = Path(env).expanduser()
        if not p.is_dir():
            raise RecordError(f"{DATA_ENV}={env} is not a directory")
        return p
    cands = _candidates()
    for c in cands:
        if c.is_dir():
            return c
    raise RecordError(
        f"no shared data folder: {DATA_ENV} is not set and no shared/data exists above {Path.cwd()} "
        f"or above the fdml package ({Path(__file__).resolve().parent}); set {DATA_ENV}=/path/to/shared/data"
    )


def data_path(relative: str) -> Path:
    """Path of a file in the shared data folder, which must exist.

    Parameters
    ----------
    relative : str
        Path inside the data folder, e.g. ``"twin_otter/totter_lon_020213f1_017.mat"``.

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
        how = f"{DATA_ENV}={os.environ[DATA_ENV]}" if os.environ.get(DATA_ENV) else "found by walking up"
        raise RecordError(f"flight record {relative} not found: looked for {p} (data folder {root}, {how})")
    return p
