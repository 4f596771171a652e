"""Data-quality checks: synthetic records with known defects, the three real records, ``fdml check``."""

import json
import math

import numpy as np
import pytest
from conftest import lsim_dimensional, three_two_one_one

from fdml.cli import main
from fdml.errors import BandError
from fdml.io import data_path, load_record
from fdml.models import make_model
from fdml.quality import GOOD_COHERENCE, LOW_INPUT_DB, check_quality
from fdml.record import Record

BAND = (0.5, 10.0, 0.1)


def _record(seed=0, duration=20.0, dt=0.02, noise=0.02):
    """Navion dimensional model, 3-2-1-1, noise a fraction of each output's standard deviation."""
    m = make_model("dimensional", "navion")
    t = np.arange(0, duration + 1e-9, dt)
    de = three_two_one_one(t)
    y = lsim_dimensional(m, t, de)
    rng = np.random.default_rng(seed)
    y = y + noise * y.std(axis=0) * rng.standard_normal(y.shape)
    sig = {"de": de, "alpha": 0.05 + y[:, 0], "q": y[:, 1], "az": -1.0 + y[:, 2], "V": 50.0 + 0.1 * np.sin(0.3 * t)}
    return Record(t, sig, name="synthetic")


def test_clean_record_has_no_findings_of_defects():
    rep = check_quality(_record(), BAND)
    for c in rep.channels:
        assert c.holds == () and c.clipped == (), c
    assert rep.sufficient
    assert rep.jitter < 1e-9
    assert rep.n == 1001 and rep.dt == pytest.approx(0.02)
    # 2 % noise: linear outputs are coherent with the input over the excited band
    assert np.median(rep.coherence["q"]) > 0.9
    assert any("no dropouts or saturation" in f for f in rep.findings)
    d = rep.to_dict()
    json.dumps(d)  # JSON-safe
    assert d["sufficient"] is True and len(d["channels"]) == 5


def test_dropout_is_found_where_it_is():
    rec = _record()
    a = rec["alpha"].copy()
    a[400:412] = a[400]  # held for 12 samples (0.22 s) during the 3-2-1-1
    rep = check_quality(rec.with_signals(alpha=a), BAND)
    holds = rep.channel("alpha").holds
    assert len(holds) == 1
    start, dur = holds[0]
    assert start == pytest.approx(400 * 0.02) and dur == pytest.approx(11 * 0.02)
    assert any(f.startswith("alpha holds its value") for f in rep.findings)
    assert rep.channel("q").holds == ()


def test_saturation_is_found_and_a_smooth_peak_is_not():
    rec = _record(noise=0.0)
    az = rec["az"]
    top = az.max() - 0.3 * (az.max() - az.mean())
    rep = check_quality(rec.with_signals(az=np.minimum(az, top)), BAND)
    assert "max" in rep.channel("az").clipped and "min" not in rep.channel("az").clipped
    assert rep.channel("az").flat_max > 0.05
    assert any("saturation" in f for f in rep.findings)
    # the unclipped noise-free peak is smooth: not flagged
    assert check_quality(rec, BAND).channel("az").clipped == ()


def test_slow_update_channel():
    rec = _record()
    t = rec.t
    held = rec["V"][(np.floor(t * 2.0) / 2.0 / 0.02).round().astype(int)]  # new value every 0.5 s
    rep = check_quality(rec.with_signals(V=held), BAND)
    c = rep.channel("V")
    assert c.change_rate == pytest.approx(2.0, abs=0.1)
    assert c.repeat_fraction > 0.95
    assert any("V changes value only" in f for f in rep.findings)


def test_jitter_is_measured():
    rec = _record()
    t = rec.t + 0.02 * 5e-4 * (np.arange(rec.n) % 2)  # every other interval 0.05 % longer
    rep = check_quality(Record(t, rec.signals), BAND)
    assert rep.jitter == pytest.approx(5e-4, rel=0.05)


def test_band_without_input_is_insufficient():
    t = np.arange(0, 30 + 1e-9, 0.02)
    de = 0.02 * np.exp(-0.5 * ((t - 15) / 3.0) ** 2)  # Gaussian pulse: spectrum exp(-w^2 9/2)
    rng = np.random.default_rng(4)
    rec = Record(
        t,
        {
            "de": de,
            "alpha": 0.3 * de + 1e-4 * rng.standard_normal(t.size),
            "q": 1e-4 * rng.standard_normal(t.size),
            "az": -1 + 1e-3 * rng.standard_normal(t.size),
        },
    )
    rep = check_quality(rec, (3.0, 10.0, 0.1))
    # at 3 rad/s the pulse is exp(-40.5) in energy below its peak: about -176 dB
    assert np.all(rep.input_db < -LOW_INPUT_DB)
    assert rep.low_input == ((3.0, 10.0),)
    assert not rep.sufficient and rep.useful_frequencies == 0
    assert rep.findings[0].startswith("excitation INSUFFICIENT")
    assert rep.input_energy_fraction < 1e-10
    # the same record over a band that holds the pulse's energy is fine
    rep2 = check_quality(rec, (0.05, 0.6, 0.01))
    assert rep2.input_energy_fraction > 0.5


def test_short_record_uses_daniell_and_long_record_welch():
    short = check_quality(_record(duration=6.0), (0.63, 9.4, 0.1))
    assert "too short" in short.coherence_method and "Daniell" in short.coherence_method
    # 5 averages: 1 - 0.05**(1/4)
    assert short.coherence_threshold == pytest.approx(1 - 0.05**0.25)
    assert any("too short" in f for f in short.findings)
    long = check_quality(_record(duration=60.0), (1.0, 10.0, 0.1))
    assert long.coherence_method.startswith("Welch")
    assert long.coherence_omega.min() >= 1.0


def test_welch_coherence_equals_scipy():
    """fdml's numpy Welch (no scipy.signal on the fit path, issue 20) against scipy.signal.coherence.

    Both compute the same sums in double precision; the ratio differs only by rounding (1e-12
    leaves a factor of 1e3 over the ~1e-15 relative rounding of a few hundred products).
    """
    from scipy import signal

    from fdml.quality import _welch

    rec = _record(duration=30.0, noise=0.3)
    n, fs = rec.n, 1 / rec.dt
    nper = int(2 * n / 8)
    Y = np.vstack([rec[k] for k in ("alpha", "q", "az")])
    f, pxx, pyy, pxy = _welch(rec["de"], Y, fs, nper, nper // 2)
    ours = np.abs(pxy) ** 2 / (pxx * pyy)
    for i, k in enumerate(("alpha", "q", "az")):
        f_ref, ref = signal.coherence(rec["de"], rec[k], fs=fs, nperseg=nper, noverlap=nper // 2)
        np.testing.assert_allclose(f, f_ref, rtol=1e-14)
        np.testing.assert_allclose(ours[i], ref, rtol=1e-12, atol=1e-14)
        # the cross spectrum's phase too (a coherence hides a conjugate mistake)
        _, ref_xy = signal.csd(rec["de"], rec[k], fs=fs, nperseg=nper, noverlap=nper // 2)
        np.testing.assert_allclose(np.angle(pxy[i][1:-1]), np.angle(ref_xy[1:-1]), atol=1e-10)


def test_coherence_drops_with_noise():
    quiet = check_quality(_record(noise=0.01, duration=40.0), BAND)
    loud = check_quality(_record(noise=3.0, duration=40.0), BAND)
    assert np.median(loud.coherence["alpha"]) < GOOD_COHERENCE < np.median(quiet.coherence["alpha"])


def test_band_above_nyquist():
    with pytest.raises(BandError, match="Nyquist"):
        check_quality(_record(dt=0.1), (0.1, 40.0, 0.1))


# --- the real records ----------------------------------------------------------------------------
def test_twin_otter_quality():
    rec = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
    rep = check_quality(rec, (0.63, 9.4, 0.1))
    assert rep.sufficient
    assert "Daniell" in rep.coherence_method  # 6 s cannot resolve 0.1 Hz with Welch segments
    v = rep.channel("V")
    assert v.n_levels <= 10 and v.repeat_fraction > 0.85  # airspeed: 9 values in 6 s
    assert rep.input_energy_fraction > 0.7
    assert np.median(rep.coherence["q"]) > 0.9


def test_hfb320_quality_finds_the_frozen_samples():
    rec = load_record(data_path("hfb320/hfb320_1_10.asc"))
    rep = check_quality(rec, (0.3, 10.0, 0.1))
    assert rep.coherence_method.startswith("Welch")
    # at 48.0-48.2 s a_z, V and alpha repeat their values exactly while the motion goes on
    az_holds = rep.channel("az").holds
    assert any(abs(s - 48.0) < 0.15 for s, _ in az_holds)
    assert rep.jitter > 1e-5  # time stamps written to 5 decimals


def test_attas_quality():
    rec = load_record(data_path("attas/fAttasElv1.mat"))
    rep = check_quality(rec, (0.3, 8.0, 0.1))
    assert rep.sufficient and rep.input_energy_fraction > 0.9
    assert math.isclose(rep.dt, 0.04)


# --- command line --------------------------------------------------------------------------------
def test_fdml_check_cli(tmp_path, capsys):
    f = _record().to_csv(tmp_path / "r.csv")
    code = main(["check", str(f), "--band", "0.5:10:0.1", "--json"])
    out = capsys.readouterr().out
    assert code == 0
    d = json.loads(out)
    assert d["quality"]["sufficient"] is True and "compatibility" not in d
    code = main(["check", str(f), "--band", "0.5:10:0.1", "--t0", "2", "--t1", "12"])
    out = capsys.readouterr().out
    assert code == 0 and "Data quality" in out and "501 samples" in out
    code = main(["check", str(tmp_path / "absent.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "absent.csv" in err


def test_fdml_check_real_record_with_compat(capsys):
    path = data_path("twin_otter/totter_lon_020213f1_017.mat")
    code = main(["check", str(path), "--band", "0.63:9.4:0.1", "--compat", "--json"])
    d = json.loads(capsys.readouterr().out)
    assert code == 0
    assert "tau_alpha" in d["compatibility"]["params"]
    assert d["quality"]["n"] == 301
