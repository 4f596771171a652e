"""Flight condition from the records: the airspeed a model uses, where it came from, and a mismatch check.

SIDPAC and DLR files carry the true airspeed (``record.meta["U"]``: its mean
over the window, m/s) and, where the file has them, density, mass, pitch
inertia and geometry (``rho``, ``mass``, ``Iy``, ``S_w``, ``c_w``, ``b``; see
:mod:`fdml.io.sidpac` and :mod:`fdml.io.dlr`).  The dimensional model needs
only U (the a_z gain U/g, docs/theory.md Eq. 5); the others are reported, not used.

A model whose U differs from the record's by more than
:data:`AIRSPEED_TOLERANCE` gets an ``airspeed.mismatch`` finding: the a_z gain
U/g is then wrong by that fraction, and the a_z-borne estimates (Z_a, CL_a)
with it.
"""

from __future__ import annotations

import math

from .findings import Finding

__all__ = [
    "AIRSPEED_TOLERANCE",
    "RECORD_CONDITIONS",
    "airspeed_findings",
    "airspeed_rule",
    "attach_conditions",
    "model_provenance",
    "record_airspeed",
    "record_conditions",
]

#: Relative airspeed difference above which a model and a record disagree: the
#: a_z gain U/g is wrong by the same fraction, which exceeds the few-percent
#: scatter of a record's airspeed over a manoeuvre and of a preset's nominal U.
AIRSPEED_TOLERANCE = 0.05
#: Flight-condition keys a record's meta may carry (SI), besides U.
RECORD_CONDITIONS = ("rho", "mass", "Iy", "S_w", "c_w", "b")


def _finite(x) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) and v > 0 else None


def _mean(records, key: str) -> float | None:
    """The mean of the records' ``meta[key]``, or None when there are none or any lacks a finite positive one."""
    values = [_finite(r.meta.get(key)) for r in records]
    known = [v for v in values if v is not None]
    return sum(known) / len(known) if known and len(known) == len(values) else None


def record_airspeed(records) -> float | None:
    """The mean of the records' airspeeds (``meta["U"]``, m/s), or None when any record lacks one.

    Parameters
    ----------
    records : sequence of Record
        The records.

    Returns
    -------
    float or None
        The mean airspeed, m/s.
    """
    return _mean(records, "U")


def record_conditions(records) -> dict:
    """Flight-condition values every record carries (``rho``, ``mass``, ...), averaged over the records.

    Parameters
    ----------
    records : sequence of Record
        The records.

    Returns
    -------
    dict of str to float
        Each key of :data:`RECORD_CONDITIONS` that every record carries (finite),
        with its mean, in the meta data's (SI) unit.
    """
    means = {key: _mean(records, key) for key in RECORD_CONDITIONS}
    return {key: v for key, v in means.items() if v is not None}


def airspeed_findings(model, records, tolerance: float = AIRSPEED_TOLERANCE) -> list[Finding]:
    """An ``airspeed.mismatch`` finding (kind ``estimation``) per record whose U differs from the model's.

    Parameters
    ----------
    model : Model
        Its ``U`` (m/s) is the airspeed of the a_z gain.
    records : sequence of Record
        Records without ``meta["U"]`` are skipped.
    tolerance : float, optional
        Relative difference allowed (default :data:`AIRSPEED_TOLERANCE`).

    Returns
    -------
    list of Finding
        The mismatches (empty when the model has no airspeed).
    """
    U = _finite(getattr(model, "U", None))
    if U is None:
        return []
    found = []
    for r in records:
        Ur = _finite(r.meta.get("U"))
        if Ur is not None and abs(U / Ur - 1.0) > tolerance:
            text = (
                f"the model's airspeed {U:.4g} m/s differs from the record's mean airspeed {Ur:.4g} m/s by "
                f"{100 * (U / Ur - 1):+.1f} % (more than {100 * tolerance:g} %): the a_z gain U/g is wrong by that "
                f"fraction; give --airspeed {Ur:.4g}, or leave out --airspeed and --aircraft: the dimensional "
                "model then takes the record's airspeed"
            )
            found.append(Finding("airspeed.mismatch", text, kind="estimation", record=r.name, value=U, expected=Ur))
    return found


def airspeed_rule(kind: str, aircraft, airspeed: float | None, records) -> tuple[float | None, str]:
    """The airspeed of the model rule and where it comes from: ``(U, source)``.

    The rule (``fdml fit``, ``fdml batch`` and :class:`fdml.batch.ModelSpec` alike): a given
    ``airspeed`` wins (source ``"given"``); a model with an aircraft takes the aircraft's
    (``(None, "aircraft")``); the dimensional model without either takes the records' mean
    airspeed (source ``"record"``; U is None when a record carries none).

    Parameters
    ----------
    kind : str
        The base model kind (``"dimensional"``, ``"unsteady"``, ...).
    aircraft : object or None
        The aircraft given, if any.
    airspeed : float or None
        The airspeed given, m/s.
    records : sequence of Record
        The records the model is for.

    Returns
    -------
    tuple
        ``(U, source)``: the airspeed in m/s (None: the aircraft's, or none found) and
        ``"given"``, ``"aircraft"`` or ``"record"``.
    """
    if airspeed is not None:
        return float(airspeed), "given"
    if aircraft is not None or kind != "dimensional":
        return None, "aircraft"
    return record_airspeed(records), "record"


def model_provenance(kind: str, model_source: str, model, airspeed_source: str, records) -> dict:
    """A result's provenance: the model, its airspeed and where it came from, the lag constants, the records' condition.

    Parameters
    ----------
    kind : str
        The base model kind.
    model_source : str
        How the kind was chosen (``"--model"``, ``"model rule"``, ``"model spec"``).
    model : Model
        The model built; its ``U`` (m/s) and, for the unsteady model, its aircraft's lag constants.
    airspeed_source : str
        Where the airspeed came from (:func:`airspeed_rule`'s source, or an option's name).
    records : sequence of Record
        The records fitted.

    Returns
    -------
    dict
        ``{"model", "airspeed", ["lag_constants"], ["record_conditions"]}``, plain data.
    """
    from .aircraft import lag_provenance

    out: dict = {
        "model": {"kind": kind, "source": model_source},
        "airspeed": {"value": float(model.U), "unit": "m/s", "source": airspeed_source},
    }
    aircraft = getattr(model, "aircraft", None)
    if kind == "unsteady" and aircraft is not None:
        out["lag_constants"] = lag_provenance(aircraft)
    cond = record_conditions(records)
    if cond:
        out["record_conditions"] = cond
    return out


def attach_conditions(res, model, records, provenance: dict):
    """The fit result with its provenance and any ``airspeed.mismatch`` finding (also issued as a warning).

    Parameters
    ----------
    res : FitResult
        The result of fitting ``model`` to ``records``.
    model : Model
        The model fitted.
    records : sequence of Record
        The records fitted.
    provenance : dict
        As :func:`model_provenance` makes it.

    Returns
    -------
    FitResult
        ``res`` with ``provenance`` and the findings appended.
    """
    from dataclasses import replace

    from .findings import emit

    found = airspeed_findings(model, records)
    emit(found)
    return replace(res, provenance=provenance, findings=tuple(res.findings) + tuple(found))
