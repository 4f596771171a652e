"""Speed of fdml's estimator, as ratios against baselines measured in the same run.

Run with ``python benchmarks/bench_fit.py [--quick]``.  Every time is the best of
several repetitions (in-process, wall clock), so that load from other processes
inflates it as little as possible.  Printed:

1. one model evaluation, vectorised, against a Python loop over frequencies;
2. one Gauss-Newton pass (residuals, sensitivities, gradient and Hessian) with
   analytic sensitivities, with the paper's Eq. 26 finite differences, and with
   a per-frequency loop of model evaluations for the sensitivities;
3. a whole fit of each model (transform included) against a time-domain
   output-error fit of the same model on the same record (fdml's simulator with
   scipy.optimize.least_squares), and against the issue's targets;
4. fit time as the record grows (1 to 100 minutes at 50 Hz) and as the number of
   frequencies grows (10 to 10,000), with the growth order fitted in log-log;
5. a whole ``fdml fit`` process (imports included) against a process that reads the record
   and takes its transform alone, and the start-up of ``import fdml`` and ``fdml --help``.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

warnings.simplefilter("ignore")

from fdml import fit, make_model  # noqa: E402
from fdml.estimate import _cov_R, _grad_hess, prepare  # noqa: E402
from fdml.record import add_noise  # noqa: E402
from fdml.simulate import simulate, simulate_maneuver  # noqa: E402
from fdml.timefit import fit_time_domain  # noqa: E402

QUICK = "--quick" in sys.argv


def best(f, reps=20):
    out = []
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        out.append(time.perf_counter() - t0)
    return min(out)


def record(model, duration, seed=1, noise=0.02, maneuver="3211"):
    rec = simulate_maneuver(model, maneuver, duration=duration, dt=0.02)
    return add_noise(rec, noise, np.random.default_rng(seed), relative=True)


def row(label, t, ref=None, unit="ms"):
    scale = 1e3 if unit == "ms" else 1.0
    ratio = f"{ref / t:10.1f}x" if ref is not None else ""
    print(f"  {label:58s}{t * scale:10.3f} {unit} {ratio}")


def section_model_eval():
    print("1. one model evaluation (100 frequencies): vectorised vs a loop over frequencies")
    om = np.linspace(0.1, 10, 100)
    for kind in ("dimensional", "derivatives", "steady", "unsteady"):
        m = make_model(kind, "navion", gust=True)
        t_loop = best(lambda: [m.evaluate([w]) for w in om], 5)
        t_vec = best(lambda: m.evaluate(om))
        row(f"{kind}: loop (reference)", t_loop)
        row(f"{kind}: vectorised", t_vec, t_loop)


def section_gn_pass():
    print("2. one Gauss-Newton pass (10 s record, 100 frequencies)")
    for kind in ("dimensional", "unsteady"):
        truth = make_model("unsteady", "navion")
        m = make_model(kind, "navion")
        rec = record(truth, 10.0)
        results = {}
        for sens in ("analytic", "fd"):
            prob = prepare(rec, m, sensitivity=sens)
            th = prob.initial()

            def one_pass(prob=prob, th=th):
                V = prob.residuals(th)
                R = _cov_R(V)
                A = prob.sensitivities(th)
                return _grad_hess(A, V, R, True)

            results[sens] = best(one_pass, 10)
        prob = prepare(rec, m, sensitivity="analytic")
        th = prob.initial()
        names = [prob.slots[i].name for i in prob.model_slots]

        def loop_pass(prob=prob, th=th, names=names, m=m):
            # reference: sensitivities by central differences, one frequency at a time
            d = prob.data[0]
            vals = prob.model_values(th)
            for w in d.omega:
                for n in names:
                    h = 1e-6 * max(abs(vals[n]), 1e-3)
                    m.evaluate([w], {**vals, n: vals[n] + h})
                    m.evaluate([w], {**vals, n: vals[n] - h})
            V = prob.residuals(th)
            return _cov_R(V)

        t_loop = best(loop_pass, 2)
        row(f"{kind}: per-frequency loop (reference)", t_loop)
        row(f"{kind}: Eq. 26 finite differences (settled)", results["fd"], t_loop)
        row(f"{kind}: analytic sensitivities", results["analytic"], t_loop)


def section_whole_fit():
    print("3. whole fit (transform included) vs time-domain output error on the same record")
    cases = [
        ("dimensional", 7.5, np.linspace(0.2 * np.pi, 3.0 * np.pi, 71), 5e-3),
        ("derivatives", 10.0, None, None),
        ("steady", 10.0, None, None),
        ("unsteady", 10.0, None, 20e-3),
    ]
    truth = make_model("unsteady", "navion")
    for kind, duration, omega, target in cases:
        m = make_model(kind, "navion")
        rec = record(truth if kind != "dimensional" else m, duration)
        kw = {"omega": omega} if omega is not None else {}
        t_fd = best(lambda: fit(rec, m, **kw), 10 if not QUICK else 3)
        t_td = best(lambda: fit_time_domain(rec, m), 1)
        n = len(omega) if omega is not None else 100
        row(f"{kind}: time-domain output error (reference)", t_td)
        tag = f" (target < {target * 1e3:g} ms)" if target else ""
        row(f"{kind}: fdml.fit, {duration:g} s, {n} frequencies{tag}", t_fd, t_td)


def growth(xs, ts):
    return np.polyfit(np.log(xs), np.log(ts), 1)[0]


def section_scaling():
    print("4. growth: record length (50 Hz) and number of frequencies (dimensional model)")
    m = make_model("dimensional", "navion")
    rng = np.random.default_rng(3)
    minutes = [1, 3, 10, 30, 100] if not QUICK else [1, 10]
    ts = []
    for mins in minutes:
        t = np.arange(0, mins * 60 + 1e-9, 0.02)
        de = np.convolve(rng.standard_normal(t.size), np.ones(25) / 25, mode="same") * 0.01
        rec = simulate(m, t, {"de": de})
        rec = add_noise(rec, 0.02, rng, relative=True)
        tt = best(lambda: fit(rec, m, band=(0.1, 10, 0.1)), 3)
        ts.append(tt)
        row(f"{mins:4d} min ({t.size} samples), 100 frequencies", tt, ts[0])
    print(f"  growth order in record length: {growth(minutes, ts):.2f}")
    t = np.arange(0, 600 + 1e-9, 0.02)
    de = np.convolve(rng.standard_normal(t.size), np.ones(25) / 25, mode="same") * 0.01
    rec = add_noise(simulate(m, t, {"de": de}), 0.02, rng, relative=True)
    counts = [10, 100, 1000, 10000] if not QUICK else [10, 100, 1000]
    ts = []
    for k in counts:
        om = np.linspace(0.1, 10.0, k)
        tt = best(lambda: fit(rec, m, omega=om), 3 if k < 10000 else 1)
        ts.append(tt)
        row(f"10 min record, {k:5d} frequencies", tt, ts[0])
    print(f"  growth order in frequencies: {growth(counts, ts):.2f}")


def section_process():
    print("5. whole processes, imports included: `fdml fit` against the transform alone")
    m = make_model("dimensional", "navion")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.csv"
        record(m, 7.5).to_csv(path)
        band = "0.6283:9.4248:0.12566"
        fit_cmd = [sys.executable, "-m", "fdml", "fit", str(path), "--model", "dimensional"]
        fit_cmd += ["--airspeed", "53.6448", "--band", band, "--json"]
        # the transform alone: read the record and take the finite Fourier transform of every
        # channel at the fit's frequencies (what any frequency-domain tool must do)
        transform = (
            "import sys, numpy as np; from fdml.record import read_csv; "
            "from fdml.fourier import finite_fourier_transform; r = read_csv(sys.argv[1]); "
            "om = np.arange(0.6283, 9.4248 + 1e-9, 0.12566); "
            "[finite_fourier_transform(r[k], r.dt, om) for k in ('de', 'alpha', 'q', 'az')]"
        )
        runs = {
            "python -c 'import numpy'": [sys.executable, "-c", "import numpy"],
            "python -c 'import fdml'": [sys.executable, "-c", "import fdml"],
            "fdml --help": [sys.executable, "-m", "fdml", "--help"],
            "transform alone (reference)": [sys.executable, "-c", transform, str(path)],
            "fdml fit (7.5 s record, 71 frequencies, --json)": fit_cmd,
        }
        times = {k: best(lambda c=c: subprocess.run(c, check=True, capture_output=True), 5) for k, c in runs.items()}
    ref = times["transform alone (reference)"]
    for k, t in times.items():
        row(k, t, unit="s")
    print(f"  fdml fit / transform alone: {times['fdml fit (7.5 s record, 71 frequencies, --json)'] / ref:.2f}")


if __name__ == "__main__":
    if "--process" in sys.argv:  # the process section alone (issue 20)
        section_process()
        sys.exit()
    t0 = time.perf_counter()
    section_model_eval()
    section_gn_pass()
    section_whole_fit()
    section_scaling()
    section_process()
    print(f"benchmark run took {time.perf_counter() - t0:.1f} s")
