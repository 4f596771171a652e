"""Issue 8, proof on real records: plain fits against fits with the effects the data ask for.

Run with ``FDML_DATA=../shared/data python benchmarks/real_records_effects.py [CASE ...]``
(cases: ``twin``, ``attas``, ``hfb``; default all).  For every record (and the Twin Otter pair
jointly) it prints

* the plain dimensional fit, what its adequacy check flags (:mod:`fdml.adequacy`) and what the
  diagnosis accepts (:func:`fdml.diagnose.diagnose`);
* the fit with the recommended effects (the diagnosis' accepted ones, or the adequacy check's
  flagged ones when the diagnosis accepts none), each record alone and jointly;
* Twin Otter: the consistency test of 017 against 018 before and after (white-noise and
  coloured-residual bounds), and the cross-prediction of each record by every parameter set
  (the data folder holds no third manoeuvre of flight 020213f1: see its README), with the
  aerodynamic and effect parameters frozen and only the nuisance terms (biases, boundary
  values) estimated on the predicted record;
* ATTAS Elv1 with (alpha, q) and with (alpha, q, a_z), with and without an alpha-sensor offset;
  HFB-320 over its 3-2-1-1 window.

Every number is computed here; nothing is pasted in.
"""

from __future__ import annotations

import math
import sys
import time
import warnings

import numpy as np

warnings.simplefilter("ignore")

from fdml import fit, make_model  # noqa: E402
from fdml.consistency import consistency  # noqa: E402
from fdml.io import data_path, load_record  # noqa: E402

DIM = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")
HZ = 2 * math.pi
TWIN_BAND = (0.1 * HZ, 1.5 * HZ, 0.02 * HZ)  # 0.1-1.5 Hz at 0.02 Hz, as SIDPAC fits these manoeuvres


def twin(n: str):
    return load_record(data_path(f"twin_otter/totter_lon_020213f1_{n}.mat"))


def base_for(recs, effects=()):
    """The dimensional model at the records' (mean) airspeed, plus ``effects``."""
    u = float(np.mean([r.meta["U"] for r in recs]))
    return make_model("dimensional", airspeed=u, effects=list(effects) or None)


def fit_with(recs, effects, opts, **kw):
    data = recs if len(recs) > 1 else recs[0]
    return fit(data, base_for(recs, effects), **opts, **kw)


def effect_params(res) -> dict:
    """The fitted effect parameters ({name: (value, stderr)}) of a result."""
    m = res.model
    root = getattr(m, "root", m)
    return {n: (res[n], res.errors[n]) for n in res.names if n in m.parameters and n not in root.parameters}


def recommended(recs, opts, outputs=None) -> tuple:
    """(flagged by the plain fit's adequacy check, accepted by the diagnosis, seconds of the diagnosis)."""
    from fdml.diagnose import diagnose

    plain = fit_with(recs, (), opts)
    flagged = tuple(e.key for e in (plain.adequacy.flagged if plain.adequacy is not None else ()))
    t0 = time.perf_counter()
    kw = {"band": opts["band"][:2]}
    if outputs:
        kw["outputs"] = list(outputs)
    rep = diagnose(recs if len(recs) > 1 else recs[0], base_for(recs), **kw)
    accepted = tuple(s["key"] for s in rep.selected)
    return plain, flagged, accepted, time.perf_counter() - t0


def _cell(res, n):
    if n not in res.names:
        return "-"
    return f"{res[n]:.4g} ± {res.errors[n]:.2g}"


def _eff_cell(res):
    ep = effect_params(res)
    return ", ".join(f"{n} {_fmt_eff(n, v, s)}" for n, (v, s) in ep.items()) or "-"


def _fmt_eff(n, v, s):
    if n.startswith("tau") or n == "T_act":
        return f"{v * 1e3:.1f} ± {s * 1e3:.1f} ms"
    return f"{v:.3g} ± {s:.2g}"


def table(rows) -> str:
    """Markdown table of (label, FitResult) rows: the six derivatives, effect parameters, cost, adequacy."""
    out = ["| fit | " + " | ".join(DIM) + " | effects | det R | flagged after |", "|---" * (len(DIM) + 4) + "|"]
    for label, res in rows:
        flag = ", ".join(e.key for e in res.adequacy.flagged) if res.adequacy is not None else "(not run)"
        out.append(
            f"| {label} | " + " | ".join(_cell(res, n) for n in DIM) + f" | {_eff_cell(res)} | "
            f"{res.cost:.3g} | {flag or 'nothing'} |"
        )
    return "\n".join(out)


def predict(params_res, target, opts):
    """Prediction of ``target`` by the parameter set of ``params_res``: model and effect parameters frozen,
    nuisance terms (biases, boundary values) estimated.  Returns (det R, per-channel residual RMS /
    measured RMS over the band)."""
    m = params_res.model
    free = [n for n in m.parameters.free_names if not n.startswith("bias_")]
    res = fit(target, m, fix=free, adequacy=False, check=False, **opts)
    sp = res.spectra[0]
    z = np.asarray(sp.z)
    v = z - res.fitted_spectra(0)
    rel = np.sqrt(np.mean(np.abs(v) ** 2, axis=0) / np.mean(np.abs(z) ** 2, axis=0))
    return res.cost, rel


def twin_otter():
    opts = {"band": TWIN_BAND}
    r17, r18 = twin("017"), twin("018")
    recs = {"017": [r17], "018": [r18], "017+018": [r17, r18]}
    print("## Twin Otter 020213f1, dimensional model, 0.1-1.5 Hz at 0.02 Hz\n")
    rec_effects = {}
    plain = {}
    for name, rr in recs.items():
        p, flagged, accepted, dt = recommended(rr, opts)
        plain[name] = p
        rec_effects[name] = accepted or flagged
        print(
            f"- {name}: plain fit flags {', '.join(flagged) or 'nothing'}; the diagnosis ({dt:.1f} s) accepts "
            f"{', '.join(accepted) or 'nothing'}"
        )
    union = tuple(dict.fromkeys(k for v in rec_effects.values() for k in v))
    eff_sets = {"time_delay:alpha": ("time_delay:alpha",)}
    if union and set(union) != {"time_delay@alpha"}:
        eff_sets["recommended (" + ", ".join(union) + ")"] = union
    fits = {("plain", n): plain[n] for n in recs}
    for label, effs in eff_sets.items():
        for name, rr in recs.items():
            fits[(label, name)] = fit_with(rr, effs, opts)
    print()
    print(table([(f"{name} {label}", fits[(label, name)]) for label in ("plain", *eff_sets) for name in recs]))
    for label in ("plain", *eff_sets):
        for cov, kw in (("white-noise", {}), ("coloured-residual", {"cov_type": "colored"})):
            if kw:
                a, b = (
                    fit_with(recs[n], () if label == "plain" else eff_sets[label], opts, **kw) for n in ("017", "018")
                )
            else:
                a, b = fits[(label, "017")], fits[(label, "018")]
            c = consistency([a, b], names=DIM)
            spread = np.abs(c.estimates[0] - c.estimates[1])
            print(f"\n### 017 against 018, {label}, {cov} bounds\n")
            print(c.summary())
            print("spread |017 - 018| per parameter: " + ", ".join(f"{n} {s:.3g}" for n, s in zip(DIM, spread)))
    print("\n### Cross-prediction (no unseen manoeuvre of flight 020213f1 in the data folder)\n")
    print("| parameter set | predicts | det R | residual/measured alpha | q | a_z |")
    print("|---|---|---|---|---|---|")
    for label in ("plain", *eff_sets):
        for src, tgt in (("017", "018"), ("018", "017")):
            cost, rel = predict(fits[(label, src)], recs[tgt][0], opts)
            print(f"| {src} {label} | {tgt} | {cost:.3g} | " + " | ".join(f"{x:.3f}" for x in rel) + " |")
        for tgt in ("017", "018"):  # the joint set predicting each record (seen in its fit)
            cost, rel = predict(fits[(label, "017+018")], recs[tgt][0], opts)
            print(f"| 017+018 {label} (seen) | {tgt} | {cost:.3g} | " + " | ".join(f"{x:.3f}" for x in rel) + " |")


def attas():
    rec = load_record(data_path("attas/fAttasElv1.mat"))
    opts = {"band": (0.3, 8.0, 0.05)}
    print("\n## ATTAS Elv1, dimensional model with output biases, 0.3-8 rad/s at 0.05 rad/s\n")
    rows = []
    for outs in ("alpha,q", "alpha,q,az"):
        o = dict(opts, outputs=outs)
        p, flagged, accepted, dt = recommended([rec], o, outputs=outs.split(","))
        print(
            f"- outputs {outs}: plain fit flags {', '.join(flagged) or 'nothing'}; the diagnosis ({dt:.1f} s) "
            f"accepts {', '.join(accepted) or 'nothing'}"
        )
        rows.append((f"{outs} plain", p))
        sets = [accepted] if accepted else []
        if outs == "alpha,q,az":
            sets += [("sensor_offset:alpha",), ("sensor_offset:alpha", "sensor_offset:az")]
        for effs in dict.fromkeys(tuple(e.replace(":", "@") for e in s) for s in sets if s):
            try:
                rows.append((f"{outs} + {', '.join(effs)}", fit_with([rec], effs, o)))
            except Exception as exc:  # a refused combination is a result too
                print(f"  {outs} + {', '.join(effs)}: refused: {exc}")
    print()
    print(table(rows))


def hfb():
    rec = load_record(data_path("hfb320/hfb320_1_10.asc"), t0=0.0, t1=20.0)
    opts = {"band": (0.3, 6.0, 0.05)}
    print("\n## HFB-320, 0-20 s (the 3-2-1-1 window), dimensional model, 0.3-6 rad/s at 0.05 rad/s\n")
    p, flagged, accepted, dt = recommended([rec], opts)
    print(
        f"- plain fit flags {', '.join(flagged) or 'nothing'}; the diagnosis ({dt:.1f} s) accepts "
        f"{', '.join(accepted) or 'nothing'}"
    )
    rows = [("plain", p)]
    for effs in dict.fromkeys(tuple(s) for s in (accepted, flagged) if s):
        rows.append((" + ".join(effs), fit_with([rec], effs, opts)))
    print()
    print(table(rows))


CASES = {"twin": twin_otter, "attas": attas, "hfb": hfb}


def main(argv=None) -> int:
    names = (argv if argv is not None else sys.argv[1:]) or list(CASES)
    t0 = time.perf_counter()
    for n in names:
        CASES[n]()
    print(f"\n(elapsed {time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
