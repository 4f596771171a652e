"""Warnings kept with the result they belong to.

Every fdml computation that returns a result (a fit, a batch row, a Monte
Carlo trial, a diagnosis) records the warnings raised while it ran, with
their category, in the result itself, so that none is lost when the
computation runs in a worker process or under a caller's warning filter.
:func:`recording` is the one way to do that: it catches every warning raised
inside it, keeps it as a :class:`RecordedWarning`, and (by default) raises it
again on leaving, so that the caller's own filters still decide what is shown.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from .jsoncodec import Codec

__all__ = ["RecordedWarning", "recording", "as_recorded", "merged"]


@dataclass(frozen=True)
class RecordedWarning(Codec):
    """One warning, as kept in a result.

    Parameters
    ----------
    category : str
        The warning class's name, e.g. ``"DataWarning"``.
    message : str
        The warning's text.
    """

    category: str
    message: str

    json_source = "recorded warning"

    def __str__(self) -> str:
        return f"{self.category}: {self.message}"

    @classmethod
    def from_value(cls, value) -> RecordedWarning:
        """A recorded warning from its dict, its ``"Category: message"`` string or itself.

        Parameters
        ----------
        value : RecordedWarning, dict or str
            A recorded warning, a dict with ``"category"`` and ``"message"``, or
            text; text without a ``"SomeWarning: "`` head is a ``UserWarning``.

        Returns
        -------
        RecordedWarning
            The warning.
        """
        if isinstance(value, RecordedWarning):
            return value
        if isinstance(value, dict):
            return cls(str(value.get("category", "UserWarning")), str(value.get("message", "")))
        text = str(value)
        head, sep, tail = text.partition(": ")
        if sep and head.isidentifier() and head.endswith("Warning"):
            return cls(head, tail)
        return cls("UserWarning", text)


def as_recorded(values: Iterable) -> tuple[RecordedWarning, ...]:
    """Recorded warnings from dicts, strings or recorded warnings, first occurrence of each kept.

    Parameters
    ----------
    values : iterable
        Warnings in any form :meth:`RecordedWarning.from_value` accepts.

    Returns
    -------
    tuple of RecordedWarning
        The distinct warnings, in order of first occurrence.
    """
    return tuple(dict.fromkeys(RecordedWarning.from_value(v) for v in values))


@contextmanager
def recording(reemit: bool = True) -> Iterator[list[RecordedWarning]]:
    """Record every warning raised inside the block.

    Parameters
    ----------
    reemit : bool
        Raise each recorded warning again on leaving the block (through
        :func:`warnings.warn_explicit`, with its original category and place),
        so that the caller's filters decide whether it is shown. ``False``
        where the result that keeps them is all the caller will see.

    Yields
    ------
    list of RecordedWarning
        Filled when the block ends, first occurrence of each warning only.

    Examples
    --------
    >>> import warnings
    >>> with recording(reemit=False) as log:
    ...     warnings.warn("ends far from trim", UserWarning)
    >>> [str(w) for w in log]
    ['UserWarning: ends far from trim']
    """
    log: list[RecordedWarning] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield log
        finally:
            seen = list(caught)
    firsts: dict[tuple[str, str], warnings.WarningMessage] = {}  # (category, message) -> first caught
    for w in seen:
        firsts.setdefault((w.category.__name__, str(w.message)), w)
    log.extend(RecordedWarning(*key) for key in firsts)
    if reemit:
        for w in firsts.values():
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def merged(*groups: Iterable) -> tuple[RecordedWarning, ...]:
    """The warnings of several records of one computation, each message once, first category kept.

    For a fit run under :func:`recording`: ``merged(log, result.warnings)``
    keeps what was caught with its category, and adds what the result holds
    only as text (a result that keeps messages without their category).

    Parameters
    ----------
    *groups : iterable
        Groups of warnings in any form :meth:`RecordedWarning.from_value` accepts.

    Returns
    -------
    tuple of RecordedWarning
        One warning per distinct message, in order of first occurrence.
    """
    out: dict[str, RecordedWarning] = {}
    for w in as_recorded(itertools.chain(*groups)):
        out.setdefault(w.message, w)
    return tuple(out.values())
