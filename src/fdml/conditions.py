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
    values = [_finite(r.meta.get("U")) for r in records]
    known = [v for v in values if v is not None]
    if not values or len(known) < len(values):
        return None
    return sum(known) / len(known)


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
    out = {}
    for key in RECORD_CONDITIONS:
        values = [_finite(r.meta.get(key)) for r in records]
        known = [v for v in values if v is not None]
        if values and len(known) == len(values):
            out[key] = sum(known) / len(known)
    return out


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
    found: list[Finding] = []
    if U is None:
        return found
    for r in records:
        Ur = _finite(r.meta.get("U"))
        if Ur is None or abs(U / Ur - 1.0) <= tolerance:
            continue
        found.append(
            Finding(
                "airspeed.mismatch",
                f"the model's airspeed {U:.4g} m/s differs from the record's mean airspeed {Ur:.4g} m/s by "
                f"{100 * (U / Ur - 1):+.1f} % (more than {100 * tolerance:g} %): the a_z gain U/g is wrong by that "
                "fraction; fit without --aircraft (the record's airspeed) or give --airspeed",
                kind="estimation",
                record=r.name,
                value=U,
                expected=Ur,
            )
        )
    return found
