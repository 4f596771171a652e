"""Fuzzing: every reader of user input gives a valid object or one FdmlError naming the problem.

Property, for each loader (SIDPAC .mat, DLR .asc and .mat, fdml CSV, mapped
CSV, :func:`fdml.io.load_record`'s format detection), the band and assignment
parsers, the aircraft JSON reader and the result JSON reader: whatever the
input -- arbitrary bytes, a valid file truncated or with bytes changed,
non-UTF-8 bytes, wrong shapes, NaN and inf, non-monotonic or duplicate time,
angles in degrees, huge and tiny numbers -- the reader returns its object or
raises :class:`fdml.errors.FdmlError` with a one-line message that names the
file (or, for the parsers, the option or the item).  Any other exception
fails, and so does a hang: each example runs under a SIGALRM guard
(:data:`HANG_SECONDS`) besides the profile's per-example deadline.

The number of examples comes from the hypothesis profile (tests/conftest.py):
``ci`` (default, about half a minute for this file) or ``long``
(``pytest tests/test_properties.py --hypothesis-profile=long``: over 100,000
examples in all).
"""

from __future__ import annotations

import contextlib
import json
import math
import signal
import warnings
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from fdml.aircraft import Aircraft, load_aircraft
from fdml.commands._common import assignments
from fdml.errors import FdmlError
from fdml.fourier import check_band
from fdml.io import (
    load_record,
    read_csv_mapped,
    read_dlr_asc,
    read_dlr_mat,
    read_fdml_csv,
    read_sidpac,
)
from fdml.record import Record
from fdml.results import FitResult, load_result
from fdml.spectral import parse_band

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

#: A reader taking longer than this on one example (all inputs here are a few kB) hangs.
HANG_SECONDS = 20
_FIXTURE_OK = settings(suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


class Hang(BaseException):
    """Raised by the SIGALRM guard (a BaseException, so that no ``except Exception`` swallows it)."""


@contextlib.contextmanager
def no_hang(seconds: int = HANG_SECONDS):
    def _alarm(signum, frame):
        raise Hang(f"no answer after {seconds} s")

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def outcome(call, *names):
    """Run ``call()``; return its value, or None after an FdmlError naming one of ``names``."""
    try:
        with no_hang(), warnings.catch_warnings():
            warnings.simplefilter("ignore")  # data warnings are allowed; exceptions are the property
            return call()
    except FdmlError as exc:
        msg = str(exc)
        assert msg.strip() and "\n" not in msg, f"not one line: {msg!r}"
        assert any(str(n) in msg or repr(n) in msg for n in names), f"message names none of {names}: {msg!r}"
        return None


# --- value strategies --------------------------------------------------------------------------
#: NaN, inf, huge, tiny, subnormal, degree-sized and ordinary values.
WILD = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(
        [
            math.nan,
            math.inf,
            -math.inf,
            0.0,
            -0.0,
            1e308,
            -1e308,
            1.7e308,
            5e-324,
            1e-300,
            57.29578,
            180.0,
            -360.0,
            1e6,
            1e-12,
        ]
    ),
)
NON_UTF8 = st.sampled_from(
    [
        b"\xff",
        b"\xfe\xff",
        b"\x80",
        b"\xc3\x28",
        b"\xed\xa0\x80",
        b"\x00",
        b"\xef\xbb\xbf",
        b"\r",
        b"\n\n",
        b",",
        b";",
        b"\t",
        b'"',
        b"#",
        b"%",
    ]
)


def mutated(valid: bytes):
    """A valid file truncated, with bytes replaced or inserted (non-UTF-8 too), or arbitrary bytes."""
    n = len(valid)
    truncated = st.integers(0, n).map(lambda k: valid[:k])

    @st.composite
    def edited(draw):
        b = bytearray(valid)
        for _ in range(draw(st.integers(1, 4))):
            i = draw(st.integers(0, len(b)))
            piece = draw(st.one_of(NON_UTF8, st.binary(min_size=1, max_size=4)))
            if draw(st.booleans()):
                b[i : i + len(piece)] = piece
            else:
                b[i:i] = piece
        return bytes(b)

    return st.one_of(truncated, edited(), st.binary(max_size=300))


# --- valid records and structured damage -----------------------------------------------------
N = 60
DT = 0.02


def base_channels():
    """Time and the short-period signals of a smooth record, SI units."""
    t = np.arange(N) * DT
    de = 0.02 * np.sin(2.0 * t)
    alpha = 0.05 + 0.01 * np.sin(2.0 * t + 0.3)
    q = 0.03 * np.cos(2.0 * t)
    az = -1.0 + 0.05 * np.sin(2.0 * t)
    return t, de, alpha, q, az


@st.composite
@np.errstate(all="ignore")  # scaling by 1e300 overflows on purpose
def damaged(draw, data: np.ndarray, time_col: int | None = 0, cols: tuple = ()):
    """``data`` (rows = samples) with a few structured damages."""
    a = np.array(data, dtype=float)
    for _ in range(draw(st.integers(0, 3))):
        kind = draw(
            st.sampled_from(["cell", "scale", "swap", "dup", "reverse", "ms", "rows", "shape", "zero", "const"])
        )
        nr, nc = a.shape
        col = draw(st.sampled_from(cols)) if cols and nc > max(cols) else draw(st.integers(0, max(nc - 1, 0)))
        if nr == 0 or nc == 0:
            break
        if kind == "cell":
            a[draw(st.integers(0, nr - 1)), draw(st.integers(0, nc - 1))] = draw(WILD)
        elif kind == "scale":  # degrees for radians, huge and tiny
            a[:, col] *= draw(st.sampled_from([57.29578, 1e3, 1e-9, 1e300, -1.0, 0.0]))
        elif time_col is not None and kind in ("swap", "dup", "reverse", "ms") and nr > 2:
            i = draw(st.integers(0, nr - 2))
            if kind == "swap":
                a[[i, i + 1], time_col] = a[[i + 1, i], time_col]
            elif kind == "dup":
                a[i + 1, time_col] = a[i, time_col]
            elif kind == "reverse":
                a[:, time_col] = a[::-1, time_col]
            else:
                a[:, time_col] *= 1e3
        elif kind == "rows":
            a = a[: draw(st.integers(0, nr))]
        elif kind == "shape":
            a = a[:, : draw(st.integers(0, nc))] if draw(st.booleans()) else np.hstack([a, a[:, :1]])
        elif kind == "zero":
            a[:, col] = 0.0
        else:
            a[:, col] = draw(WILD)
    return a


def number_text(x: float) -> str:
    return repr(float(x))


# --- SIDPAC .mat -------------------------------------------------------------------------------
SIDPAC_LABELS = {
    2: "airspeed",
    4: "alpha",
    6: "q ",
    9: "theta",
    11: "ax",
    13: "az",
    14: "elevator",
    27: "qbar",
    29: "rho",
    30: "altitude",
    43: "qdot",
    48: "mass",
    50: "iyy",
}


def sidpac_matrix() -> np.ndarray:
    t, de, alpha, q, az = base_channels()
    fd = np.zeros((N, 90))
    fd[:, 0] = 3600.0 + t
    fd[:, 1] = 200.0
    fd[:, 3] = np.degrees(alpha)
    fd[:, 5] = np.degrees(q)
    fd[:, 8] = np.degrees(alpha)
    fd[:, 10] = 0.01
    fd[:, 12] = az
    fd[:, 13] = np.degrees(de)
    fd[:, 26] = 45.0
    fd[:, 28] = 0.002
    fd[:, 29] = 5000.0
    fd[:, 42] = np.degrees(np.gradient(q, DT))
    fd[:, 47] = 300.0
    fd[:, 49] = 20000.0
    return fd


def sidpac_vars(fd, with_t: bool = True) -> dict:
    lab = np.array([f"{SIDPAC_LABELS.get(i + 1, 'spare')} {i + 1:2d}" for i in range(90)], dtype=object)
    out = {"fdata": fd, "varlab": lab, "sarea": 420.0, "bspan": 65.0, "cbar": 6.5}
    if with_t:
        out["t"] = (fd[:, :1] - fd[0, 0]) if fd.size else np.zeros((0, 1))
    return out


def mat_bytes(tmp: Path, variables: dict) -> bytes:
    f = tmp / "build.mat"
    savemat(str(f), variables)
    return f.read_bytes()


@cache
def valid_sidpac(tmp: Path) -> bytes:
    return mat_bytes(tmp, sidpac_vars(sidpac_matrix()))


def test_valid_files_are_read(scratch):
    """The unfuzzed files below are valid, so the fuzzing starts from real records."""
    (scratch / "s.mat").write_bytes(valid_sidpac(scratch))
    (scratch / "h.asc").write_bytes(valid_dlr_asc())
    (scratch / "a.mat").write_bytes(valid_dlr_mat(scratch))
    (scratch / "c.csv").write_bytes(valid_fdml_csv())
    (scratch / "m.csv").write_bytes(valid_mapped_csv())
    recs = [
        read_sidpac(scratch / "s.mat"),
        read_dlr_asc(scratch / "h.asc", "hfb320"),
        read_dlr_mat(scratch / "a.mat", "attas"),
        read_fdml_csv(scratch / "c.csv"),
        read_csv_mapped(scratch / "m.csv", MAP),
        load_record(scratch / "s.mat"),
        load_record(scratch / "h.asc"),
    ]
    assert all(isinstance(r, Record) and r.n == N for r in recs)
    assert isinstance(load_aircraft(valid_aircraft_path(scratch)), Aircraft)


@_FIXTURE_OK
@given(raw=st.data())
def test_sidpac_bytes(scratch, raw):
    path = scratch / "fuzz.mat"
    path.write_bytes(raw.draw(mutated(valid_sidpac(scratch))))
    rec = outcome(lambda: read_sidpac(path), path)
    assert rec is None or isinstance(rec, Record)


@pytest.mark.slow
@_FIXTURE_OK
@given(data=st.data())
def test_sidpac_structured(scratch, data):
    fd = data.draw(damaged(sidpac_matrix(), time_col=0, cols=(0, 1, 3, 5, 12, 13, 28, 47)))
    variables = sidpac_vars(fd, with_t=data.draw(st.booleans()))
    odd = data.draw(st.sampled_from(["none", "transpose", "int", "complex", "text", "cell", "vector", "labels", "t"]))
    if odd == "transpose":
        variables["fdata"] = fd.T
    elif odd == "int":
        variables["fdata"] = np.nan_to_num(fd, posinf=1e9, neginf=-1e9).clip(-1e9, 1e9).astype(np.int32)
    elif odd == "complex":
        variables["fdata"] = fd + 1j
    elif odd == "text":
        variables["fdata"] = "not a matrix"
    elif odd == "cell":
        variables["fdata"] = np.array([fd, "x"], dtype=object)
    elif odd == "vector":
        variables["fdata"] = fd.ravel()[:90]
    elif odd == "labels":
        variables["varlab"] = data.draw(st.sampled_from([np.arange(5.0), "x", np.array([1, "a"], dtype=object)]))
    elif odd == "t":
        variables["t"] = data.draw(
            st.sampled_from([np.full(fd.shape[0], np.nan), np.zeros(fd.shape[0]), np.arange(fd.shape[0])[::-1] * 1.0])
        )
    path = scratch / "fuzz.mat"
    path.write_bytes(mat_bytes(scratch, variables))
    original = data.draw(st.booleans())
    rec = outcome(lambda: read_sidpac(path, original=original), path)
    assert rec is None or isinstance(rec, Record)


# --- DLR .asc and .mat ---------------------------------------------------------------------------
def hfb_matrix() -> np.ndarray:
    t, de, alpha, q, az = base_channels()
    d = np.zeros((N, 20))
    d[:, 0], d[:, 1], d[:, 2], d[:, 4], d[:, 5] = t, de, 6000.0, 100.0, alpha
    d[:, 6], d[:, 7], d[:, 8], d[:, 9], d[:, 10] = alpha, q, np.gradient(q, DT), 0.1, az * 9.80665
    return d


def attas_matrix() -> np.ndarray:
    t, de, alpha, q, az = base_channels()
    d = np.zeros((N, 45))
    d[:, 0], d[:, 1], d[:, 3], d[:, 7] = t, 0.1, az * 9.80665, np.degrees(q)
    d[:, 10], d[:, 12], d[:, 14], d[:, 15] = np.degrees(alpha), np.degrees(alpha), 100.0, 10000.0
    d[:, 17], d[:, 21], d[:, 33] = np.degrees(np.gradient(q, DT)), np.degrees(de), 0.9
    return d


def asc_text(d: np.ndarray, header: str = "HFB-320 record\n") -> str:
    return header + "".join(" ".join(number_text(x) for x in row) + "\n" for row in d)


def valid_dlr_asc() -> bytes:
    return asc_text(hfb_matrix()).encode()


@cache
def valid_dlr_mat(tmp: Path) -> bytes:
    return mat_bytes(tmp, {"fAttasElv1": attas_matrix()})


@_FIXTURE_OK
@given(data=st.data())
def test_dlr_asc_bytes(scratch, data):
    path = scratch / "fuzz.asc"
    path.write_bytes(data.draw(mutated(valid_dlr_asc())))
    rec = outcome(lambda: read_dlr_asc(path, "hfb320"), path)
    assert rec is None or isinstance(rec, Record)


@_FIXTURE_OK
@given(data=st.data())
def test_dlr_asc_structured(scratch, data):
    d = data.draw(damaged(hfb_matrix(), time_col=0, cols=(0, 1, 5, 7, 10)))
    sep = data.draw(st.sampled_from([" ", ",", "\t", "  "]))
    text = "".join(sep.join(number_text(x) for x in row) + "\n" for row in d)
    path = scratch / "fuzz.asc"
    path.write_text(data.draw(st.sampled_from(["", "% header\n", "time elev\n"])) + text)
    window = data.draw(st.one_of(st.none(), st.tuples(WILD, WILD)))
    kw = {} if window is None else {"t0": window[0], "t1": window[1]}
    trim = data.draw(st.sampled_from([None, "first", "mean"]))
    rec = outcome(lambda: read_dlr_asc(path, "hfb320", trim=trim, **kw), path)
    assert rec is None or isinstance(rec, Record)


@_FIXTURE_OK
@given(data=st.data())
def test_dlr_mat_bytes(scratch, data):
    path = scratch / "fuzz.mat"
    path.write_bytes(data.draw(mutated(valid_dlr_mat(scratch))))
    rec = outcome(lambda: read_dlr_mat(path, "attas"), path)
    assert rec is None or isinstance(rec, Record)


@pytest.mark.slow
@_FIXTURE_OK
@given(data=st.data())
def test_dlr_mat_structured(scratch, data):
    d = data.draw(damaged(attas_matrix(), time_col=0, cols=(0, 3, 7, 12, 14, 21, 33)))
    extra = data.draw(st.sampled_from([{}, {"other": d}, {"s": "text"}, {"v": np.arange(3.0)}]))
    variables = {"fAttasElv1": d, **extra}
    path = scratch / "fuzz.mat"
    path.write_bytes(mat_bytes(scratch, variables))
    variable = data.draw(st.sampled_from([None, "fAttasElv1", "missing", "s"]))
    rec = outcome(lambda: read_dlr_mat(path, "attas", variable=variable), path)
    assert rec is None or isinstance(rec, Record)
    rec2 = outcome(lambda: load_record(path), path)  # format and layout detected from the file
    assert rec2 is None or isinstance(rec2, Record)


# --- fdml CSV and mapped CSV --------------------------------------------------------------------
def csv_matrix() -> np.ndarray:
    return np.column_stack(base_channels())


def valid_fdml_csv() -> bytes:
    t, de, alpha, q, az = base_channels()
    return Record(t, {"de": de, "alpha": alpha, "q": q, "az": az}).to_csv_text().encode()


MAP = {"t": "time", "de": "elev", "alpha": "AOA", "q": "pitch rate", "az": "nz"}
MAPPED_HEADER = ["time (s)", "elev [deg]", "AOA (deg)", "pitch rate (deg/s)", "nz (g)"]


def mapped_matrix() -> np.ndarray:
    t, de, alpha, q, az = base_channels()
    return np.column_stack([t, np.degrees(de), np.degrees(alpha), np.degrees(q), az])


def valid_mapped_csv(sep: str = ",") -> bytes:
    rows = [sep.join(MAPPED_HEADER)] + [sep.join(number_text(x) for x in r) for r in mapped_matrix()]
    return ("\n".join(rows) + "\n").encode()


@_FIXTURE_OK
@given(data=st.data())
def test_fdml_csv_bytes(scratch, data):
    path = scratch / "fuzz.csv"
    path.write_bytes(data.draw(mutated(valid_fdml_csv())))
    rec = outcome(lambda: read_fdml_csv(path), path)
    assert rec is None or isinstance(rec, Record)
    rec2 = outcome(lambda: load_record(path), path)
    assert rec2 is None or isinstance(rec2, Record)


@_FIXTURE_OK
@given(data=st.data())
def test_fdml_csv_structured(scratch, data):
    d = data.draw(damaged(csv_matrix(), time_col=0, cols=(0, 1, 2, 3, 4)))
    header = data.draw(
        st.sampled_from(
            [
                ["t", "de", "alpha", "q", "az"],
                ["t", "de", "alpha", "q", "az", "x"],
                ["t", "de", "alpha", "q"],
                ["t", "de", "de", "q", "az"],
                ["\ufefft", "de", "alpha", "q", "az"],
            ]
        )
    )
    text = ",".join(header) + "\n" + "".join(",".join(number_text(x) for x in r) + "\n" for r in d)
    path = scratch / "fuzz.csv"
    path.write_text(text)
    window = data.draw(st.one_of(st.none(), st.tuples(WILD, WILD)))
    kw = {} if window is None else {"t0": window[0], "t1": window[1]}
    rec = outcome(lambda: read_fdml_csv(path, **kw), path)
    assert rec is None or isinstance(rec, Record)


@_FIXTURE_OK
@given(data=st.data())
def test_mapped_csv_bytes(scratch, data):
    path = scratch / "fuzz.csv"
    sep = data.draw(st.sampled_from([",", ";", "\t", " "]))
    path.write_bytes(data.draw(mutated(valid_mapped_csv(sep))))
    delimiter = data.draw(st.sampled_from([None, sep]))
    rec = outcome(lambda: read_csv_mapped(path, MAP, delimiter=delimiter), path)
    assert rec is None or isinstance(rec, Record)


@_FIXTURE_OK
@given(data=st.data())
def test_mapped_csv_structured(scratch, data):
    d = data.draw(damaged(mapped_matrix(), time_col=0, cols=(0, 1, 2, 3, 4)))
    header = list(MAPPED_HEADER)
    k = data.draw(st.integers(0, len(header) - 1))
    header[k] = data.draw(
        st.sampled_from(
            [header[k], "AOA (deg)", "time (ms)", "nz (m/s^2)", "q (furlong)", "elev", "", header[k] + " (rad)"]
        )
    )
    sep = data.draw(st.sampled_from([",", ";", "\t"]))
    cells = [[number_text(x) for x in r] for r in d]
    if cells and cells[0] and data.draw(st.booleans()):
        cells[data.draw(st.integers(0, len(cells) - 1))][0] = data.draw(st.sampled_from(["", "abc", "1,5", "nan"]))
    text = sep.join(header) + "\n" + "".join(sep.join(r) + "\n" for r in cells)
    path = scratch / "fuzz.csv"
    path.write_text(text)
    units = data.draw(st.sampled_from([None, {"alpha": "rad"}, {"alpha": "deg"}, {"az": "deg"}, {"t": "ms"}]))
    sign = data.draw(st.sampled_from([None, {"az": -1}, {"az": 2}, {"az": True}, {"alpha": -1.0}]))
    rec = outcome(lambda: read_csv_mapped(path, MAP, units=units, sign=sign), path)
    assert rec is None or isinstance(rec, Record)


# --- parsers -----------------------------------------------------------------------------------
BAND_TEXT = st.one_of(
    st.text(max_size=30),
    st.lists(st.one_of(WILD.map(number_text), st.text(max_size=5), st.integers().map(str)), min_size=1, max_size=4).map(
        ":".join
    ),
)


@given(
    band=st.one_of(
        BAND_TEXT,
        st.none(),
        st.tuples(WILD, WILD, WILD),
        st.lists(WILD, max_size=4),
        st.tuples(st.text(max_size=4), WILD, st.booleans()),
    ),
    positive=st.booleans(),
)
def test_parse_band(band, positive):
    out = outcome(lambda: parse_band(band, what="--band", positive=positive), "--band")
    if out is not None:
        lo, hi, step = out
        assert all(math.isfinite(v) for v in out) and 0 <= lo <= hi and step > 0 and (lo > 0 or not positive)


@given(
    lo=st.one_of(WILD, st.text(max_size=4), st.none(), st.booleans()),
    hi=st.one_of(WILD, st.text(max_size=4), st.booleans()),
    step=st.one_of(st.none(), WILD, st.integers(), st.text(max_size=4)),
)
def test_check_band(lo, hi, step):
    out = outcome(lambda: check_band(lo, hi, step, what="omega"), "omega")
    if out is not None:
        assert out[3] >= 0 and out[0] <= out[1]


ITEM = st.one_of(
    st.text(max_size=20),
    st.tuples(st.sampled_from(["Cm_de", "M_q", " Z_q ", "", "a=b"]), WILD.map(number_text)).map(
        lambda p: f"{p[0]}={p[1]}"
    ),
)


@given(items=st.lists(ITEM, max_size=5))
def test_assignments(items):
    out = outcome(lambda: assignments(items), *items)
    if out is not None:
        assert all(isinstance(v, float) and math.isfinite(v) for v in out.values())
        assert all(k and k == k.strip() for k in out)


# --- aircraft and result JSON ----------------------------------------------------------------------
def valid_aircraft_text() -> str:
    from importlib import resources

    return (resources.files("fdml") / "presets" / "navion.json").read_text()


def valid_aircraft_path(tmp: Path) -> Path:
    p = tmp / "plane.json"
    p.write_text(valid_aircraft_text())
    return p


JSON_VALUE = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), WILD, st.text(max_size=6)),
    lambda inner: st.one_of(st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=5), inner, max_size=3)),
    max_leaves=6,
)


@_FIXTURE_OK
@given(data=st.data())
def test_aircraft_json(scratch, data):
    path = scratch / "fuzz.json"
    if data.draw(st.booleans()):
        path.write_bytes(data.draw(mutated(valid_aircraft_text().encode())))
    else:
        doc = json.loads(valid_aircraft_text())
        for _ in range(data.draw(st.integers(1, 3))):
            key = data.draw(st.sampled_from(sorted(doc) + ["extra"]))
            if data.draw(st.booleans()):
                doc.pop(key, None)
            else:
                doc[key] = data.draw(JSON_VALUE)
        path.write_text(json.dumps(doc))  # NaN and Infinity tokens included
    ac = outcome(lambda: load_aircraft(path), path)
    assert ac is None or isinstance(ac, Aircraft)


@cache
def valid_result_text() -> str:
    from fdml.estimate import fit
    from fdml.models import make_model
    from fdml.simulate import simulate_maneuver

    model = make_model("dimensional", "navion")
    rec = simulate_maneuver(model, "3211", duration=4.0, dt=0.05, noise={"alpha": 1e-4, "q": 1e-4, "az": 1e-3}, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit(rec, model, band=(0.5, 8.0, 0.5)).to_json(indent=None)


@_FIXTURE_OK
@given(data=st.data())
def test_result_json_truncated_or_edited(scratch, data):
    """Arbitrary JSON in a result is covered by tests/test_results_json.py; here: damaged files."""
    path = scratch / "fuzz.json"
    path.write_bytes(data.draw(mutated(valid_result_text().encode())))
    res = outcome(lambda: load_result(path), path)
    assert res is None or isinstance(res, FitResult)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")
