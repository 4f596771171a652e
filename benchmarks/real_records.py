"""fdml on the real flight records in $FDML_DATA (e.g. ../shared/data): the proof asked for in issue 3.

Run with ``python benchmarks/real_records.py [OUT_DIR]``.  For the Twin Otter
manoeuvres 017 and 018 (each alone and both together), an HFB-320 short-period
window and the ATTAS elevator 3-2-1-1, it fits the ``dimensional`` model in the
frequency domain and, as a cross-check, by time-domain output error with fdml's
own simulator (``fdml.timefit``), prints both with their standard errors and the
difference in combined standard errors, runs the consistency test of the two
Twin Otter manoeuvres with white-noise and coloured-residual bounds, and fits
``derivatives``, ``steady`` and ``unsteady`` with the Twin Otter's geometry for
the steady-versus-unsteady table.  Figures go to OUT_DIR (default
benchmarks/out/real).
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

warnings.simplefilter("ignore")

from fdml import fit, make_model  # noqa: E402
from fdml.aircraft import Aircraft  # noqa: E402
from fdml.compare import compare_steady_unsteady  # noqa: E402
from fdml.consistency import consistency  # noqa: E402
from fdml.io import data_path, load_record  # noqa: E402
from fdml.timefit import fit_time_domain  # noqa: E402

DIM = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")
HZ = 2 * np.pi
TWIN_OTTER_BAND = (0.1 * HZ, 1.5 * HZ, 0.02 * HZ)  # 0.1-1.5 Hz, as SIDPAC fits these manoeuvres


def load():
    r17 = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
    r18 = load_record(data_path("twin_otter/totter_lon_020213f1_018.mat"))
    hfb = load_record(data_path("hfb320/hfb320_1_10.asc"), t0=0.0, t1=20.0)
    att = load_record(data_path("attas/fAttasElv1.mat"))
    return r17, r18, hfb, att


#: name -> (records, fit options); every case estimates output biases (trim removed)
def cases(r17, r18, hfb, att):
    return {
        "Twin Otter 017": ([r17], dict(band=TWIN_OTTER_BAND)),
        "Twin Otter 018": ([r18], dict(band=TWIN_OTTER_BAND)),
        "Twin Otter 017+018": ([r17, r18], dict(band=TWIN_OTTER_BAND)),
        "HFB-320 0-20 s": ([hfb], dict(band=(0.3, 6.0, 0.05))),
        "ATTAS Elv1 (alpha, q)": ([att], dict(band=(0.3, 8.0, 0.05), outputs="alpha,q")),
    }


def dimensional_for(recs):
    return make_model("dimensional", airspeed=float(np.mean([r.meta["U"] for r in recs])))


def fmt(v, s):
    return f"{v:9.4g} ± {s:<8.2g}"


def compare_domains(name, recs, opts):
    m = dimensional_for(recs)
    t0 = time.perf_counter()
    fd = fit(recs if len(recs) > 1 else recs[0], m, **opts)
    t_fd = time.perf_counter() - t0
    fdc = fit(recs if len(recs) > 1 else recs[0], m, cov_type="colored", **opts)
    print(
        f"\n### {name}: frequency domain ({fd.iterations} iterations, {t_fd * 1e3:.0f} ms, "
        f"{'converged' if fd.converged else 'NOT converged'}; outputs {', '.join(fd.outputs)})"
    )
    if len(recs) == 1:
        t0 = time.perf_counter()
        td = fit_time_domain(recs[0], m, outputs=opts.get("outputs"))
        t_td = time.perf_counter() - t0
        print(f"time-domain output error: {td.nfev} simulations, {t_td * 1e3:.0f} ms")
        print("| parameter | frequency domain (white) | coloured s.e. | time domain | diff / combined s.e. |")
        print("|---|---|---|---|---|")
        for n in DIM:
            z = (fd[n] - td[n]) / np.hypot(fd.errors[n], td.errors[n])
            print(f"| {n} | {fmt(fd[n], fd.errors[n])} | {fdc.errors[n]:.2g} | {fmt(td[n], td.errors[n])} | {z:+.2f} |")
    else:
        print("| parameter | frequency domain (white) | coloured s.e. |")
        print("|---|---|---|")
        for n in DIM:
            print(f"| {n} | {fmt(fd[n], fd.errors[n])} | {fdc.errors[n]:.2g} |")
    return fd, fdc


def twin_otter_aircraft(rec):
    """Twin Otter geometry from the record (wing, mass, inertia, condition) plus an assumed tail."""
    meta = rec.meta
    return Aircraft(
        name="twin_otter",
        S_w=meta["S_w"],
        c_w=meta["c_w"],
        mass=meta["mass"],
        Iy=meta["Iy"],
        U=meta["U"],
        rho=meta["rho"],
        S_t=9.3,
        c_t=1.5,
        l_t=7.0,  # DHC-6 horizontal tail about 100 ft^2, arm about 7 m [ASSUMED]
        constants={"F": 1.358, "G": 0.513, "H": 0.065, "y_w": 0.361, "z_w": 0.381},
        sources={
            "S_t": "DHC-6 horizontal tail about 100 ft^2 [ASSUMED]",
            "l_t": "about 7 m [ASSUMED]",
            "F": "Sundowner, WK Table 2 [ASSUMED]",
            "y_w": "R. T. Jones AR 6 [MEM]",
        },
        assumed=frozenset({"S_t", "c_t", "l_t", "F", "G", "H", "y_w", "z_w"}),
        description="DHC-6 Twin Otter, NASA Glenn flight 020213f1 (record meta) with an assumed tail",
    )


def main(out_dir: Path):
    r17, r18, hfb, att = load()
    fits = {}
    for name, (recs, opts) in cases(r17, r18, hfb, att).items():
        fits[name] = compare_domains(name, recs, opts)
    for label, k in (("white-noise", 0), ("coloured-residual", 1)):
        c = consistency([fits["Twin Otter 017"][k], fits["Twin Otter 018"][k]], names=DIM)
        print(f"\n### Twin Otter 017 against 018, {label} bounds\n")
        print(c.summary())
    ac = twin_otter_aircraft(r17)
    cmp = compare_steady_unsteady([r17, r18], ac, band=TWIN_OTTER_BAND)
    print("\n### Twin Otter 017+018: steady (six derivatives) against unsteady (Wells-Keskar, assumed tail)\n")
    print(cmp.table().as_markdown() if hasattr(cmp.table(), "as_markdown") else cmp.table())
    out_dir.mkdir(parents=True, exist_ok=True)
    try:
        from fdml.report import write_report

        fits["Twin Otter 017+018"][0].to_json(out_dir / "twin_otter_joint.json")
        paths = write_report(out_dir / "twin_otter_joint.json", out_dir / "twin_otter_joint_report")
        print(f"\nreport: {paths.get('report', paths)}")
    except ImportError as exc:  # pragma: no cover
        print(f"(no report: {exc})")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "out" / "real")
