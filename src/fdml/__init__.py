"""fdml: frequency-domain maximum-likelihood identification of the short period.

Data flow: :class:`Record` -> :func:`spectra` -> model (:func:`make_model`)
-> :func:`fit` -> :class:`FitResult` (summary, JSON, plots).

Names are imported on first use (PEP 562), so ``import fdml`` and the command
line start fast and load scipy or matplotlib only when a task needs them.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: public name -> module that defines it
_LAZY = {
    "Aircraft": "aircraft",
    "get_aircraft": "aircraft",
    "list_aircraft": "aircraft",
    "load_aircraft": "aircraft",
    "AircraftError": "errors",
    "BandError": "errors",
    "ConvergenceWarning": "errors",
    "DataWarning": "errors",
    "FdmlError": "errors",
    "FdmlWarning": "errors",
    "IdentifiabilityWarning": "errors",
    "ParameterError": "errors",
    "RecordError": "errors",
    "fit": "estimate",
    "FitOptions": "fit_options",
    "EstimatorSettings": "estimate",
    "MODEL_KINDS": "models",
    "Model": "models",
    "make_model": "models",
    "with_effects": "models",
    "Parameter": "parameters",
    "Parameters": "parameters",
    "Role": "parameters",
    "Slot": "parameters",
    "execute": "parallel",
    "Record": "record",
    "read_csv": "record",
    "load_record": "io",
    "FitResult": "results",
    "RecordedWarning": "warning_log",
    "load_result": "results",
    "compare_steady_unsteady": "compare",
    "fit_time_domain": "timefit",
}

# spectra() lives in fdml.spectral, so the function never hides a module of its name;
# it is bound eagerly (numpy only).  The simulator and the consistency test stay in
# their modules (fdml.simulate.simulate, fdml.consistency.consistency): they load scipy.
from .spectral import FrequencyData, spectra  # noqa: E402

__all__ = ["__version__", "FrequencyData", "spectra", *_LAZY]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'fdml' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
