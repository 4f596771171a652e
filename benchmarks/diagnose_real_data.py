"""``fdml.diagnose`` on the real flight records ($FDML_DATA, e.g. ../shared/data), with the base model a
flight-test engineer starts from when there is no geometry: the dimensional short-period model.

    python benchmarks/diagnose_real_data.py            # all cases
    python benchmarks/diagnose_real_data.py twin_joint  # one case

Reports (JSON) and figures go to benchmarks/output/ (not committed).
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from pathlib import Path

import fdml
from fdml.diagnose import diagnose
from fdml.io import data_path, load_record

OUT = Path(__file__).resolve().parent / "output"
HZ = 2 * math.pi
TWIN = (0.1 * HZ, 1.5 * HZ)  # SIDPAC's band for these manoeuvres


def _twin(n):
    return load_record(data_path(f"twin_otter/totter_lon_020213f1_{n}.mat"))


CASES = {
    # two repeats at one condition: each judged on the other, then both fitted jointly
    "twin_017_holdout_018": lambda: (_twin("017"), _twin("018"), {"band": TWIN}),
    "twin_018_holdout_017": lambda: (_twin("018"), _twin("017"), {"band": TWIN}),
    "twin_joint": lambda: ([_twin("017"), _twin("018")], None, {"band": TWIN}),
    # HFB-320: the 3-2-1-1 window (the phugoid follows), and the whole record above the phugoid
    "hfb320_0_20s": lambda: (
        load_record(data_path("hfb320/hfb320_1_10.asc"), t0=0.0, t1=20.0),
        None,
        {"band": (0.3, 6.0)},
    ),
    "hfb320_60s": lambda: (load_record(data_path("hfb320/hfb320_1_10.asc")), None, {"band": (0.6, 6.0)}),
    # ATTAS: all three outputs, and alpha, q only (as the book fits it)
    "attas": lambda: (load_record(data_path("attas/fAttasElv1.mat")), None, {"band": (0.3, 8.0)}),
    "attas_alpha_q": lambda: (
        load_record(data_path("attas/fAttasElv1.mat")),
        None,
        {"band": (0.3, 8.0), "outputs": ["alpha", "q"]},
    ),
}


def main(argv=None) -> int:
    names = (argv if argv is not None else sys.argv[1:]) or list(CASES)
    OUT.mkdir(exist_ok=True)
    warnings.simplefilter("ignore")
    for name in names:
        rec, hold, kw = CASES[name]()
        first = rec[0] if isinstance(rec, list) else rec
        base = fdml.make_model("dimensional", airspeed=first.meta["U"])
        t0 = time.time()
        rep = diagnose(rec, base, holdout=hold, **kw)
        print(f"===== {name} ({time.time() - t0:.1f} s, status {rep.status})")
        print(rep.summary())
        rep.to_json(OUT / f"real_{name}.json")
        if rep.status == "ok":
            rep.plot(OUT / f"real_{name}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
