"""The data check: corrupted copies are named, clean records of every kind pass.

The corrupted copies are made from a Navion dimensional-model 3-2-1-1 computed
by scipy.signal.lsim (tests/conftest.py), independent of fdml's simulator; the
clean records that must pass come from fdml's time-domain simulator with what a
real record varies (manoeuvre, edges, sample rate, turbulence, a start off trim,
a small alpha delay), and from the real flight records.
"""

import json
import math

import numpy as np
import pytest
from conftest import lsim_dimensional, three_two_one_one

import fdml
from fdml.cli import main
from fdml.constants import G0
from fdml.datacheck import DEG, check_data
from fdml.errors import DataCheckError, DataWarning
from fdml.record import Record

NAVION = fdml.make_model("dimensional", "navion")


@pytest.fixture(scope="module")
def navion_3211():
    """Navion 3-2-1-1 of 1 deg, 12 s at 50 Hz, 3 % output noise (lsim, independent of fdml)."""
    t = np.arange(0, 12 + 1e-9, 0.02)
    de = three_two_one_one(t, amplitude=math.radians(1.0))
    y = lsim_dimensional(NAVION, t, de)
    rng = np.random.default_rng(7)
    y = y + rng.normal(size=y.shape) * 0.03 * y.std(axis=0)
    return Record(t, {"de": de, "alpha": y[:, 0], "q": y[:, 1], "az": y[:, 2]}, name="navion")


def _corrupt(rec: Record, how: str) -> Record:
    s = dict(rec.signals)
    rng = np.random.default_rng(3)
    if how == "de_deg":
        s["de"] = s["de"] * DEG
    elif how == "alpha_deg":
        s["alpha"] = s["alpha"] * DEG
    elif how == "q_deg":
        s["q"] = s["q"] * DEG
    elif how == "az_ms2":
        s["az"] = s["az"] * G0
    elif how == "az_flip":
        s["az"] = -s["az"]
    elif how == "q_flip":
        s["q"] = -s["q"]
    elif how == "alpha_q_swapped":
        s["alpha"], s["q"] = s["q"], s["alpha"]
    elif how == "q_az_swapped":
        s["q"], s["az"] = s["az"], s["q"]
    elif how == "white_noise":
        for k in ("alpha", "q", "az"):
            s[k] = rng.normal(size=rec.n) * s[k].std()
    return Record(rec.t, s, name=how, check_units=False)


# case, expected code, expected estimate (value) or None, relative tolerance of the estimate.
# Tolerances: the slopes come from a regression on 3 %-noise spectra over 0.1-10 rad/s and
# are within about 1 % of the truth (clean copies: a = 0.998, b/(g/U) = 0.998); 3 % allows
# for the noise draw.
CORRUPTED = [
    ("de_deg", "units.elevator", None, None),
    ("alpha_deg", "units.alpha", DEG, 0.03),
    ("q_deg", "units.q", DEG, 0.03),
    ("az_ms2", "units.az", G0, 0.03),
    ("az_flip", "sign.az", -G0 / NAVION.U, 0.03),
    ("q_flip", "sign.q", -1.0, 0.03),
    ("alpha_q_swapped", "channels.swapped", None, None),
    ("q_az_swapped", "channels.swapped", None, None),
    ("white_noise", "response.alpha", None, None),
]


@pytest.mark.parametrize("how, code, value, rtol", CORRUPTED, ids=[c[0] for c in CORRUPTED])
def test_corrupted_copy_is_named(navion_3211, how, code, value, rtol):
    dc = check_data(_corrupt(navion_3211, how), airspeed=NAVION.U)
    assert code in dc.codes, dc.summary()
    if value is not None:
        f = next(f for f in dc.findings if f.code == code)
        assert f.value == pytest.approx(value, rel=rtol)
    if how == "white_noise":
        assert {"response.alpha", "response.q", "response.az"} <= set(dc.codes)
    else:  # one error, one finding: nothing else is blamed
        assert len(dc.findings) == 1, dc.summary()


def test_clean_copy_has_no_findings_and_the_identity_slopes(navion_3211):
    dc = check_data(navion_3211, airspeed=NAVION.U)
    assert dc.findings == ()
    k = dc.kinematics
    # 3 % noise: slopes within 2 % of 1 and g/U (the regression is weighted to the input's band)
    assert k.slope_q == pytest.approx(1.0, rel=0.02)
    assert k.slope_az == pytest.approx(G0 / NAVION.U, rel=0.02)
    assert k.implied_airspeed == pytest.approx(NAVION.U, rel=0.02)


def test_without_airspeed_a_sign_error_is_still_found(navion_3211):
    assert check_data(_corrupt(navion_3211, "az_flip")).codes == ("sign.az",)
    assert check_data(navion_3211).codes == ()


# --- no false alarms on clean records of every kind ------------------------------------------
CLEAN = [
    # model, manoeuvre, dt, options
    ("unsteady", "3211", 0.02, {}),
    ("unsteady", "doublet", 0.01, {"rise": 0.0}),  # stepped edges, interpolated between samples
    ("steady", "multisine", 0.05, {}),
    ("derivatives", "3211", 0.04, {"rise": 0.2}),
    ("unsteady", "3211", 0.02, {"gust_std": 2.0}),  # strong unmeasured turbulence
    ("unsteady", "3211", 0.02, {"window": 2.0}),  # record starts mid-manoeuvre, off trim
    ("unsteady", "3211", 0.02, {"delay": 0.021}),  # the Twin Otter's alpha lag
    ("dimensional", "doublet", 0.02, {"noise": 0.2}),  # noisy
]


@pytest.mark.parametrize(
    "kind, manoeuvre, dt, opts", CLEAN, ids=[f"{c[0]}-{c[1]}-{c[2]}-{sorted(c[3])}" for c in CLEAN]
)
def test_clean_simulated_records_pass(kind, manoeuvre, dt, opts):
    from fdml.record import add_noise
    from fdml.simulate import simulate_maneuver

    opts = dict(opts)
    gust = opts.pop("gust_std", 0.0)
    window = opts.pop("window", None)
    delay = opts.pop("delay", None)
    noise = opts.pop("noise", 0.03)
    model = fdml.make_model(kind, "navion", gust=gust > 0)
    rec = simulate_maneuver(
        model, manoeuvre, duration=14.0, dt=dt, amplitude=math.radians(1.5), gust_std=gust, seed=11, **opts
    )
    if gust:  # the gust is not measured
        rec = Record(rec.t, {k: v for k, v in rec.signals.items() if k != "alpha_w"}, name="gust")
    if delay:
        s = dict(rec.signals)
        s["alpha"] = np.interp(rec.t - delay, rec.t, s["alpha"])
        rec = Record(rec.t, s, name="delayed")
    if window:
        rec = rec.window(window, None)
    rec = add_noise(rec, noise, np.random.default_rng(5), relative=True)
    dc = check_data(rec, airspeed=model.U)
    assert dc.findings == (), dc.summary()


REAL = [
    ("twin_otter/totter_lon_020213f1_017.mat", {}),
    ("twin_otter/totter_lon_020213f1_018.mat", {}),
    ("hfb320/hfb320_1_10.asc", {}),
    ("attas/fAttasElv1.mat", {}),
]


@pytest.mark.parametrize("path, kw", REAL, ids=[p for p, _ in REAL])
@pytest.mark.parametrize("band", [None, "0.6:9.4:0.05"])
def test_real_records_pass_and_close_the_identity(path, kw, band):
    from fdml.errors import RecordError
    from fdml.io import data_path, load_record

    try:
        rec = load_record(data_path(path), **kw)
    except RecordError as exc:
        pytest.skip(str(exc))
    dc = check_data(rec, band=band)
    # the 60 s HFB-320 record holds a phugoid cycle that the default band reaches (test_phugoid_* below)
    phugoid = path.startswith("hfb320") and band is None
    assert dc.codes == (("phugoid.in_band",) if phugoid else ()), dc.summary()
    k = dc.kinematics
    # Real sensors: vane upwash and position, accelerometer position (absorbed by the j w q
    # regressor), alpha lags: a within 5 %, the implied airspeed within 10 % of the record's.
    assert k.slope_q == pytest.approx(1.0, abs=0.05)
    assert k.implied_airspeed == pytest.approx(rec.meta["U"], rel=0.10)


# --- the phugoid -----------------------------------------------------------------------------
U_PH = 100.0
#: A four-state longitudinal model (u m/s, alpha rad, q rad/s, theta rad; level flight,
#: stability axes): force and moment derivatives per unit of state, as accelerations.  The lift's
#: change with speed Z_u = -2 g/U is that of a trimmed aircraft (L = m g at U), so the speed-to-
#: flight-path coupling d = -Z_u/U = 2 g/U^2 and Lanchester's omega = sqrt(g d) = sqrt(2) g/U.
LONG = {"X_u": -0.02, "X_a": 4.0, "Z_u": -2 * G0 / U_PH, "Z_a": -1.2 * U_PH, "Z_de": -0.08 * U_PH}
LONG |= {"M_a": -4.0, "M_q": -1.5, "M_de": -6.0}


def _four_state():
    p = LONG
    A = np.array(
        [
            [p["X_u"], p["X_a"], 0.0, -G0],
            [p["Z_u"] / U_PH, p["Z_a"] / U_PH, 1.0, 0.0],
            [0.0, p["M_a"], p["M_q"], 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ]
    )
    return A, np.array([0.0, p["Z_de"] / U_PH, p["M_de"], 0.0])


@pytest.fixture(scope="module")
def phugoid_record():
    """60 s at 20 Hz of the four-state model after a slow 3-2-1-1 (1 s unit), exact zero-order hold."""
    from scipy.linalg import expm

    A, B = _four_state()
    dt = 0.05
    t = np.arange(0.0, 60.0 + 1e-9, dt)
    de = three_two_one_one(t, amplitude=math.radians(1.0), start=2.0, unit=1.0, rise=0.3)
    M = np.zeros((5, 5))
    M[:4, :4], M[:4, 4] = A * dt, B * dt
    E = expm(M)
    x, xs = np.zeros(4), []
    for u_k in de:
        xs.append(x)
        x = E[:4, :4] @ x + E[:4, 4] * u_k
    u, alpha, q, theta = np.array(xs).T
    az = (LONG["Z_u"] * u + LONG["Z_a"] * alpha + LONG["Z_de"] * de) / G0  # body-z specific force, g
    rng = np.random.default_rng(11)
    noisy = {"alpha": alpha, "q": q, "az": az, "theta": theta}
    noisy = {k: v + 0.02 * v.std() * rng.standard_normal(t.size) for k, v in noisy.items()}
    V = U_PH + u + 0.05 * rng.standard_normal(t.size)  # a 0.05 m/s airspeed sensor
    return Record(t, {"de": de, **noisy, "V": V}, name="phugoid", meta={"U": U_PH})


def test_phugoid_in_the_default_band_is_found_with_a_window_and_a_band(phugoid_record):
    from fdml.datacheck import PHUGOID_BAND_FACTOR, phugoid_frequency

    lanchester = math.sqrt(2.0) * G0 / U_PH
    # what the check measures is Lanchester's frequency of this aircraft; 3 % covers the noise
    assert phugoid_frequency(phugoid_record) == pytest.approx(lanchester, rel=0.03)
    dc = check_data(phugoid_record)
    assert dc.codes == ("phugoid.in_band",), dc.summary()
    f = dc.findings[0]
    assert f.kind == "estimation" and f.value == pytest.approx(lanchester, rel=0.03) and f.expected == 0.1
    # the suggestions leave out the four-state model's own phugoid (its eigenvalue, not the approximation)
    true_w = float(np.min(np.abs(np.linalg.eigvals(_four_state()[0]))))  # the slow pair: 0.115 rad/s
    t1 = float(f.message.split("--t1 ")[1].split(")")[0])
    lo = float(f.message.split("--band ")[1].split(":")[0])
    assert t1 <= math.pi / true_w  # at most half a period of the true phugoid
    assert lo >= PHUGOID_BAND_FACTOR * f.value and lo > 2.5 * true_w
    # what the finding suggests removes it
    assert check_data(phugoid_record.window(0.0, t1)).codes == ()
    assert check_data(phugoid_record, band=f"{lo}:10:0.1").codes == ()


def test_no_phugoid_claimed_without_speed_and_attitude_or_a_full_cycle(phugoid_record, navion_3211):
    short_period_only = Record(phugoid_record.t, {k: phugoid_record[k] for k in ("de", "alpha", "q", "az")})
    assert check_data(short_period_only).codes == ()
    assert check_data(phugoid_record.window(0.0, 35.0)).codes == ()  # 0.8 of a cycle
    steady_speed = phugoid_record.with_signals(V=np.full(phugoid_record.n, U_PH))
    assert "phugoid.in_band" not in check_data(steady_speed).codes
    assert check_data(navion_3211).codes == ()


def test_phugoid_of_the_60_s_hfb320_record(capsys):
    from fdml.io import data_path, load_record

    rec = load_record(data_path("hfb320/hfb320_1_10.asc"))
    dc = check_data(rec)
    assert dc.codes == ("phugoid.in_band",), dc.summary()
    w = dc.findings[0].value
    # Lanchester's sqrt(2) g/U at the record's mean airspeed (0.128 rad/s); 15 %: the real aircraft's
    # lift-speed slope need not be 2 g/U^2 (thrust, compressibility), and the record holds 1.3 cycles
    assert w == pytest.approx(math.sqrt(2.0) * G0 / float(np.mean(rec["V"])), rel=0.15)
    assert "--t1 23" in dc.findings[0].message  # half a period: the docs' 0-20 s window lies inside it
    assert check_data(load_record(data_path("hfb320/hfb320_1_10.asc"), t0=0.0, t1=20.0)).codes == ()
    code = main(["check", str(data_path("hfb320/hfb320_1_10.asc"))])
    assert code == 0 and "[phugoid.in_band]" in capsys.readouterr().out


# --- inside the fit and on the command line --------------------------------------------------
def test_fit_keeps_findings_warns_and_strict_refuses(navion_3211):
    bad = _corrupt(navion_3211, "alpha_q_swapped")
    model = fdml.make_model("dimensional", "navion")
    with pytest.warns(DataWarning, match=r"\[channels\.swapped\]"):
        res = fdml.fit(bad, model)
    assert [f.code for f in res.findings] == ["channels.swapped"]
    assert "[channels.swapped]" in str(res.summary())
    back = fdml.results.FitResult.from_dict(json.loads(res.to_json()))
    assert back.findings == res.findings
    with pytest.raises(DataCheckError, match="channels.swapped"):
        fdml.fit(bad, model, strict=True)
    clean = fdml.fit(navion_3211, model, strict=True)
    assert clean.findings == ()


@pytest.mark.parametrize("command", ["fit", "check"])
def test_cli_strict_exits_2_and_plain_run_prints_the_code(tmp_path, navion_3211, capsys, command):
    path = tmp_path / "az_ms2.csv"
    _corrupt(navion_3211, "az_ms2").to_csv(path)
    extra = ["--aircraft", "navion", "--model", "dimensional"] if command == "fit" else ["--airspeed", str(NAVION.U)]
    assert main([command, str(path), *extra, "--strict"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "units.az" in err[0]
    main([command, str(path), *extra])
    assert "[units.az]" in capsys.readouterr().out


def test_check_costs_little_against_a_fit(navion_3211):
    """The check is always on: it must be a small fraction of the cheapest fit (a ratio, not a time)."""
    import time

    model = fdml.make_model("dimensional", "navion")
    t0 = time.perf_counter()
    for _ in range(5):
        check_data(navion_3211, airspeed=NAVION.U)
    t_check = (time.perf_counter() - t0) / 5
    t0 = time.perf_counter()
    fdml.fit(navion_3211, model, check=False)
    t_fit = time.perf_counter() - t0
    assert t_check < 0.5 * t_fit


def test_batch_table_carries_findings_and_strict_fails_the_record(tmp_path, navion_3211, capsys):
    import csv

    good, bad = tmp_path / "good.csv", tmp_path / "bad.csv"
    navion_3211.to_csv(good)
    _corrupt(navion_3211, "az_ms2").to_csv(bad)
    common = [str(good), str(bad), "--aircraft", "navion", "--model", "dimensional", "--serial", "--no-progress"]
    assert main(["batch", *common, "--output", str(tmp_path / "plain")]) == 0
    with open(tmp_path / "plain" / "table.csv") as fh:
        rows = {r["key"]: r for r in csv.DictReader(fh)}
    assert rows["good"]["findings"] == "" and rows["bad"]["findings"] == "units.az"
    assert "bad: units.az" in capsys.readouterr().out
    assert main(["batch", *common, "--output", str(tmp_path / "strict"), "--strict"]) == 1
    with open(tmp_path / "strict" / "table.csv") as fh:
        rows = {r["key"]: r for r in csv.DictReader(fh)}
    assert rows["good"]["status"] == "ok"
    assert rows["bad"]["status"] == "error" and "units.az" in rows["bad"]["error"]


def test_diagnose_keeps_findings_and_strict_refuses(navion_3211):
    from fdml.diagnose import diagnose

    bad = _corrupt(navion_3211, "q_flip")
    with pytest.raises(DataCheckError, match="sign.q"):
        diagnose([bad], fdml.make_model("dimensional", "navion"), strict=True)
