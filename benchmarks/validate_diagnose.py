"""Validation of ``fdml.diagnose`` on records whose effect is withheld (issue 4).

Two seed ranges that never overlap:

1. the *tuning* range (seeds from 0): the label threshold (shrink needed for "confirmed") is chosen
   there by :func:`fdml.diagnose.validation.tune_threshold`;
2. the *report* range (seeds from ``REPORT_SEED_BASE``): the table is computed there, with the
   threshold from step 1, on at least 40 runs per effect and 200 per null case.

Usage::

    python benchmarks/validate_diagnose.py tune   [--n-effect 2 --n-null 10]
    python benchmarks/validate_diagnose.py report [--n-effect 4 --n-null 34] [--threshold X]

Rows (one JSON line per run) and the table go to benchmarks/output/ (not committed).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

OUT = Path(__file__).resolve().parent / "output"


def main(argv=None) -> int:
    from fdml.diagnose.validation import REPORT_SEED_BASE, format_scores, score, tune_threshold, validate

    p = argparse.ArgumentParser()
    p.add_argument("phase", choices=("tune", "report", "rescore"))
    p.add_argument("--n-effect", type=int, default=None)
    p.add_argument("--n-null", type=int, default=None)
    p.add_argument("--processes", type=int, default=2)
    p.add_argument("--threshold", type=float, default=None)
    a = p.parse_args(argv)
    OUT.mkdir(exist_ok=True)
    if a.phase == "rescore":
        rows = [json.loads(x) for x in (OUT / "report_rows.jsonl").read_text().splitlines() if x.strip()]
        th = a.threshold if a.threshold is not None else json.loads((OUT / "tuning.json").read_text())["threshold"]
        s = score(rows, th)
        (OUT / "report_table.txt").write_text(format_scores(s) + "\n")
        print(format_scores(s))
        return 0
    tune = a.phase == "tune"
    n_e = a.n_effect if a.n_effect is not None else (2 if tune else 4)
    n_n = a.n_null if a.n_null is not None else (10 if tune else 34)
    seed_base = 0 if tune else REPORT_SEED_BASE
    rows_path = OUT / f"{a.phase}_rows.jsonl"
    if rows_path.exists():
        rows_path.unlink()
    t0 = time.time()

    def progress(done, total):
        sys.stderr.write(f"\r{a.phase}: {done}/{total}  {time.time() - t0:.0f} s")
        sys.stderr.flush()

    res = validate(
        n_effect=n_e, n_null=n_n, seed_base=seed_base, processes=a.processes, rows_path=rows_path, progress=progress
    )
    sys.stderr.write("\n")
    if tune:
        th, rule = tune_threshold(res.rows, return_rule=True)
        s = score(res.rows, th)
        (OUT / "tuning.json").write_text(
            json.dumps({"threshold": th, "rule": rule, "scores": s}, indent=1, default=str)
        )
        print(f"chosen remaining-gap rule: {rule}")
        (OUT / "tuning_table.txt").write_text(format_scores(s) + "\n")
        print(f"chosen threshold: {th}")
        print(format_scores(s))
    else:
        th = a.threshold
        if th is None and (OUT / "tuning.json").exists():
            th = json.loads((OUT / "tuning.json").read_text())["threshold"]
        s = score(res.rows, th if th is not None else 0.5)
        (OUT / "report.json").write_text(json.dumps({"settings": res.settings, "scores": s}, indent=1, default=str))
        (OUT / "report_table.txt").write_text(format_scores(s) + "\n")
        print(format_scores(s))
    print(f"elapsed {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
