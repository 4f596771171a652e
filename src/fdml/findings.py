"""Findings: what a check found, with a stable short code a user can filter on.

A :class:`Finding` is the unit in which fdml reports a questionable property
of the data (``units.elevator``, ``channels.swapped``, ``coherence.q``) or of
an estimate.  Findings are emitted as warnings (:class:`~fdml.errors.DataWarning`
for data findings) *and* kept in the result that they concern, so that no
command loses them; ``--strict`` turns the data findings into errors
(:class:`~fdml.errors.DataCheckError`, exit code 2).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from dataclasses import dataclass

from .errors import DataCheckError, DataWarning
from .jsoncodec import Codec, text

__all__ = ["Finding", "emit", "raise_if_strict", "KINDS"]

#: ``data``: the record is probably not what its labels say (units, signs,
#: channels, duplicates, no response); ``estimation``: the estimate is
#: questionable (correlation, convergence).  Only data findings are made fatal
#: by ``--strict``.
KINDS = ("data", "estimation")


@dataclass(frozen=True)
class Finding(Codec):
    """One finding of a check.

    Parameters
    ----------
    code : str
        Stable short code, ``area.item`` (for example ``units.elevator``).
    message : str
        One sentence that names the quantity, its value and the likely cause.
    kind : {"data", "estimation"}
        What the finding is about: the record's data or the estimation.
    record : str or None
        Name of the record concerned, if one.
    value : float or None
        The checked quantity (a slope, a unit factor, a coherence), if one.
    expected : float or None
        What the quantity should be for a record in fdml's units and signs.
    """

    code: str
    message: str
    kind: str = "data"
    record: str | None = None
    value: float | None = None
    expected: float | None = None

    json_fields = {"kind": text(choices=KINDS)}
    json_source = "finding"

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"finding kind must be one of {KINDS}, got {self.kind!r}")

    def __str__(self) -> str:
        where = f"{self.record}: " if self.record else ""
        return f"[{self.code}] {where}{self.message}"


def emit(findings: Iterable[Finding], stacklevel: int = 2) -> None:
    """Issue every finding as a :class:`~fdml.errors.DataWarning` (text ``[code] message``).

    Parameters
    ----------
    findings : iterable of Finding
        The findings to issue.
    stacklevel : int
        Stack level of the warning, counted from the caller of :func:`emit`.
    """
    for f in findings:
        warnings.warn(str(f), DataWarning, stacklevel=stacklevel + 1)


def raise_if_strict(findings: Iterable[Finding], strict: bool) -> None:
    """With ``strict``, raise :class:`~fdml.errors.DataCheckError` listing every data finding.

    Parameters
    ----------
    findings : iterable of Finding
        The findings of a check; only those of kind ``"data"`` count.
    strict : bool
        Whether to raise (``--strict``); without it this does nothing.
    """
    bad = [f for f in findings if f.kind == "data"] if strict else []
    if bad:
        raise DataCheckError("data check failed (--strict): " + "; ".join(str(f) for f in bad))
