"""Sim-to-real gap diagnosis: where the model misses the data, which unmodelled effect causes it,
and how far the gap shrinks once that effect is added.

=====================  =================================================================
module                 job
=====================  =================================================================
:mod:`.data`           the analysis grid (2x the independent spacing 2 pi/T per record)
:mod:`.likelihood`     fits under a band-wise noise model; LR = 2 (C0 - C1) / K
:mod:`.locate`         the gap map: coherent vs incoherent residual per channel x band,
                       noise floor, gain/phase error with bounds, F tests, Holm/BH
:mod:`.screen`         score (LM) screen, aliasing, minimum detectable effect (in
                       :mod:`fdml.score`, shared with every fit's adequacy check)
:mod:`.attribute`      refits, chi2 / chi-bar-square / Davies nulls (:mod:`fdml.score`), Holm,
                       BIC, ambiguity
:mod:`.disturbance`    unmeasured turbulence on the input-incoherent residual
:mod:`.shrink`         shrink, footprint, compensation, parameter shifts, hold-out fits
:mod:`.report`         labels, verdict, JSON; :mod:`.text` the paragraph; :mod:`.plots`
:mod:`.core`           :func:`diagnose`
:mod:`.truth`          validation truths (time-domain, one withheld effect)
:mod:`.validation`     the validation harness
=====================  =================================================================

The candidate effects and their open registry are :mod:`fdml.models.augment` (what an effect
is), :mod:`fdml.models.effect_library` (the built-in ones, lift_lag ... unmeasured_gust) and
:mod:`fdml.models.effects` (the registry); the names a user needs are re-exported here.

Example::

    import fdml
    from fdml.diagnose import diagnose

    rep = diagnose(records, fdml.make_model("steady", "navion"), holdout=other_record)
    print(rep.verdict, rep.summary())
    rep.to_json("diagnosis.json"); rep.plot("diagnosis.png")
"""

from ..models.effects import (
    AugmentedModel,
    Effect,
    FreeParameterEffect,
    MatrixEffect,
    OutputEffect,
    Param,
    default_library,
    get_effect,
    register_effect,
    registered_effects,
    scale_rows,
    unregister_effect,
)
from .core import diagnose
from .report import JSON_KEYS, DiagnosisReport


def validate(*args, **kwargs):
    """Run the validation harness (see :func:`fdml.diagnose.validation.validate`).

    Parameters
    ----------
    *args, **kwargs
        Arguments of :func:`fdml.diagnose.validation.validate`.

    Returns
    -------
    ValidationResult
        The scored scenarios.
    """
    from .validation import validate as _v

    return _v(*args, **kwargs)


__all__ = [
    "diagnose",
    "validate",
    "DiagnosisReport",
    "JSON_KEYS",
    "Effect",
    "OutputEffect",
    "MatrixEffect",
    "FreeParameterEffect",
    "Param",
    "AugmentedModel",
    "register_effect",
    "unregister_effect",
    "get_effect",
    "registered_effects",
    "default_library",
    "scale_rows",
]
