"""The main job on bundled defaults: Wells-Keskar Table 1 with the Navion.

Simulate a Navion 3-2-1-1 manoeuvre with the unsteady model (docs/theory.md
section 10 set-up) and measurement noise, fit the conventional steady model
and the unsteady model, print the two derivative sets side by side with the
paper's, and write a Bode-style figure of measured against fitted spectra
(WK Figs. 3-5), the record and both fits into an output folder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .compare import Comparison, compare_steady_unsteady
from .models import make_model
from .outputs import atomic_savefig, atomic_write_text, check_output_folder
from .record import Record, add_noise

__all__ = ["DemoResult", "run_demo", "WK_TABLE1"]

#: The demo's measurement noise: a fraction of each output's RMS.
DEFAULT_NOISE = 0.02
#: The files the demo writes into its folder (the figure only with ``figure=True``).
FILES = {
    "record": "navion_3211.csv",
    "unsteady": "unsteady.json",
    "steady": "steady.json",
    "summary": "summary.txt",
    "figure": "bode.png",
}

#: WK Table 1 (docs/theory.md 11.1): {derivative: (unsteady, steady)}.
WK_TABLE1 = {
    "Cz_a": (-4.99, -4.90),
    "Cz_q": (-4.82, -6.28),
    "Cz_de": (-0.51, -0.49),
    "Cm_a": (-1.00, -0.83),
    "Cm_q": (-12.77, -14.68),
    "Cm_de": (-1.42, -1.36),
}


@dataclass(frozen=True)
class DemoResult:
    """What :func:`run_demo` made.

    Parameters
    ----------
    comparison : Comparison
        Steady and unsteady fits.
    record : Record
        The simulated noisy record.
    table : str
        The side-by-side table with the paper's columns.
    files : dict
        Paths written (``record``, ``figure``, ``unsteady``, ``steady``, ``summary``).
    """

    comparison: Comparison
    record: Record
    table: str
    files: dict


def run_demo(
    out_dir: str | Path = "fdml-demo",
    *,
    seed: int = 1,
    noise: float = DEFAULT_NOISE,
    duration: float = 12.0,
    dt: float = 0.02,
    figure: bool = True,
) -> DemoResult:
    """Run the demo and write its files into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Output folder (created if needed).
    seed : int
        Seed of the measurement noise.
    noise : float
        Noise standard deviation as a fraction of each output's RMS.
    duration, dt : float
        Record length and sample interval, s.
    figure : bool
        Write the Bode figure (needs matplotlib).

    Returns
    -------
    DemoResult
        The simulated record, the comparison, its table and the files written.
    """
    from .simulate import simulate_maneuver

    out = Path(out_dir)
    # every output checked before the work
    check_output_folder(out, {name: f"demo {key} file" for key, name in FILES.items()}, what="demo folder")
    truth = make_model("unsteady", "navion")
    clean = simulate_maneuver(truth, "3211", duration=duration, dt=dt)
    rec = add_noise(clean, noise, np.random.default_rng(seed), relative=True)
    rec = Record(rec.t, rec.signals, name="navion_3211", meta=rec.meta)
    cmp = compare_steady_unsteady(rec, "navion")
    table = cmp.table(reference=WK_TABLE1)
    files = {k: out / name for k, name in FILES.items() if figure or k != "figure"}
    rec.to_csv(files["record"])
    cmp.unsteady.to_json(files["unsteady"])
    cmp.steady.to_json(files["steady"])
    text = (
        "fdml demo: Navion 3-2-1-1 simulated with the unsteady model, "
        f"{100 * noise:g} % noise (seed {seed}); steady = six-derivative model\n\n" + table + "\n"
    )
    atomic_write_text(files["summary"], text)
    if figure:
        from .plotting import plot_spectra

        fits, labels = [cmp.unsteady, cmp.steady], ["unsteady fit", "steady fit"]
        title = "Navion 3-2-1-1: measured and fitted spectra"
        atomic_savefig(lambda: plot_spectra(fits, labels, title=title)[0], files["figure"], dpi=110)
    return DemoResult(comparison=cmp, record=rec, table=table, files=files)
