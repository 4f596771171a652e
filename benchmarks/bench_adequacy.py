"""Cost of the adequacy check (fdml.adequacy) relative to the fit it checks.

Run with ``python benchmarks/bench_adequacy.py [REPEATS] [--first-fit N]``
(default 7 repeats).  Two cases: a 12 s, 50 Hz 3-2-1-1 record of the Navion
``derivatives`` model over the default band 0.1:10:0.1 rad/s, and the Twin
Otter 017 record (dimensional model, 0.1-1.5 Hz at 0.02 Hz; skipped without
the data).  For each, in-process, the best and the median over REPEATS of the
fit time (``FitResult.elapsed``: the estimator, without the check) and of the
check's time (``Adequacy.elapsed``), and their ratios; issue 8 allows at most 1
(the check may cost as much again as the fit).  Best-of-N is the figure for a
quiet machine; the median shows what load does to both.

``--first-fit N``: the first ``fdml.fit`` in a fresh interpreter (``python -c
"import fdml; fdml.fit(...)"``, imports included), best of N processes, with
and without the check, and whether the fit imported ``fdml.diagnose``.
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np

import fdml
from fdml.io import data_path, load_record
from fdml.simulate import simulate_maneuver

warnings.simplefilter("ignore")
HZ = 2 * math.pi


def cases():
    nav = fdml.make_model("derivatives", "navion")
    rec = simulate_maneuver(nav, "3211", duration=12.0, dt=0.02, noise={"alpha": 1e-3, "q": 2e-3, "az": 5e-3}, seed=1)
    out = {"12 s Navion 3-2-1-1, 0.1:10:0.1": (rec, nav, (0.1, 10.0, 0.1))}
    try:
        to = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
        out["Twin Otter 017, 0.1-1.5 Hz"] = (
            to,
            fdml.make_model("dimensional", airspeed=float(to.meta["U"])),
            (0.1 * HZ, 1.5 * HZ, 0.02 * HZ),
        )
    except (fdml.FdmlError, OSError) as exc:
        print(f"Twin Otter skipped: {exc}")
    return out


def measure(rec, model, band, repeats: int):
    """(fit times, check times) in s over ``repeats`` fits after a warm-up, and the last check."""
    fdml.fit(rec, model, band=band)  # warm-up: imports, caches
    t_fit, t_adq = [], []
    for _ in range(repeats):
        res = fdml.fit(rec, model, band=band)
        t_fit.append(res.elapsed)
        t_adq.append(res.adequacy.elapsed)
    return np.array(t_fit), np.array(t_adq), res.adequacy


FIRST_FIT = """
import math, sys, time, warnings
import fdml
from fdml.io import data_path, load_record
rec = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
m = fdml.make_model("dimensional", airspeed=float(rec.meta["U"]))
warnings.simplefilter("ignore")
t1 = time.perf_counter()
fdml.fit(rec, m, band=(0.1 * 2 * math.pi, 1.5 * 2 * math.pi, 0.02 * 2 * math.pi), adequacy=ADEQUACY)
t2 = time.perf_counter()
print(t2 - t1, any(k.startswith("fdml.diagnose") for k in sys.modules))
"""


def first_fit(n: int) -> None:
    """Best of ``n`` fresh interpreters: the first fit's wall time with and without the check (Twin Otter 017)."""
    import subprocess

    print(f"| first fit in a fresh process (Twin Otter 017) | best of {n}, s | imports fdml.diagnose |")
    print("|---|---|---|")
    for adequacy in (True, False):
        runs = [
            subprocess.run(
                [sys.executable, "-c", FIRST_FIT.replace("ADEQUACY", str(adequacy))],
                capture_output=True,
                text=True,
                check=True,
            ).stdout.split()
            for _ in range(n)
        ]
        best = min(float(r[0]) for r in runs)
        print(f"| adequacy={adequacy} | {best:.3f} | {runs[0][1]} |")


def main(repeats: int = 7):
    print(
        "| case | fit, ms: best / median | adequacy, ms: best / median | ratio of bests | ratio of medians | flagged |"
    )
    print("|---|---|---|---|---|---|")
    for name, (rec, model, band) in cases().items():
        tf, ta, a = measure(rec, model, band, repeats)
        flagged = ", ".join(e.key for e in a.flagged) or "nothing"
        print(
            f"| {name} | {tf.min() * 1e3:.1f} / {np.median(tf) * 1e3:.1f} | {ta.min() * 1e3:.1f} / "
            f"{np.median(ta) * 1e3:.1f} | {ta.min() / tf.min():.2f} | {np.median(ta) / np.median(tf):.2f} "
            f"| {flagged} |"
        )


if __name__ == "__main__":
    argv = sys.argv[1:]
    n_first = 0
    if "--first-fit" in argv:
        i = argv.index("--first-fit")
        n_first = int(argv[i + 1])
        del argv[i : i + 2]
    main(int(argv[0]) if argv else 7)
    if n_first:
        first_fit(n_first)
