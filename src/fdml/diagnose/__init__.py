"""Sim-to-real gap diagnosis: where the model misses the data, which unmodelled effect causes it,
and how far the gap shrinks once that effect is added.

=====================  =================================================================
module                 job
=====================  =================================================================
:mod:`.data`           the analysis grid (2x the independent spacing 2 pi/T per record)
:mod:`.likelihood`     fits under a band-wise noise model; LR = 2 (C0 - C1) / K
:mod:`.locate`         the gap map: coherent vs incoherent residual per channel x band,
                       noise floor, gain/phase error with bounds, F tests, Holm/BH
:mod:`.attribute`      screen, refits, Holm, BIC, ambiguity; the score (LM) screen and the
                       chi2 / chi-bar-square / Davies nulls are :mod:`fdml.score`'s, shared
                       with every fit's adequacy check
:mod:`.disturbance`    unmeasured turbulence on the input-incoherent residual
:mod:`.shrink`         shrink, footprint, compensation, parameter shifts, hold-out fits
:mod:`.report`         labels, verdict, JSON; :mod:`.text` the paragraph; :mod:`.plots`
:mod:`.core`           :func:`diagnose`
:mod:`.truth`          validation truths (time-domain, one withheld effect)
:mod:`.validation`     the validation harness
=====================  =================================================================

The candidate effects and their open registry are :mod:`fdml.models.effects` (their public
home: the effect classes, the registry, ``register_effect``), built on
:mod:`fdml.models.augment` (what an effect is) and :mod:`fdml.models.effect_library` (the
built-in ones, lift_lag ... unmeasured_gust); their validation truths are in :mod:`.truth`.

Example::

    import fdml
    from fdml.diagnose import diagnose

    rep = diagnose(records, fdml.make_model("steady", "navion"), holdout=other_record)
    print(rep.verdict, rep.summary())
    rep.to_json("diagnosis.json"); rep.plot("diagnosis.png")
"""

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


__all__ = ["diagnose", "validate", "DiagnosisReport", "JSON_KEYS"]
