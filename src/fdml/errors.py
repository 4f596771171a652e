"""Exceptions and warnings raised by fdml.

Every error that fdml raises on bad input is a :class:`FdmlError` (a
``ValueError``), with a message that names the offending quantity, so that a
command-line user sees one clear line instead of a traceback.
"""

from __future__ import annotations


class FdmlError(ValueError):
    """Base class for errors caused by bad input to fdml."""


class RecordError(FdmlError):
    """A flight record is unusable: NaN, uneven time, missing columns, units."""


class BandError(FdmlError):
    """A frequency band is unusable: empty, above Nyquist, too fine for the record."""


class ParameterError(FdmlError):
    """An unknown parameter name, an impossible value or inconsistent bounds."""


class AircraftError(FdmlError):
    """An aircraft description is incomplete or inconsistent."""


class OutputError(FdmlError):
    """An output path is unsafe or unwritable.

    It is one of the inputs, a device, a FIFO, a folder, or its folder cannot be written.
    """


class DataCheckError(FdmlError):
    """A data check found a problem and ``strict`` asked for it to be fatal."""


class FdmlWarning(UserWarning):
    """Base class for fdml warnings."""


class ConvergenceWarning(FdmlWarning):
    """The estimator stopped before its convergence test was met."""


class IdentifiabilityWarning(FdmlWarning):
    """The information matrix is singular, or parameters are highly correlated."""


class DataWarning(FdmlWarning):
    """The data are usable but questionable (end state far from trim, jitter)."""


class BoundsWarning(FdmlWarning):
    """An estimate ended on a bound set on its parameter (``fit(..., bounds=...)``, or a model's own).

    The likelihood's optimum may lie beyond the bound, and the estimate's
    standard error, which assumes an interior optimum, does not hold.
    """


class AdequacyWarning(FdmlWarning):
    """A fit's adequacy check (fdml.adequacy) flagged an unmodelled effect or non-white residuals."""


__all__ = [
    "FdmlError",
    "RecordError",
    "BandError",
    "ParameterError",
    "AircraftError",
    "OutputError",
    "DataCheckError",
    "FdmlWarning",
    "ConvergenceWarning",
    "IdentifiabilityWarning",
    "DataWarning",
    "BoundsWarning",
    "AdequacyWarning",
]
