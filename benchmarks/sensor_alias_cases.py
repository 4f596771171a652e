"""Issue 19's aliased sensor cases on records that no fdml code made: what a user gets.

The records come from ``tests/independent_truth.py`` (a scipy ``solve_ivp`` simulation of the
dimensional short-period model with the sensors applied in the time domain; the Navion's
derivatives).  Each run does what a user does::

    res = fdml.fit(rec, fdml.make_model("dimensional", "navion"))        # plain fit + adequacy
    rep = fdml.diagnose.diagnose(rec, fdml.make_model("dimensional", "navion"))

and keeps: the plain fit's first flagged effect (its one-step size), the diagnosis's accepted
effects with their sizes as the recommended fit has them, whether the recommended model is
flagged ambiguous (issue 19 item 3, a field that may not exist yet: see :func:`flagged_ambiguous`),
the recommended derivatives with standard errors against the truth, and the worst
|estimate - truth| / stderr.  A **confident wrong answer** is a recommended derivative more than
:data:`WRONG_Z` standard errors from the truth while the recommendation is not flagged ambiguous.

Cases (issue 19): a, alpha-vane offset 2.5 m; b+/b-, accelerometer offset +1.5 / -2.5 m; c, alpha
and a_z lag q by 100 ms; d, alpha lags 20 ms; e, no effect (false alarm); f, q lags 40 ms.

Seed s fixes everything a real record varies: the sample interval, manoeuvre and elevator edge
shape (:func:`rotation`: s = 0..5 covers dt 0.02, 0.01, 0.04 on a 3-2-1-1, then on a doublet,
with raised-cosine, linear and true-step edges), the edge width (0.05-0.2 s), the first edge's
time off the sample grid, the initial alpha and q (off trim), and the noise.  Every case uses the
same details for a seed, so case e with seed s is the clean twin of the others.  A true step
between samples is, to a fit that interpolates the record, an elevator timing error of up to
dt/2 (the truth's ``step_offsets``; the table shows the largest, in ms): the summary counts
confident wrong answers on smooth-edged records apart.

Usage::

    python benchmarks/sensor_alias_cases.py [--quick] [--seeds N] [--cases a,c] [--noise 0.03] [--input-edges auto]

``--quick``: seed 0 only (dt 0.02 s, 3-2-1-1), about 4 s a run.  Rows go to
benchmarks/output/sensor_alias_cases.jsonl (not committed), one JSON line per run.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import fdml
from fdml.diagnose import diagnose

HERE = Path(__file__).resolve().parent
OUT = HERE / "output" / "sensor_alias_cases.jsonl"
DERIVS = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")
#: A derivative this many standard errors from the truth is "wrong" (the issue's criterion).
WRONG_Z = 3.0
DTS = (0.02, 0.01, 0.04)
KINDS = ("3211", "doublet")
#: Pulse unit per manoeuvre, s: 0.3 s puts the 3-2-1-1's power around the Navion's short period
#: (about 4.3 rad/s); a doublet of 0.5 s units peaks near 2.3/0.5 = 4.6 rad/s.
UNITS = {"3211": 0.3, "doublet": 0.5}
DURATION = 12.0
AMPLITUDE = 0.02  # rad


def _load_truth():
    """tests/independent_truth.py as a module (the tests' simulator; not part of the package)."""
    name = "independent_truth"
    if name not in sys.modules:  # under pytest the tests may have imported it already
        spec = importlib.util.spec_from_file_location(name, HERE.parent / "tests" / "independent_truth.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod  # dataclasses look their module up by name
        spec.loader.exec_module(mod)
    return sys.modules[name]


truth_sim = _load_truth()


@dataclass(frozen=True)
class Case:
    """One truth: its label, sensors and the effect keys that name it.

    ``names`` holds the key sets that describe the truth exactly (an empty set: no effect).
    """

    label: str
    sensors: object
    names: tuple


CASES = {
    "a": Case("alpha vane 2.5 m ahead", truth_sim.Sensors(x_alpha=2.5), (frozenset({"sensor_offset@alpha"}),)),
    "b+": Case("accelerometer 1.5 m ahead", truth_sim.Sensors(x_az=1.5), (frozenset({"sensor_offset@az"}),)),
    "b-": Case("accelerometer 2.5 m aft", truth_sim.Sensors(x_az=-2.5), (frozenset({"sensor_offset@az"}),)),
    "c": Case(
        "alpha, az lag q 100 ms",
        truth_sim.Sensors(delays={"alpha": 0.1, "az": 0.1}),
        # the timing group itself, or the same timing said in two parts: alpha and az late, or elevator
        # late and q early
        (
            frozenset({"time_delay@alpha,az"}),
            frozenset({"time_delay@alpha", "time_delay@az"}),
            frozenset({"time_delay@de", "time_delay@q"}),
        ),
    ),
    "d": Case("alpha lags 20 ms", truth_sim.Sensors(delays={"alpha": 0.02}), (frozenset({"time_delay@alpha"}),)),
    "e": Case("no effect", truth_sim.Sensors(), (frozenset(),)),
    "f": Case("q lags 40 ms", truth_sim.Sensors(delays={"q": 0.04}), (frozenset({"time_delay@q"}),)),
}


def rotation(seed: int) -> tuple[float, str, str]:
    """The sample interval (s), manoeuvre kind and edge shape of a seed.

    Seeds 0..5 cover every (dt, kind) pair and every edge shape with each kind; seed 0 is the
    issue's record (50 Hz, 3-2-1-1, smooth edges).
    """
    n = len(DTS)
    return DTS[seed % n], KINDS[(seed // n) % len(KINDS)], truth_sim.EDGES[(seed + seed // n) % len(truth_sim.EDGES)]


def make_record(case: str, seed: int, *, dt: float | None = None, kind: str | None = None, noise: float = 0.03):
    """The record of one case and seed, and its truth (see the module doc for what the seed varies).

    Parameters
    ----------
    case : str
        A key of :data:`CASES`.
    seed : int
        Seeds the record's details and noise.
    dt : float, optional
        Sample interval, s (default: the seed's, :func:`rotation`).
    kind : {"3211", "doublet"}, optional
        Manoeuvre (default: the seed's).
    noise : float, optional
        White noise as a fraction of each channel's RMS.

    Returns
    -------
    (Record, dict)
        The record and the truth (tests/independent_truth.py's dict).
    """
    dt0, kind0, edge = rotation(seed)
    dt, kind = dt0 if dt is None else dt, kind0 if kind is None else kind
    rng = np.random.default_rng(seed)
    man = truth_sim.Manoeuvre(
        kind=kind,
        amplitude=AMPLITUDE,
        start=1.0 + rng.uniform(0.0, 1.0) * dt,  # the first edge between two samples
        unit=UNITS[kind],
        edge=edge,
        width=rng.uniform(0.05, 0.2),
    )
    x0 = (rng.uniform(-1, 1) * 0.005, rng.uniform(-1, 1) * 0.02)  # off trim: up to 0.3 deg and 1.1 deg/s
    return truth_sim.simulate_record(
        man, CASES[case].sensors, dt=dt, duration=DURATION, x0=x0, noise=noise, rng=rng, name=f"{case}-{seed}"
    )


def flagged_ambiguous(report) -> bool | None:
    """Whether the diagnosis flags its recommended model ambiguous (issue 19 item 3).

    Looks for ``recommended.ambiguous``, then ``report.alternatives``, then the recommended
    brief's ``"ambiguous"``; None when fdml has none of them (today's code).
    """
    v = (getattr(report, "recommendation", None) or {}).get("ambiguous")
    if v is not None:
        return bool(v)
    rec = report.recommended
    for v in (getattr(rec, "ambiguous", None), getattr(report, "alternatives", None)):
        if v is not None:
            return bool(v)
    if rec is not None:
        v = rec.brief().get("ambiguous")
        if v is not None:
            return bool(v)
    return None


def derivative_table(res) -> tuple[dict, float | None, str | None]:
    """Derivatives of a fit against the truth: ``{name: [est, stderr, truth]}``, the worst z and its name."""
    if res is None:
        return {}, None, None
    p, e = res.params, res.errors
    tab = {n: [float(p[n]), float(e[n]), truth_sim.NAVION[n]] for n in DERIVS}
    z = {n: abs(v - t) / s if s > 0 and math.isfinite(s) else math.inf for n, (v, s, t) in tab.items()}
    worst = max(z, key=z.get)
    return tab, float(z[worst]), worst


def _num(x) -> float:
    """A brief's stderr as a float: None (held fixed) is nan, the string "inf" is inf."""
    return math.nan if x is None else float(x)


def effect_sizes(res) -> list:
    """The fit's effects as it has them: ``[{"key", "params": {name: [value, stderr]}}]``."""
    if res is None:
        return []
    return [
        {"key": e["key"], "params": {k: [v["value"], _num(v["stderr"])] for k, v in e["parameters"].items()}}
        for e in res.effects_brief()
    ]


def _fit_part(rec, base, input_edges: str | None = None) -> dict:
    t0 = time.perf_counter()
    res = fdml.fit(rec, base, **({} if input_edges is None else {"input_edges": input_edges}))
    flagged = res.adequacy.flagged if res.adequacy is not None else ()
    verdict = res.adequacy.verdict if res.adequacy is not None else None
    tab, wz, wn = derivative_table(res)
    if verdict is not None:  # the check's one ranking (issue 19): what the diagnosis would accept first
        first, size = verdict.key, {k: v for k, (v, _) in verdict.params.items()}
    else:
        first, size = (flagged[0].key, dict(flagged[0].expected)) if flagged else (None, {})
    return {
        "first": first,
        "first_size": size,
        "first_aliases": list(verdict.aliases) if verdict is not None else [],
        "flagged": [e.key for e in flagged],
        "residual_flags": [c.name for c in res.adequacy.residual_flags] if res.adequacy is not None else [],
        "derivs": tab,
        "worst_z": wz,
        "worst": wn,
        "elapsed": time.perf_counter() - t0,
    }


def _diagnose_part(rec, base, input_edges: str | None = None) -> dict:
    t0 = time.perf_counter()
    rep = diagnose(rec, base, input_edges=input_edges)
    elapsed = time.perf_counter() - t0
    tab, wz, wn = derivative_table(rep.recommended)
    return {
        "verdict": rep.verdict,
        "status": rep.status,
        "accepted": [s["key"] for s in rep.selected],
        "labels": [s.get("label") for s in rep.selected],
        "effects": effect_sizes(rep.recommended),
        "equally_consistent": list(rep.ambiguous),  # today's report list, not the recommended flag
        "recommended_ambiguous": flagged_ambiguous(rep),
        "alternatives": len(getattr(rep, "alternatives", None) or ()),
        "derivs": tab,
        "worst_z": wz,
        "worst": wn,
        "elapsed": elapsed,
    }


def run_case(
    case: str,
    seed: int,
    *,
    dt: float | None = None,
    kind: str | None = None,
    noise: float = 0.03,
    input_edges: str | None = None,
) -> dict:
    """Simulate one case, run plain fit and the diagnosis on it, and score them.

    Parameters
    ----------
    case : str
        A key of :data:`CASES`.
    seed : int
        Seeds the record (see :func:`make_record`).
    dt, kind, noise : optional
        As in :func:`make_record`.
    input_edges : {"none", "estimated", "auto"}, optional
        The elevator steps' timing terms of the fit and the diagnosis (docs/theory.md section 7a);
        default: each one's own default.

    Returns
    -------
    dict
        JSON-ready row: the record's details, ``fit`` and ``diagnose`` parts, and the scores
        ``fit_names_truth``, ``diagnose_names_truth`` (first flagged / accepted effect belongs to
        the truth; for the clean case: nothing flagged / accepted), ``diagnose_exact`` (the accepted
        set describes the truth exactly) and ``confident_wrong``.
    """
    rec, truth = make_record(case, seed, dt=dt, kind=kind, noise=noise)
    base = fdml.make_model("dimensional", "navion")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the fits' warnings are kept in their results
        fit_part = _fit_part(rec, base, input_edges)
        diag_part = _diagnose_part(rec, base, input_edges)
    names = CASES[case].names
    allowed = set().union(*names)

    def names_truth(first):
        first = None if first == "input_edges" else first  # the steps' timing (theory 7a) names no effect
        return first is None if not allowed else first in allowed

    accepted = diag_part["accepted"]
    wz = diag_part["worst_z"]
    return {
        "case": case,
        "label": CASES[case].label,
        "seed": seed,
        "truth": truth,
        "fit": fit_part,
        "diagnose": diag_part,
        "fit_names_truth": names_truth(fit_part["first"]),
        "diagnose_names_truth": names_truth(accepted[0] if accepted else None),
        "diagnose_exact": frozenset(accepted) in names,
        "confident_wrong": None if wz is None else bool(wz > WRONG_Z and not diag_part["recommended_ambiguous"]),
    }


# --- the table ------------------------------------------------------------------------------------------------


def _size(d: dict) -> str:
    return ", ".join(f"{k} {v:+.3g}" for k, v in d.items())


def _effects(effects: list) -> str:
    if not effects:
        return "none"
    return "; ".join(
        f"{e['key']} " + ", ".join(f"{k} {v:+.3g}±{s:.2g}" for k, (v, s) in e["params"].items()) for e in effects
    )


def format_row(r: dict) -> str:
    """One run as one line of the table."""
    f, d = r["fit"], r["diagnose"]
    advice = f"{f['first']} ({_size(f['first_size'])})" if f["first"] else "adequate"
    derivs = " ".join(f"{v:+.3f}±{s:.3f}" for v, s, _ in d["derivs"].values()) if d["derivs"] else "no recommended fit"
    wz = "-" if d["worst_z"] is None else f"{d['worst_z']:.1f} {d['worst']}"
    amb = {None: "n/a", True: "yes", False: "no"}[d["recommended_ambiguous"]]
    off = r["truth"]["step_offsets"]
    edge = f"step{1e3 * max(off, key=abs):+.1f}" if off else r["truth"]["manoeuvre"]["edge"]
    return (
        f"{r['case']:3s} {r['seed']:2d} {r['truth']['dt']:.2f} {r['truth']['manoeuvre']['kind']:7s} "
        f"{edge:9s} | fit: {advice} | diagnose: {_effects(d['effects'])} "
        f"[also: {','.join(d['equally_consistent']) or '-'}] amb {amb} | {derivs} | worst z {wz}"
        f"{' CONFIDENT WRONG' if r['confident_wrong'] else ''}"
    )


def summary(rows: list) -> list[str]:
    """Per case: runs, how often plain fit and the diagnosis name the truth first, exact sets, confident wrong.

    ``conf.wrong`` counts every run; ``smooth`` the runs with raised-cosine or linear edges only.
    """
    out = [
        f"{'case':4s} {'truth':26s} {'runs':>4s} {'fit 1st':>7s} {'diag 1st':>8s} {'exact':>6s} "
        f"{'conf.wrong':>10s} {'smooth':>7s}"
    ]
    for case in CASES:
        rs = [r for r in rows if r["case"] == case]
        if not rs:
            continue
        n = len(rs)
        cnt = {k: sum(bool(r[k]) for r in rs) for k in ("fit_names_truth", "diagnose_names_truth", "diagnose_exact")}
        cw = sum(bool(r["confident_wrong"]) for r in rs)
        sm = [r for r in rs if r["truth"]["manoeuvre"]["edge"] != "step"]
        cws = sum(bool(r["confident_wrong"]) for r in sm)
        out.append(
            f"{case:4s} {CASES[case].label:26s} {n:4d} {cnt['fit_names_truth']:4d}/{n:<2d} "
            f"{cnt['diagnose_names_truth']:5d}/{n:<2d} {cnt['diagnose_exact']:3d}/{n:<2d} {cw:7d}/{n:<2d} "
            f"{cws:4d}/{len(sm):<2d}"
        )
    return out


def main(argv=None) -> int:
    """Run the cases and print the table and the summary."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="seed 0 only")
    p.add_argument("--seeds", type=int, default=6, help="seeds 0..N-1 per case (default 6: every dt and manoeuvre)")
    p.add_argument("--cases", default=",".join(CASES), help="comma-separated case keys")
    p.add_argument("--noise", type=float, default=0.03, help="noise, fraction of each channel's RMS")
    p.add_argument(
        "--input-edges",
        default=None,
        choices=("none", "estimated", "auto"),
        help="the steps' timing terms (default: fdml.fit's and diagnose's defaults)",
    )
    a = p.parse_args(argv)
    cases = [c for c in a.cases.split(",") if c]
    bad = [c for c in cases if c not in CASES]
    if bad:
        p.error(f"unknown case {bad[0]!r}: use one of {', '.join(CASES)}")
    seeds = [0] if a.quick else list(range(a.seeds))
    OUT.parent.mkdir(exist_ok=True)
    truth = " ".join(f"{n} {truth_sim.NAVION[n]:+.4f}" for n in DERIVS)
    print(f"truth: {truth}; noise {a.noise:g} of RMS; recommended derivatives in the order {', '.join(DERIVS)}")
    rows = []
    with OUT.open("w") as fh:
        for case in cases:
            for seed in seeds:
                r = run_case(case, seed, noise=a.noise, input_edges=a.input_edges)
                rows.append(r)
                fh.write(json.dumps(r, default=float) + "\n")
                fh.flush()
                print(format_row(r), flush=True)
    print()
    print("\n".join(summary(rows)))
    times = [r["diagnose"]["elapsed"] for r in rows]
    print(f"diagnose: median {np.median(times):.2f} s, max {max(times):.2f} s per call; rows in {OUT}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
