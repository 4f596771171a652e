"""Issue 19 on the real records: one verdict per record, from the fit's adequacy check and the diagnosis.

Run with ``FDML_DATA=../shared/data python benchmarks/real_records_verdict.py``.  For ATTAS Elv1,
HFB-320 (the whole 60 s and its 0-20 s short-period window) and the Twin Otter manoeuvres 017 and
018 (each alone and together) it prints, each from its own run:

* what the kinematics say (:mod:`fdml.kinematics`, the short-period identity; and the time-domain
  flight-path reconstruction, :func:`fdml.flightpath.check_compatibility`, where theta, V and h
  are recorded);
* the effect plain ``fdml.fit`` names first (its adequacy check's verdict) and the one
  ``fdml diagnose`` accepts first, and whether they agree;
* the recommended model: its effects, whether it is ambiguous, and its derivatives with standard
  errors beside the base model's;
* Twin Otter: the agreement of the two manoeuvres' recommended derivatives (difference over the
  combined standard error);
* HFB-320: Cm_q from the recommended M_q, against the DLR book's output-error (-27) and
  filter-error (-35) values (issue 19).  The conversion is the book's model:
  ``M_q = (S c / Iy) qbar Cm_q cbarH / V0`` with S c/Iy = 8.0027e-4 m^3/(kg m^2) (the record's
  README), rho 0.792 kg/m^3, V0 104.67 m/s and cbarH = 1.215 m, half the mean chord (the book's
  test case 4 of chapter 4, as its published code has it).

Every number is computed here; times are wall-clock seconds of this run.
"""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np

warnings.simplefilter("ignore")

import fdml  # noqa: E402
from fdml.diagnose import diagnose  # noqa: E402
from fdml.flightpath import check_compatibility  # noqa: E402
from fdml.io import data_path, load_record  # noqa: E402

DIM = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")
#: The DLR book's HFB-320 constants for Cm_q (module doc).
HFB = {"Sc_over_Iy": 8.0027e-4, "rho": 0.792, "V0": 104.67, "cbar_half": 1.215}
DLR_CMQ = {"output error": -27.0, "filter error": -35.0}


def records() -> dict:
    """The cases: name -> list of records."""
    tw = {n: load_record(data_path(f"twin_otter/totter_lon_020213f1_{n}.mat")) for n in ("017", "018")}
    return {
        "ATTAS Elv1": [load_record(data_path("attas/fAttasElv1.mat"))],
        "HFB-320 0-60 s": [load_record(data_path("hfb320/hfb320_1_10.asc"))],
        "HFB-320 0-20 s": [load_record(data_path("hfb320/hfb320_1_10.asc"), t0=0.0, t1=20.0)],
        "Twin Otter 017": [tw["017"]],
        "Twin Otter 018": [tw["018"]],
        "Twin Otter 017+018": [tw["017"], tw["018"]],
    }


def base_for(recs):
    """The dimensional model at the records' mean airspeed (fdml's model rule)."""
    return fdml.make_model("dimensional", airspeed=float(np.mean([r.meta["U"] for r in recs])))


def flight_path(recs) -> list:
    """The time-domain compatibility findings of each record with theta (one line each)."""
    out = []
    for r in recs:
        if not r.has("theta"):
            continue
        c = check_compatibility(r)
        sig = [p for p in c.params.values() if abs(p.value - p.nominal) > 3 * p.stderr]
        out.append(f"{r.name}: " + ", ".join(f"{p.name} {p.value:.4g} +- {p.stderr:.2g}" for p in sig))
    return out


def run(name: str, recs) -> dict:
    base = base_for(recs)
    data = recs if len(recs) > 1 else recs[0]
    t0 = time.perf_counter()
    res = fdml.fit(data, base)
    t_fit = time.perf_counter() - t0
    v = res.adequacy.verdict if res.adequacy is not None else None
    t0 = time.perf_counter()
    rep = diagnose(data, base)
    t_diag = time.perf_counter() - t0
    first = rep.selected[0]["key"] if rep.selected else rep.verdict
    if "input_edges" in rep.settings:  # the diagnosis found the elevator steps' timing first (theory 7a)
        first = "input_edges"
    return {
        "name": name,
        "fit_first": None if v is None else v.key,
        "fit_aliases": () if v is None else v.aliases,
        "diag_first": first,
        "agree": (v.key if v is not None else "none") == first,
        "ambiguous": rep.recommendation.get("ambiguous"),
        "alternatives": [a["effects"] for a in rep.recommendation.get("alternatives", [])],
        "kinematics": rep.kinematics,
        "effects": [e["key"] for e in rep.recommended.effects_brief()] if rep.recommended else [],
        "sizes": rep.recommended.effects_brief() if rep.recommended else [],
        "derivs": rep.recommendation.get("derivatives", {}),
        "flight_path": flight_path(recs),
        "t_fit": t_fit,
        "t_diag": t_diag,
        "plain": res,
        "recommended": rep.recommended,
    }


def show(r: dict) -> None:
    print(f"\n== {r['name']}  (fit {r['t_fit']:.2f} s, diagnose {r['t_diag']:.2f} s)")
    k = r["kinematics"]
    for m in k.get("settled", []):
        print(f"   kinematics settle {m['key']} {m['param']} = {m['value']:.4g} +- {m['stderr']:.2g} {m['unit']}")
    for a in k.get("aliases", []):
        print("   kinematics cannot attribute: " + " or ".join(f"{m['key']} {m['value']:.3g} {m['unit']}" for m in a))
    for line in r["flight_path"]:
        print(f"   flight path: {line}")
    print(f"   fit names first: {r['fit_first']} (equally: {', '.join(r['fit_aliases'])})")
    amb = " AMBIGUOUS: " + " | ".join("+".join(a) for a in r["alternatives"]) if r["ambiguous"] else ""
    print(f"   diagnose accepts first: {r['diag_first']}  -> {'agree' if r['agree'] else 'DIFFER'}{amb}")
    sizes = "; ".join(
        f"{e['key']} " + ", ".join(f"{n} {p['value']:.4g} +- {p['stderr']}" for n, p in e["parameters"].items())
        for e in r["sizes"]
    )
    print(f"   recommended: {sizes or 'the base model'}")
    for n in DIM:
        row = r["derivs"].get(n)
        if row:
            b, rc = row.get("base", [np.nan, np.nan]), row["recommended"]
            print(f"     {n:5s} base {b[0]:9.4g} +- {b[1]:<8.2g} recommended {rc[0]:9.4g} +- {rc[1]:.2g}")


def agreement(a: dict, b: dict) -> None:
    print(f"\n== agreement of {a['name']} and {b['name']} (difference / combined standard error)")
    for n in DIM:
        x, y = a["derivs"][n]["recommended"], b["derivs"][n]["recommended"]
        print(f"     {n:5s} {x[0]:9.4g} vs {y[0]:9.4g}: {(x[0] - y[0]) / np.hypot(x[1], y[1]):+.1f}")


def predict(params_res, target) -> tuple:
    """``target`` predicted by the parameter set of ``params_res``: its model's parameters frozen, the
    nuisance terms (biases, boundary values) estimated.  (det R, residual RMS / measured RMS per output)."""
    m = params_res.model
    free = [n for n in m.parameters.free_names if not n.startswith("bias_")]
    res = fdml.fit(target, m, fix=free, adequacy=False, check=False)
    z = np.asarray(res.spectra[0].z)
    v = z - res.fitted_spectra(0)
    return res.cost, np.sqrt(np.mean(np.abs(v) ** 2, axis=0) / np.mean(np.abs(z) ** 2, axis=0))


def cross_prediction(results: dict, cases: dict) -> None:
    print("\n== Twin Otter: each manoeuvre predicted by the other's parameters (a withheld manoeuvre)")
    for src, tgt in (("017", "018"), ("018", "017")):
        a, rec = results[f"Twin Otter {src}"], cases[f"Twin Otter {tgt}"][0]
        for label in ("plain", "recommended"):
            cost, rel = predict(a[label], rec)
            print(
                f"     {src} -> {tgt} {label:11s} det R {cost:.3g}; residual / measured RMS "
                + ", ".join(f"{o} {x:.3f}" for o, x in zip(("alpha", "q", "a_z"), rel))
            )


def cmq(r: dict) -> None:
    qbar = 0.5 * HFB["rho"] * HFB["V0"] ** 2
    k = HFB["Sc_over_Iy"] * qbar * HFB["cbar_half"] / HFB["V0"]
    mq, se = r["derivs"]["M_q"]["recommended"]
    inside = min(DLR_CMQ.values()) <= mq / k <= max(DLR_CMQ.values())
    print(
        f"   Cm_q = {mq / k:.1f} +- {se / k:.1f} from M_q (DLR: output error {DLR_CMQ['output error']:g}, "
        f"filter error {DLR_CMQ['filter error']:g}): {'between them' if inside else 'OUTSIDE'}"
    )


def main() -> int:
    cases = records()
    results = {}
    for name, recs in cases.items():
        results[name] = run(name, recs)
        show(results[name])
        if name.startswith("HFB"):
            cmq(results[name])
    agreement(results["Twin Otter 017"], results["Twin Otter 018"])
    cross_prediction(results, cases)
    n_agree = sum(r["agree"] for r in results.values())
    print(f"\nfit and diagnosis name the same effect first on {n_agree} of {len(results)} cases")
    return 0


if __name__ == "__main__":
    sys.exit(main())
