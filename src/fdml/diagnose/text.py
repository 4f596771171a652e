"""The plain-language paragraph of a diagnosis."""

from __future__ import annotations

import math

__all__ = ["paragraph"]

_UNIT_SCALE = {"s": (1e3, "ms")}


def _fmt_param(name: str, d: dict) -> str:
    v, se, unit = d.get("value"), d.get("stderr"), d.get("unit", "")
    if v is None:
        return name
    k, u = _UNIT_SCALE.get(unit, (1.0, unit))
    s = f"{name} = {k * v:.3g}"
    if _finite(se):
        s += f" ± {k * se:.2g}"
    return s + (f" {u}" if u and u != "-" else "")


def _finite(x) -> bool:
    return x is not None and math.isfinite(x)


def _where(c, whole) -> str:
    """``at LO-HI rad/s``, or ``across the band`` for a cell that spans the whole analysis band."""
    if whole is not None and all(math.isclose(a, b, rel_tol=1e-6) for a, b in zip(c["band"], whole)):
        return "across the band"
    return f"at {c['band'][0]:.3g}-{c['band'][1]:.3g} rad/s"


def _errors(c) -> str:
    bits = []
    if c.get("gain_db") is not None:
        bits.append(f"{c['gain_db']:+.2f} dB")
    if c.get("phase_deg") is not None:
        bits.append(f"{c['phase_deg']:+.1f} deg")
    p = c.get("p_holm")
    ptxt = f", p = {p:.1g}" if p is not None else ""
    return f"measured/model {', '.join(bits)}{ptxt}"


def _cell_phrase(c, whole=None) -> str:
    return f"{c['channel']} {_where(c, whole)} ({_errors(c)})"


def _misses(flagged: list, whole) -> str:
    """The sentence on the flagged cells, worst first; cells that all span the band are said to be across it."""
    if all(_where(c, whole) == "across the band" for c in flagged):
        worst = flagged[0]
        return (
            f"The model misses the measured {', '.join(c['channel'] for c in flagged)} across the band "
            f"({whole[0]:.3g}-{whole[1]:.3g} rad/s, the gap map's only band); "
            f"worst: {worst['channel']} ({_errors(worst)})."
        )
    return (
        "The model misses the measured "
        + "; ".join(_cell_phrase(c, whole) for c in flagged[:3])
        + (f"; {len(flagged) - 3} more cell(s)" if len(flagged) > 3 else "")
        + "."
    )


def _p(p) -> str:
    if p is None:
        return "-"
    return f"{p:.2g}" if p >= 1e-300 else "< 1e-300"


def _kinematics_sentences(rep) -> list:
    """What the short-period identity said about the sensors, and what it did with it."""
    k = getattr(rep, "kinematics", None) or {}
    out = [
        f"The kinematics (alpha, q and a_z obey the short-period identity whatever the aerodynamics) settle "
        f"{m['key']} ({_fmt_param(m['param'], m)}, LR {m['lr']:.3g}): it enters the recommended model fixed at "
        "that value, its uncertainty carried into the standard errors."
        for m in k.get("settled", [])
    ]
    out += [
        f"The kinematics' other reading, {m['key']} ({_fmt_param(m['param'], m)}), lies outside its plausible range."
        for m in k.get("implausible", [])
    ]
    out += _flight_path_sentences(k)
    for a in k.get("aliases", []):
        names = " or ".join(f"{m['key']} ({_fmt_param(m['param'], m)})" for m in a)
        out.append(
            f"The kinematics show a sensor error they cannot attribute: {names}; the aerodynamic fit chose "
            "among them first."
        )
    return out


def _flight_path_sentences(k: dict) -> list:
    """The time-domain flight-path reconstruction's view beside the identity's (where theta is recorded)."""
    out = []
    offset = any(m["key"].startswith("sensor_offset") for m in k.get("settled", []) + sum(k.get("aliases", []), []))
    for e in k.get("flight_path", []):
        sig = e.get("significant")
        if not sig:
            continue
        found = ", ".join(_fmt_param(p["name"], p) for p in sig)
        note = (
            " (it models no vane offset: a vane x ahead of the accelerometer reads there as an alpha lag of about x/U)"
            if offset and any(p["name"] == "tau_alpha" for p in sig)
            else ""
        )
        used = ", ".join(c for c in ("theta", "V", "h", "ax") if c not in e.get("missing", []))
        out.append(f"The flight-path reconstruction of {e['record']} ({used}) finds {found}{note}.")
    missing = sorted({c for e in k.get("flight_path", []) for c in e.get("missing", [])})
    if missing:
        out.append(
            f"The records lack {', '.join(missing)}: the kinematics rest on the short-period identity "
            "(alpha, q and a_z) there."
        )
    return out


#: What separates two kinds of alias, by the effects involved.
_SEPARATE = (
    (
        {"sensor_offset@alpha", "sensor_offset@az"},
        'give the sensor positions in the aircraft file ("sensors": {"alpha": {"x": m}, "az": {"x": m}}): '
        "alpha, q and a_z see only the difference of the two positions",
    ),
    (
        {"time_delay@alpha", "sensor_offset@alpha", "time_delay@alpha,az"},
        "a delay and a vane offset part at high frequency: a manoeuvre with more energy above the short-period "
        "frequency (a sweep or a multisine to twice it; fdml design --criterion discriminate) separates them, "
        "as does the vane's known position",
    ),
)


def _ambiguity_sentences(rep) -> list:
    rec = getattr(rep, "recommendation", None) or {}
    if not rec.get("ambiguous"):
        return ["Equally consistent with these data: " + ", ".join(rep.ambiguous) + "."] if rep.ambiguous else []
    alts = rec.get("alternatives", [])
    keys = {a["effects"][-1] for a in alts}
    spread = rec.get("spread", {})
    worst = max(spread.items(), key=lambda kv: kv[1].get("in_stderr") or 0.0, default=None)
    out = [
        "These data cannot tell apart "
        + " or ".join(
            f"{a['effects'][-1]} ({', '.join(_fmt_param(n, d) for n, d in a['params'].items())})" for a in alts
        )
        + ": the recommended model is ambiguous."
    ]
    if worst is not None and worst[1].get("in_stderr") is not None:
        n, d = worst
        out.append(
            f"Their derivatives spread most in {n}, {d['min']:.4g} to {d['max']:.4g} "
            f"({d['in_stderr']:.1f} standard errors)."
        )
    how = [txt for ks, txt in _SEPARATE if len(keys & ks) >= 2]
    out.append(
        "To separate them: "
        + ("; ".join(how) if how else "fdml design --criterion discriminate plans a manoeuvre that does")
        + "."
    )
    return out


def paragraph(rep) -> str:
    """A short paragraph: where the model misses, what explains it, how much, and what is left.

    Parameters
    ----------
    rep : DiagnosisReport
        The diagnosis.

    Returns
    -------
    str
        The paragraph, plain text.
    """
    st = rep.settings
    out = [
        f"Base: {st.get('base_model')}, {len(st.get('records', []))} record(s), "
        f"{st['band'][0]:.3g}-{st['band'][1]:.3g} rad/s, {st.get('independent_frequencies')} independent "
        "frequencies."
    ]
    out += _kinematics_sentences(rep)
    for key in ("input_edges", "input_edges_alternative"):  # the elevator steps' timing (theory 7a)
        if isinstance(st.get(key), str):
            out.append(st[key])
    whole = st.get("band")
    flagged = [c for c in rep.location if c.get("significant")]
    if flagged:
        flagged.sort(key=lambda c: -(c.get("excess") or 0))
        out.append(_misses(flagged, whole))
    else:
        out.append(
            "The gap map flags no channel-band cell: in every band the base model's error is within "
            "what the noise floor allows (small effects can still be found by the targeted tests)."
        )
    sel = [s for s in rep.selected if s.get("source") != "kinematics"]
    if sel:
        for i, s in enumerate(sel):
            params = ", ".join(_fmt_param(k, v) for k, v in s["params"].items())
            shtxt = (
                f"explains {100 * s['shrink']:.0f} % of the coherent gap in the flagged cells"
                if s.get("shrink") is not None
                else "is significant although no cell was flagged"
            )
            if s.get("shrink_holdout") is not None and s.get("shrink_in_sample") is not None:
                shtxt += f" (held out; in-sample {100 * s['shrink_in_sample']:.0f} %)"
            lead = "Cause" if i == 0 else "A further effect"
            kin = s.get("kinematic")
            kin_txt = (
                "; the kinematics alone give " + ", ".join(_fmt_param(k, v) for k, v in kin.items()) if kin else ""
            )
            out.append(
                f"{lead}: {s['effect']} on {s['channel']} ({params}, as the recommended model has it{kin_txt}) "
                f"{shtxt}; LR = {s['lr']:.1f}, p = {_p(s.get('p_holm'))} after Holm; label {s['label']}."
            )
            if i == 0:
                fp = [f for f in rep.footprint if f.get("effect") == s["key"] and f.get("share")]
                if fp:
                    top = max(fp, key=lambda f: f["share"])
                    out.append(
                        f"It acts mostly on {top['channel']} {_where(top, whole)} ({100 * top['share']:.0f} % "
                        "of its footprint)."
                    )
        shifts = (sel[0].get("parameter_shifts") or {}).items()
        big = sorted(
            ((k, v) for k, v in shifts if _finite(v.get("shift_in_stderr")) and abs(v["shift_in_stderr"]) >= 2),
            key=lambda kv: -abs(kv[1]["shift_in_stderr"]),
        )[:3]
        if big:
            out.append(
                "Without it the base estimates were biased: "
                + ", ".join(
                    f"{k} {v['base']:.4g} -> {v['augmented']:.4g} ({v['shift_in_stderr']:+.1f} s.e.)" for k, v in big
                )
                + "."
            )
        g = next((r for r in rep.ranking if r["effect"] == "unmeasured_gust" and r.get("significant")), None)
        if g:
            out.append(
                f"Unmeasured turbulence is also present (sigma_w = {g['params']['sigma_w']['value']:.2g} m/s, "
                f"p = {_p(g['p_holm'])})."
            )
    elif len(sel) < len(rep.selected):
        out.append("No further effect is significant at the family level once the sensors are settled.")
    elif rep.verdict == "unmeasured_gust":
        g = next(r for r in rep.ranking if r["effect"] == "unmeasured_gust")
        out.append(
            f"Cause: unmeasured turbulence (sigma_w = {g['params']['sigma_w']['value']:.2g} m/s) explains "
            f"{100 * g['shrink']:.0f} % of the input-incoherent residual power; LR = {g['lr']:.1f}, "
            f"p = {_p(g['p_holm'])}."
        )
    else:
        out.append(f"No candidate effect is significant at the family level {st.get('alpha')}: verdict none.")
    out += _ambiguity_sentences(rep)
    parts = []
    for where, lead in (("in-sample", "in-sample"), ("holdout", "on the held-out record")):
        cells = [u for u in rep.unexplained if u.get("where") == where]
        if cells:
            parts.append(f"{lead} " + "; ".join(_cell_phrase(u, whole) for u in cells[:3]))
    if parts:
        out.append("Still unexplained: " + " and ".join(parts) + ".")
    elif sel:
        out.append("No flagged cell remains after the final model.")
    return " ".join(out)
