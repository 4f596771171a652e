"""fdml: frequency-domain maximum-likelihood identification of the short period.

Data flow: :class:`Record` -> :func:`spectra` -> model (:func:`make_model`)
-> :func:`fit` -> :class:`FitResult` (summary, JSON, plots).

Heavy or optional parts (plotting, the command line) are imported lazily.
"""

from __future__ import annotations

__version__ = "0.1.0"

from .aircraft import Aircraft, get_aircraft, list_aircraft, load_aircraft
from .errors import (
    AircraftError,
    BandError,
    ConvergenceWarning,
    DataWarning,
    FdmlError,
    FdmlWarning,
    IdentifiabilityWarning,
    ParameterError,
    RecordError,
)
from .estimate import fit
from .models import MODEL_KINDS, Model, make_model
from .parameters import Parameter, Parameters
from .record import Record, read_csv
from .results import FitResult, load_result
from .spectra import FrequencyData, spectra

__all__ = [
    "__version__",
    "Aircraft",
    "get_aircraft",
    "list_aircraft",
    "load_aircraft",
    "AircraftError",
    "BandError",
    "ConvergenceWarning",
    "DataWarning",
    "FdmlError",
    "FdmlWarning",
    "IdentifiabilityWarning",
    "ParameterError",
    "RecordError",
    "fit",
    "MODEL_KINDS",
    "Model",
    "make_model",
    "Parameter",
    "Parameters",
    "Record",
    "read_csv",
    "FitResult",
    "load_result",
    "FrequencyData",
    "spectra",
]
