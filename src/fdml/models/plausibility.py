"""Is a derivative set physical?  Sign rules and the tail's lever arm, per model kind.

Two effects that the data cannot tell apart can imply very different derivative sets: with free
dimensional derivatives an alpha-vane offset x and an accelerometer offset -x are one model
(reparametrise alpha' = alpha - x q/U), and the second choice moves Z_de by x M_de/U.  What the
record cannot say, the airframe can:

* **signs** that hold for any conventional aircraft in the short period: lift grows with alpha
  (Z_a < 0, Cz_a < 0, CLa_w > 0), pitch rate is damped (M_q < 0, Cm_q < 0), and a trailing-edge-down
  elevator (fdml's positive de) lifts its surface, so its normal force is negative (Z_de <= 0,
  Cz_de <= 0) whether the surface is a tail, a canard or an elevon;
* **the tail's lever arm** (dimensional and derivatives models with the aircraft's mass, pitch
  inertia and tail arm l_t): the elevator's force Z_delta acts l_t behind the c.g., so
  M_delta = l_t Z_delta (body z down), i.e. ``Z_de = M_de Iy / (m U l_t)`` and
  ``Cz_de = Cm_de c / l_t``.  The elevator also changes the wing's lift a little and l_t is to the
  tail's aerodynamic centre, so the rule allows Z_de from 0 to :data:`LEVER_FACTOR` times the lever-arm
  value.

A rule is broken only when the estimate lies beyond it by more than :data:`MARGIN` standard errors,
so a rule never overrides what the data can resolve.
"""

from __future__ import annotations

import math

__all__ = ["derivative_problems", "SIGN_RULES", "MARGIN", "LEVER_FACTOR"]

#: Standard errors beyond a rule at which an estimate breaks it (a 0.13 % one-sided false alarm).
MARGIN = 3.0
#: Largest ratio of |Z_de| (|Cz_de|) to its lever-arm value M_de Iy/(m U l_t) (Cm_de c/l_t) still
#: physical: the wing's share of the elevator's lift and the tail's aerodynamic centre off l_t.
LEVER_FACTOR = 3.0

#: Per parameter: the sign it must have (-1 negative, +1 positive) and why.
SIGN_RULES = {
    "Z_a": (-1, "lift grows with alpha"),
    "Cz_a": (-1, "lift grows with alpha"),
    "CLa_w": (+1, "lift grows with alpha"),
    "M_q": (-1, "pitch rate is damped"),
    "Cm_q": (-1, "pitch rate is damped"),
    "Z_de": (-1, "a trailing-edge-down elevator lifts its surface"),
    "Cz_de": (-1, "a trailing-edge-down elevator lifts its surface"),
}


def _sign_problems(values: dict, stderr: dict) -> list:
    out = []
    for name, (sign, why) in SIGN_RULES.items():
        if name not in values:
            continue
        v, se = float(values[name]), float(stderr.get(name, 0.0) or 0.0)
        if sign * v < -MARGIN * (se if math.isfinite(se) else math.inf):
            out.append(f"{name} = {v:+.3g} +- {se:.2g} has the wrong sign ({why})")
    return out


def _lever_problem(model, values: dict, stderr: dict) -> list:
    """The lever-arm rule, where the model's aircraft gives mass, pitch inertia and tail arm."""
    ac = getattr(model, "aircraft", None)
    got = [getattr(ac, k, None) for k in ("mass", "Iy", "l_t")]
    if not all(isinstance(x, (int, float)) and x > 0 for x in got):
        return []
    m, Iy, lt = (float(x) for x in got)  # type: ignore[arg-type]
    if "Z_de" in values and "M_de" in values:
        name, pred = "Z_de", float(values["M_de"]) * Iy / (m * float(model.U) * lt)
    elif "Cz_de" in values and "Cm_de" in values:
        c = getattr(ac, "c_w", None)
        if not (isinstance(c, (int, float)) and c > 0):
            return []
        name, pred = "Cz_de", float(values["Cm_de"]) * c / lt
    else:
        return []
    v, se = float(values[name]), float(stderr.get(name, 0.0) or 0.0)
    lo, hi = sorted((0.0, LEVER_FACTOR * pred))
    if v < lo - MARGIN * se or v > hi + MARGIN * se:
        return [
            f"{name} = {v:+.3g} +- {se:.2g} lies outside 0 .. {LEVER_FACTOR:g} x its lever-arm value {pred:+.3g} "
            f"(the elevator's force acts l_t = {lt:.3g} m behind the c.g.)"
        ]
    return []


def derivative_problems(model, values: dict, stderr: dict | None = None) -> list:
    """The physical rules a fitted derivative set breaks (empty when it is plausible).

    Parameters
    ----------
    model : Model
        The fitted model (its aircraft gives mass, pitch inertia, tail arm and chord).
    values : dict
        Estimates by parameter name, each in its unit.
    stderr : dict, optional
        Their standard errors (default 0: the rules apply exactly).

    Returns
    -------
    list of str
        One sentence per broken rule.
    """
    stderr = stderr or {}
    return _sign_problems(values, stderr) + _lever_problem(model, values, stderr)
