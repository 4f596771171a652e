"""Proof on data whose effect is withheld: the validation harness.

Each run simulates a record (and an independent hold-out record of another
manoeuvre) from a truth that is the base model plus exactly one effect
(:mod:`fdml.diagnose.truth`), or no effect, or an effect outside the library,
and runs :func:`fdml.diagnose.diagnose` blind with the base model.  The
scores (docs/diagnosis_method.md 3.2) are

* the confusion matrix, truth effect by verdict;
* detection (any verdict), top-1 attribution (verdict = truth), in-set (truth
  in the verdict's ambiguity set), the right channel;
* the false-alarm rate on no-effect records, white and coloured sensor noise,
  with Wilson 95 % intervals;
* the median hold-out shrink when the truth is the verdict;
* for an effect outside the library, how often it is labelled ``partial`` (or
  no verdict) rather than confidently wrong (``confirmed``).

Seeds: the *tuning* range (``seed_base = 0``) is where the label threshold
is chosen (:func:`tune_threshold`); the *report* range (``seed_base =
REPORT_SEED_BASE``) is where the figures come from.  The two never overlap.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
import time
from collections import Counter, defaultdict
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..jsoncodec import dumps, json_text, loads
from ..parallel import execute, one_line
from ..warning_log import merged, recording
from .report import SHRINK_CONFIRM, UNEXPLAINED_RULE, label_for
from .truth import OUT_OF_LIBRARY, simulate_truth

__all__ = [
    "Scenario",
    "scenarios",
    "run_scenario",
    "validate",
    "ValidationResult",
    "score",
    "tune_threshold",
    "wilson",
    "REPORT_SEED_BASE",
    "TRUTHS",
    "NULLS",
]

#: First seed of the report range (the tuning range starts at 0 and stays far below).
REPORT_SEED_BASE = 1_000_000
#: Analysis band of the validation, rad/s.
BAND = (0.3, 12.0)
#: Measured-gust RMS (m/s) for the gust-lag truths.
GUST_STD = 1.5
MANEUVERS = ("3211", "doublet", "multisine")
#: Sensor noise levels (fraction of each channel's RMS): 1 % is where the weak effects (the textbook
#: downwash lag, l_t/U at full share) become identifiable on a 20 s record; 3 and 6 % as before.
NOISES = (0.01, 0.03, 0.06)
HOLDOUT_OF = {"3211": "doublet", "doublet": "3211", "multisine": "multisine"}

#: Truths: key -> (small values, large values).  Sizes are physical ("small" near detectability at
#: 6 % noise, "large" a clearly visible effect).
TRUTHS = {
    "lift_lag@alpha": ({"y_w": 0.2}, {"y_w": 0.4}),
    "downwash_lag@q": ({"G": 0.15}, {"G": 0.5}),
    # the textbook form: the downwash reaches the tail l_t/U late (0.086 s on the Navion), simulated as a
    # transport delay (truth.py); "small" is half of it
    "downwash_lag@tail": ({"tau_dw": 0.043}, {"tau_dw": 0.086}),
    "gust_lag@alpha_w": ({"b1": 3.0}, {"b1": 7.5}),
    "time_delay@de": ({"tau_de": 0.015}, {"tau_de": 0.04}),
    "time_delay@q": ({"tau_q": 0.015}, {"tau_q": 0.04}),
    "actuator_lag@de": ({"T_act": 0.02}, {"T_act": 0.05}),
    "sensor_offset@az": ({"x_az": 0.5}, {"x_az": 1.5}),
    "sensor_offset@alpha": ({"x_alpha": 1.0}, {"x_alpha": 3.0}),
    "structural_mode@q,az": (
        {"r_q": 0.01, "r_az": 0.01, "omega_s": 9.0, "zeta_s": 0.04},
        {"r_q": 0.03, "r_az": 0.03, "omega_s": 9.0, "zeta_s": 0.04},
    ),
    "sensor_scale@alpha": ({"k_alpha": 0.04}, {"k_alpha": 0.1}),
    "unmeasured_gust": ({"sigma_w": 0.25}, {"sigma_w": 0.5}),
    "vane_filter": ({"omega_f": 10.0, "zeta_f": 0.3}, {"omega_f": 7.0, "zeta_f": 0.3}),
}
#: Null cases: name -> noise kind.
NULLS = {"none-white": "white", "none-coloured": "coloured"}


@dataclass(frozen=True)
class Scenario:
    """One validation run.

    Parameters
    ----------
    truth : str or None
        Key of the withheld effect (None for a null case).
    values : dict
        Its parameter values by name, each in its unit.
    size : str
        ``"small"`` or ``"large"`` (``"-"`` for a null case).
    maneuver : str
        ``"3211"``, ``"doublet"`` or ``"multisine"``.
    noise : float
        Sensor noise standard deviation as a fraction of each channel's RMS.
    noise_kind : str
        ``"white"`` or ``"coloured"``.
    seed : int
        Seed of the record (the hold-out record's is derived from it).
    case : str
        The case it is scored under (the truth key, or the null's name).
    """

    truth: str | None
    values: dict
    size: str
    maneuver: str
    noise: float
    noise_kind: str
    seed: int
    case: str = ""

    @property
    def truth_name(self) -> str:
        """The withheld effect's name, or ``"none"`` for a null case."""
        return "none" if self.truth is None else self.truth.split("@")[0]


def scenarios(
    *, n_effect: int = 4, n_null: int = 34, seed_base: int = REPORT_SEED_BASE, truths=None, nulls=None
) -> list:
    """The scenario list of the validation.

    Every truth x size x manoeuvre x noise level x ``n_effect`` seeds, and every null x
    manoeuvre x noise level x ``n_null`` seeds.

    Parameters
    ----------
    n_effect : int, optional
        Seeds per truth, size, manoeuvre and noise level.
    n_null : int, optional
        Seeds per null case, manoeuvre and noise level.
    seed_base : int, optional
        First seed; each scenario takes the next.
    truths : sequence of str, optional
        Keys of :data:`TRUTHS` (default all).
    nulls : sequence of str, optional
        Names of :data:`NULLS` (default all).

    Returns
    -------
    list of Scenario
        The scenarios, seeds distinct.
    """
    seeds = itertools.count(seed_base)
    out = [
        Scenario(key, dict(vals), size, man, nz, "white", next(seeds), key)
        for key in (TRUTHS if truths is None else truths)
        for size, vals in zip(("small", "large"), TRUTHS[key])
        for man, nz, _ in itertools.product(MANEUVERS, NOISES, range(n_effect))
    ]
    return out + [
        Scenario(None, {}, "-", man, nz, NULLS[name], next(seeds), name)
        for name in (NULLS if nulls is None else nulls)
        for man, nz, _ in itertools.product(MANEUVERS, NOISES, range(n_null))
    ]


def _base(sc: Scenario):
    from ..models import make_model

    return make_model("steady", "navion", gust=sc.truth == "gust_lag@alpha_w")


def run_scenario(sc: Scenario, *, diagnose_options: dict | None = None) -> dict:
    """Simulate one scenario (record + hold-out), diagnose it blind, return a flat row.

    The row's ``warnings`` (JSON text of ``"Category: message"`` strings) are
    every warning the diagnosis raised or kept; ``n_warnings`` counts them.

    Parameters
    ----------
    sc : Scenario
        The run.
    diagnose_options : dict, optional
        Keyword arguments of :func:`fdml.diagnose.diagnose`.

    Returns
    -------
    dict
        The scenario, the verdict, label, shrink and test figures, the elapsed
        time (s) and the warnings.
    """
    from .core import diagnose

    base = _base(sc)
    kw: dict[str, Any] = dict(noise=sc.noise, noise_kind=sc.noise_kind, gust_std=GUST_STD)
    t0 = time.perf_counter()
    rec = simulate_truth(base, sc.truth, sc.values, maneuver=sc.maneuver, seed=sc.seed, **kw)
    hold = simulate_truth(base, sc.truth, sc.values, maneuver=HOLDOUT_OF[sc.maneuver], seed=sc.seed + 7_919_000, **kw)
    row = _scenario_columns(sc)
    try:
        with recording(reemit=False) as log:  # hundreds of runs: counted in the row, not shown
            rep = diagnose(rec, base, holdout=hold, band=BAND, **(diagnose_options or {}))
    except Exception as exc:  # a crash is a result too: recorded, never hidden
        row.update(status=f"error: {type(exc).__name__}: {exc}", verdict="error", verdict_key="error")
        return row
    warned = merged(log, rep.warnings)
    sel = rep.selected[0] if rep.selected else None
    if sel is None and rep.verdict == "unmeasured_gust":
        sel = next((r for r in rep.ranking if r["effect"] == "unmeasured_gust"), None)
    tr = next((r for r in rep.ranking if sc.truth and sc.truth in (r["key"], r["effect"]) and r["step"] == 0), None)
    row.update(
        status=rep.status,
        verdict=rep.verdict,
        verdict_key=sel["key"] if sel else "none",
        label=sel["label"] if sel else None,
        ambiguous=dumps(rep.ambiguous, indent=None),
        ambiguous_names=dumps(sorted({a.split("@")[0] for a in rep.ambiguous}), indent=None),
        n_accepted=len(rep.selected),
        second=rep.selected[1]["key"] if len(rep.selected) > 1 else None,
        shrink=sel.get("shrink") if sel else None,
        shrink_in_sample=sel.get("shrink_in_sample") if sel else None,
        shrink_holdout=sel.get("shrink_holdout") if sel else None,
        flagged_for_label=sel.get("n_flagged") if sel else None,
        plausible=sel.get("plausible", True) if sel else None,
        flagged_before=sum(1 for c in rep.location if c.get("significant")),
        flagged_before_holdout=(rep.holdout or {}).get("flagged_before"),
        unexplained_in_sample=sum(1 for u in rep.unexplained if u.get("where") == "in-sample"),
        unexplained_holdout=sum(1 for u in rep.unexplained if u.get("where") == "holdout"),
        truth_lr=tr["lr"] if tr else None,
        truth_p_holm=tr["p_holm"] if tr else None,
        truth_not_identifiable=any(n["key"] == sc.truth for n in rep.not_identifiable) if sc.truth else False,
        elapsed=time.perf_counter() - t0,
        n_warnings=len(warned),
        warnings=dumps([str(w) for w in warned], indent=None),
    )
    return row


def _run(task: dict) -> dict:
    """One validation run (a task of :func:`fdml.parallel.execute`)."""
    return run_scenario(task["scenario"], diagnose_options=task["options"])


def _failed(task: dict, exc) -> dict:
    """The row of a run whose worker failed outside :func:`run_scenario` (it died, or the simulation raised)."""
    msg = exc if isinstance(exc, str) else one_line(exc)
    return dict(_scenario_columns(task["scenario"]), status=f"error: {msg}", verdict="error", verdict_key="error")


def _scenario_columns(sc: Scenario) -> dict:
    """The scenario's columns of a row (its values as JSON text)."""
    row = {k: v for k, v in asdict(sc).items() if k != "values"}
    return {**row, "values": dumps(sc.values, indent=None), "truth_name": sc.truth_name}


def wilson(k: int, n: int, z: float = 1.96) -> tuple:
    """Wilson score interval of a proportion k/n.

    Parameters
    ----------
    k : int
        Successes.
    n : int
        Trials.
    z : float, optional
        Standard normal quantile of the confidence level (1.96: 95 %).

    Returns
    -------
    tuple of float
        ``(lower, upper)``, within [0, 1]; NaN for n = 0.
    """
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    den = 1 + z * z / n
    c = (p + z * z / (2 * n)) / den
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(c - h, 0.0), min(c + h, 1.0))


def relabel(row: dict, threshold: float, unexplained: str = UNEXPLAINED_RULE) -> str | None:
    """The verdict's label recomputed at another shrink threshold and remaining-gap rule (no re-run).

    ``unexplained`` says which remaining flagged cells make the label partial: ``"in-sample"`` (after
    the final fit) or ``"holdout"`` (on the held-out record with the parameters frozen).

    Parameters
    ----------
    row : dict
        A row of :func:`run_scenario`.
    threshold : float
        Shrink needed for ``confirmed``.
    unexplained : {"in-sample", "holdout"}, optional
        The remaining-gap rule.

    Returns
    -------
    str or None
        The label, or None without a verdict.
    """
    if row.get("verdict") in (None, "none", "error"):
        return None
    n_unexp = row.get("unexplained_in_sample" if unexplained == "in-sample" else "unexplained_holdout") or 0
    if row.get("verdict") == "unmeasured_gust":
        return "confirmed" if n_unexp == 0 else "partial"
    return label_for(
        significant=True,
        accepted=True,
        ambiguous=len(loads(row.get("ambiguous") or "[]")) > 0,
        plausible=bool(row.get("plausible", True)),
        shrink=row.get("shrink"),
        n_flagged=_flagged_for_label(row),
        n_unexplained=n_unexp,
        threshold=threshold,
    )


def _flagged_for_label(row: dict) -> int:
    """The flagged cells the verdict's label judged: held out, or in-sample where the hold-out flags none.

    A kinematics-settled sensor effect is judged on the model as given, whose hold-out map the row's
    ``flagged_before_holdout`` (the map of the base with the settled effects) does not count.  Rows
    written before the diagnosis kept the count fall back to ``flagged_before_holdout``.
    """
    n = row.get("flagged_for_label")
    return int(n) if n is not None else int(row.get("flagged_before_holdout") or 0)


def score(rows: list, threshold: float = SHRINK_CONFIRM) -> dict:
    """Scores of a set of runs (see module doc).

    Parameters
    ----------
    rows : list of dict
        Rows of :func:`run_scenario`.
    threshold : float, optional
        Shrink needed for the label ``confirmed``.

    Returns
    -------
    dict
        ``threshold``, ``effects``, ``nulls``, ``out_of_library``, ``confusion``,
        ``top1_overall`` and ``median_time_s``.
    """
    by = defaultdict(list)
    for r in rows:
        by[r["case"]].append(r)
    eff: dict[str, dict[str, Any]] = {}
    nulls: dict[str, dict[str, Any]] = {}
    ool: dict[str, dict[str, Any]] = {}
    verdicts = sorted({r["verdict"] for r in rows} | {"none"})
    confusion = {}
    for case, rs in by.items():
        n = len(rs)
        labels = [relabel(r, threshold) for r in rs]
        conf = Counter(r["verdict"] for r in rs)
        confusion[case] = {v: conf.get(v, 0) for v in verdicts}
        errors = sum(1 for r in rs if r["verdict"] == "error")
        if case in NULLS:
            k = sum(1 for r in rs if r["verdict"] != "none")
            nulls[case] = {
                "n": n,
                "false_alarms": k,
                "rate": k / n,
                "wilson95": wilson(k, n),
                "fired": dict(Counter(r["verdict_key"] for r in rs if r["verdict"] != "none")),
                "errors": errors,
            }
            continue
        if case in OUT_OF_LIBRARY:
            wrong_conf = sum(
                1 for r, lab in zip(rs, labels) if r["verdict"] not in ("none", "error") and lab == "confirmed"
            )
            partial = sum(1 for r, lab in zip(rs, labels) if r["verdict"] == "none" or lab == "partial")
            ool[case] = {
                "n": n,
                "confidently_wrong": wrong_conf / n,
                "partial_or_none": partial / n,
                "not_confirmed": 1 - wrong_conf / n,
                "labels": dict(Counter(str(x) for x in labels)),
                "verdicts": dict(Counter(r["verdict_key"] for r in rs)),
            }
            continue
        name = rs[0]["truth_name"]
        det = [r for r in rs if r["verdict"] not in ("none", "error")]
        top1 = [r for r in rs if r["verdict"] == name]
        inset = [r for r in rs if r["verdict"] == name or name in loads(r.get("ambiguous_names") or "[]")]
        chan = [
            r for r in rs if r["verdict_key"] == rs[0]["truth"] or (name == "unmeasured_gust" and r["verdict"] == name)
        ]
        shr = [r["shrink"] for r in top1 if r.get("shrink") is not None]
        lab_top = Counter(lab for r, lab in zip(rs, labels) if r["verdict"] == name)
        by_size = {size: [r for r in rs if r["size"] == size] for size in ("small", "large")}
        eff[case] = {
            "n": n,
            "detected": len(det) / n,
            "top1": len(top1) / n,
            "top1_wilson95": wilson(len(top1), n),
            "in_set": len(inset) / n,
            "channel": len(chan) / n,
            "median_shrink": float(np.median(shr)) if shr else None,
            "confirmed_when_top1": lab_top.get("confirmed", 0) / max(len(top1), 1),
            "labels_when_top1": dict(lab_top),
            "errors": errors,
            "by_size": {
                size: {
                    "n": len(rr),
                    "top1": sum(1 for r in rr if r["verdict"] == name) / len(rr),
                    "detected": sum(1 for r in rr if r["verdict"] not in ("none", "error")) / len(rr),
                }
                for size, rr in by_size.items()
                if rr
            },
        }
    overall_top1 = sum(v["top1"] * v["n"] for v in eff.values()) / max(sum(v["n"] for v in eff.values()), 1)
    return {
        "threshold": threshold,
        "effects": eff,
        "nulls": nulls,
        "out_of_library": ool,
        "confusion": confusion,
        "top1_overall": overall_top1,
        "median_time_s": float(np.median([r["elapsed"] for r in rows if "elapsed" in r])) if rows else None,
    }


def tune_threshold(
    rows: list,
    grid=(0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9),
    cost: float = 2.0,
    rules=("holdout", "in-sample"),
    return_rule: bool = False,
):
    """Label rule chosen on tuning runs: the shrink threshold for "confirmed" and which remaining cells count.

    Maximises ``P(confirmed and right) - cost * P(confirmed and wrong)`` over every run: "right" is a
    verdict naming the withheld effect; "wrong" is any other verdict on a library truth, any verdict
    on an effect outside the library, or a false alarm on a null record.  A confident wrong answer
    counts ``cost`` (2) times a correct one left tentative or partial; ties go to the more
    conservative choice (higher threshold; the hold-out rule).

    Parameters
    ----------
    rows : list of dict
        Rows of :func:`run_scenario` on the tuning range.
    grid : sequence of float, optional
        Shrink thresholds tried.
    cost : float, optional
        Weight of a confident wrong answer against a confident right one.
    rules : sequence of str, optional
        Which remaining cells count (``"holdout"``, ``"in-sample"``).
    return_rule : bool, optional
        Also return the rule.

    Returns
    -------
    float or tuple
        The threshold, or ``(threshold, rule)`` with ``return_rule``.
    """
    best, best_rule, best_j = SHRINK_CONFIRM, UNEXPLAINED_RULE, -math.inf
    runs = [r for r in rows if r.get("verdict") not in (None, "error")]
    for rule, th in itertools.product(rules, sorted(grid, reverse=True)):
        confirmed = [r for r in runs if r["verdict"] != "none" and relabel(r, th, rule) == "confirmed"]
        good = sum(
            1
            for r in confirmed
            if r.get("truth") is not None and r["case"] not in OUT_OF_LIBRARY and r["verdict"] == r["truth_name"]
        )
        j = (good - cost * (len(confirmed) - good)) / max(len(runs), 1)
        if j > best_j + 1e-12:
            best, best_rule, best_j = th, rule, j
    return (float(best), best_rule) if return_rule else float(best)


@dataclass
class ValidationResult:
    """Rows of every run and their scores.

    Parameters
    ----------
    rows : list of dict
        One row per run (:func:`run_scenario`).
    scores : dict
        Their scores (:func:`score`).
    settings : dict
        The harness's settings (seeds, band, manoeuvres, noise levels).
    """

    rows: list
    scores: dict
    settings: dict = field(default_factory=dict)

    def table(self) -> str:
        """The scores as a text table (:func:`format_scores`).

        Returns
        -------
        str
            The table.
        """
        return format_scores(self.scores)

    def to_json(self, path=None, *, inputs=()) -> str:
        """JSON text; written atomically to ``path`` when given (never over ``inputs``).

        Parameters
        ----------
        path : str or Path, optional
            File to write.
        inputs : sequence of str or Path, optional
            Input files the output must not overwrite.

        Returns
        -------
        str
            The settings, scores and rows as JSON.
        """
        d = {"settings": self.settings, "scores": self.scores, "rows": self.rows}
        return json_text(d, path, inputs=inputs, what="validation file")


def format_scores(s: dict) -> str:
    """The validation table as text.

    Parameters
    ----------
    s : dict
        Scores (:func:`score`).

    Returns
    -------
    str
        The table: per truth, null case and out-of-library case.
    """
    out = [f"label threshold (shrink for 'confirmed'): {s['threshold']:.2f}", ""]
    out.append(
        f"{'truth':22s} {'n':>4s} {'detect':>7s} {'top-1':>6s} {'[Wilson 95%]':>15s} {'in-set':>7s} "
        f"{'chan':>5s} {'shrink':>7s} {'conf|top1':>9s} {'top1 small/large':>17s}"
    )
    for k, v in sorted(s["effects"].items()):
        w = v["top1_wilson95"]
        bs = v.get("by_size", {})
        sl = f"{bs.get('small', {}).get('top1', float('nan')):.2f}/{bs.get('large', {}).get('top1', float('nan')):.2f}"
        ms = v["median_shrink"]
        out.append(
            f"{k:22s} {v['n']:4d} {v['detected']:7.2f} {v['top1']:6.2f} [{w[0]:.2f}, {w[1]:.2f}]   "
            f"{v['in_set']:7.2f} {v['channel']:5.2f} {(f'{ms:.2f}' if ms is not None else '-'):>7s} "
            f"{v['confirmed_when_top1']:9.2f} {sl:>17s}"
        )
    out.append(f"top-1 over library effects: {s['top1_overall']:.3f}")
    out.append("")
    for k, v in s["nulls"].items():
        w = v["wilson95"]
        out.append(
            f"false alarms {k:14s} {v['false_alarms']}/{v['n']} = {v['rate']:.3f} [{w[0]:.3f}, {w[1]:.3f}]"
            f"  fired: {v['fired']}"
        )
    for k, v in s["out_of_library"].items():
        out.append(
            f"out of library {k}: n={v['n']}, confidently wrong {v['confidently_wrong']:.2f}, partial or no "
            f"verdict {v['partial_or_none']:.2f}, labels {v['labels']}, verdicts {v['verdicts']}"
        )
    out.append("")
    cols = sorted({c for row in s["confusion"].values() for c in row})
    out.append("confusion (rows truth case, columns verdict):")
    out.append(f"{'':22s} " + " ".join(f"{c[:8]:>8s}" for c in cols))
    for k in sorted(s["confusion"]):
        out.append(f"{k:22s} " + " ".join(f"{s['confusion'][k].get(c, 0):8d}" for c in cols))
    if s.get("median_time_s"):
        out.append(f"\nmedian time per diagnosis (record + hold-out): {s['median_time_s']:.2f} s")
    return "\n".join(out)


def validate(
    *,
    n_effect: int = 4,
    n_null: int = 34,
    seed_base: int = REPORT_SEED_BASE,
    processes: int | None = None,
    truths=None,
    nulls=None,
    threshold: float | None = None,
    rows_path=None,
    progress=None,
    diagnose_options: dict | None = None,
) -> ValidationResult:
    """Run the validation harness.

    Parameters
    ----------
    n_effect, n_null : int
        Seeds per (truth, size, manoeuvre, noise level) and per (null, manoeuvre, noise level): the
        defaults give 48 runs per effect and 204 per null case.
    seed_base : int
        First seed (default the report range; 0 is the tuning range).
    processes : int, optional
        Worker processes of the local pool (:func:`fdml.parallel.execute`; default: the CPU
        count; 1 runs in this process).
    truths, nulls : sequence of str, optional
        Subsets of :data:`TRUTHS` and :data:`NULLS`.
    threshold : float, optional
        Label threshold for scoring (default the library's).
    rows_path : path, optional
        Append every finished row as one JSON line (a long run can be resumed/inspected).
    progress : callable, optional
        ``progress(done, total)`` after every run.
    diagnose_options : dict, optional
        Keyword arguments of :func:`fdml.diagnose.diagnose` for every run.

    Returns
    -------
    ValidationResult
        The rows, their scores and the settings.
    """
    scs = scenarios(n_effect=n_effect, n_null=n_null, seed_base=seed_base, truths=truths, nulls=nulls)
    tasks = [{"index": i, "scenario": sc, "options": diagnose_options} for i, sc in enumerate(scs)]
    procs = processes or os.cpu_count() or 1
    rows = []
    report = (lambda done, total, row: progress(done, total)) if progress else None
    engine = "process" if procs > 1 else "serial"
    runs = execute(_run, tasks, engine=engine, workers=procs, on_error=_failed, progress=report, total=len(tasks))
    with contextlib.ExitStack() as stack:
        fh = stack.enter_context(open(rows_path, "a")) if rows_path else None
        for row in stack.enter_context(contextlib.closing(runs)):
            rows.append(row)
            if fh:
                fh.write(dumps(row, indent=None) + "\n")
                fh.flush()
    settings = {
        "n_effect": n_effect,
        "n_null": n_null,
        "seed_base": seed_base,
        "band": BAND,
        "maneuvers": MANEUVERS,
        "noise_levels": NOISES,
        "gust_std": GUST_STD,
        "base_model": "steady navion",
    }
    return ValidationResult(rows, score(rows, SHRINK_CONFIRM if threshold is None else threshold), settings)
