"""tests/independent_truth.py, the time-domain truth that no fdml code made, against closed forms.

References are computed here from the equations, never from the simulator's own output: the
2-state system's eigen-decomposition (step response, free decay), Cramer's rule (steady state),
central differences of the continuous solution (docs/theory.md Eq. 5 and the accelerometer's
q_dot), and scipy.signal.lsim on a grid fine enough for its first-order hold.
"""

from __future__ import annotations

import numpy as np
import pytest
from independent_truth import (
    NAVION,
    PRE_ROLL,
    U_NAVION,
    G,
    Manoeuvre,
    Sensors,
    measure,
    simulate_record,
    solve,
)
from scipy import signal

P = NAVION
A = np.array([[P["Z_a"], 1 + P["Z_q"]], [P["M_a"], P["M_q"]]])
B = np.array([P["Z_de"], P["M_de"]])
#: The integration runs at rtol 1e-10: measured errors against the closed forms are 2e-12 rad and
#: 1.3e-11 rad/s on states of 0.02-0.07, so 1e-9 of each signal's peak bounds it with room.
REL = 1e-9


def _modal(t_since: np.ndarray, forcing: np.ndarray):
    """x and x_dot of x' = A x from x(0) = 0 under the constant forcing vector (closed form, modal)."""
    lam, V = np.linalg.eig(A)
    c = np.linalg.solve(V, forcing)
    e = np.exp(np.outer(lam, t_since))
    x = np.real(V @ ((e - 1.0) / lam[:, None] * c[:, None]))
    xd = np.real(V @ (e * c[:, None]))
    return x, xd


def _free(t: np.ndarray, x0) -> np.ndarray:
    """x(t) = V exp(Lambda t) V^-1 x0: free motion from x0 at t = 0 (any sign of t)."""
    lam, V = np.linalg.eig(A)
    return np.real(V @ (np.exp(np.outer(lam, t)) * np.linalg.solve(V, np.asarray(x0))[:, None]))


def test_step_between_samples_matches_the_eigen_closed_form():
    """A true elevator step at 1.0137 s (between samples): alpha, q and a_z are the modal closed form."""
    a, u = 1.0137, 0.02
    rec, _ = simulate_record(Manoeuvre(kind="step", edge="step", start=a, amplitude=u), dt=0.02, duration=6.0)
    t = rec.t
    x, xd = _modal(np.clip(t - a, 0.0, None), B * u)
    xd = xd * (t >= a)
    az = U_NAVION / G * (xd[0] - x[1])  # Eq. 5 from the closed form's own derivative
    for ch, ref in (("alpha", x[0]), ("q", x[1]), ("az", az)):
        assert np.abs(rec[ch] - ref).max() < REL * np.abs(ref).max(), ch
    # the record samples the step: old level before 1.0137 s, new level from the 1.02 s sample on
    assert np.array_equal(rec["de"], u * (t >= a))
    # 6.3 ms after the step the response has begun: a step moved onto the 1.02 s sample would miss
    # this by far more than the tolerance
    k = int(np.searchsorted(t, a))
    assert abs(rec["q"][k]) > 1e3 * REL * np.abs(x[1]).max()


def test_steady_state_gains_are_cramers_rule():
    """Long after a held step: alpha_ss, q_ss from Cramer's rule of A x + B de = 0; a_z = -(U/g) q_ss."""
    u = 0.02
    traj = solve(Manoeuvre(kind="step", edge="step", start=1.0, amplitude=u), 40.0)
    det = P["Z_a"] * P["M_q"] - (1 + P["Z_q"]) * P["M_a"]
    alpha_ss = -(P["M_q"] * P["Z_de"] - (1 + P["Z_q"]) * P["M_de"]) / det * u
    q_ss = -(P["Z_a"] * P["M_de"] - P["M_a"] * P["Z_de"]) / det * u
    y = measure(traj, [40.0])  # 39 s at a decay rate of 2.45 1/s: transients below 1e-40
    assert y["alpha"][0] == pytest.approx(alpha_ss, rel=REL)
    assert y["q"][0] == pytest.approx(q_ss, rel=REL)
    assert y["az"][0] == pytest.approx(-U_NAVION / G * q_ss, rel=REL)
    assert alpha_ss < 0 and q_ss < 0  # trailing edge down: nose down (docs/theory.md section 1)


def test_off_trim_start_decays_freely_before_and_after_the_first_sample():
    """No manoeuvre, x(0) = x0: the state is the free motion for t in [-PRE_ROLL, 5] s."""
    x0 = (0.004, -0.01)
    traj = solve(Manoeuvre(start=100.0), 5.0, x0=x0)
    t = np.linspace(-PRE_ROLL, 5.0, 301)
    ref = _free(t, x0)
    assert np.abs(traj.state(t) - ref).max() < REL * np.abs(ref).max()
    rec, _ = simulate_record(Manoeuvre(start=100.0), dt=0.02, duration=5.0, x0=x0)
    assert (rec["alpha"][0], rec["q"][0]) == pytest.approx(x0, abs=1e-15)


def _cosine_case():
    traj = solve(Manoeuvre(width=0.1), 6.0, x0=(0.002, 0.01))
    return traj, np.linspace(0.3, 5.7, 500)


#: Central differences at h = 1e-4 s: truncation h^2/6 |x'''|; on this 3-2-1-1 (edges of 0.1 s,
#: de'' up to 0.04 (pi/0.1)^2/2 = 20 rad/s^2) |q'''| stays below about 400 rad/s^4 (M_de de''
#: dominates) and |alpha'''| below about 30 rad/s^3, so the errors are below 7e-7 rad/s^2 and
#: 5e-8 rad/s; the dense output's own error (1e-11) over 2h adds 5e-8.
H, TOL_QDOT, TOL_ADOT = 1e-4, 1e-6, 1e-7


def test_az_is_eq5_of_the_differenced_alpha():
    """a_z at the c.g. = (U/g)(d alpha/dt - q) (docs/theory.md Eq. 5), alpha differenced."""
    traj, t = _cosine_case()
    adot = (traj.state(t + H)[0] - traj.state(t - H)[0]) / (2 * H)
    ref = U_NAVION / G * (adot - traj.state(t)[1])
    assert np.abs(measure(traj, t)["az"] - ref).max() < U_NAVION / G * TOL_ADOT


def test_accelerometer_offset_is_minus_x_qdot_over_g():
    """a_z at x ahead of the c.g. = a_z - x q_dot/g, q_dot checked against the differenced q."""
    traj, t = _cosine_case()
    x = -2.5
    qdot = (traj.state(t + H)[1] - traj.state(t - H)[1]) / (2 * H)
    shifted = measure(traj, t, Sensors(x_az=x))["az"] - measure(traj, t)["az"]
    assert np.abs(shifted - (-x * qdot / G)).max() < abs(x) / G * TOL_QDOT
    assert np.abs(shifted).max() > 100 * abs(x) / G * TOL_QDOT  # the offset is far above the tolerance


def test_vane_offset_is_minus_x_q_over_u_and_leaves_the_rest():
    """alpha at x_alpha ahead = alpha - x q / U; q and a_z unchanged; a scale factor multiplies."""
    traj, t = _cosine_case()
    clean = measure(traj, t)
    moved = measure(traj, t, Sensors(x_alpha=2.5, scales={"q": 1.03}))
    assert np.allclose(moved["alpha"], clean["alpha"] - 2.5 * clean["q"] / U_NAVION, rtol=0, atol=1e-15)
    assert np.array_equal(moved["az"], clean["az"])
    assert np.allclose(moved["q"], 1.03 * clean["q"], rtol=1e-15, atol=0)


def test_delay_is_the_continuous_signal_tau_earlier_even_before_the_first_sample():
    """A 40 ms lag at 50 Hz is exactly two samples; the first two are the free motion before t = 0."""
    x0 = (0.003, -0.02)
    man = Manoeuvre(edge="step", start=1.0137)
    late, _ = simulate_record(man, Sensors(delays={"alpha": 0.04, "az": 0.04}), dt=0.02, duration=4.0, x0=x0)
    clean, _ = simulate_record(man, dt=0.02, duration=4.0, x0=x0)
    for ch in ("alpha", "az"):
        assert np.abs(late[ch][2:] - clean[ch][:-2]).max() < REL * np.abs(clean[ch]).max(), ch
    assert np.array_equal(late["q"], clean["q"])
    before = _free(np.array([-0.04, -0.02]), x0)
    assert late["alpha"][:2] == pytest.approx(before[0], rel=REL)


def test_delay_off_the_sample_grid_reads_the_dense_solution():
    """A 13 ms lag at 50 Hz: the reading at t is the continuous alpha at t - 13 ms (dense output)."""
    man = Manoeuvre(width=0.07)
    rec, _ = simulate_record(man, Sensors(delays={"alpha": 0.013}), dt=0.02, duration=4.0)
    traj = solve(man, 4.0)
    assert np.abs(rec["alpha"] - traj.state(rec.t - 0.013)[0]).max() < REL * np.abs(rec["alpha"]).max()


def test_two_sample_intervals_agree_at_common_times():
    """dt 0.01 and 0.04 s of one case (step edges off the grid, offsets, lags): equal at every 0.04 s."""
    man = Manoeuvre(edge="step", start=1.0137)
    s = Sensors(x_alpha=1.0, x_az=-2.0, delays={"alpha": 0.033, "az": 0.011}, scales={"q": 1.03})
    fine, _ = simulate_record(man, s, dt=0.01, x0=(0.003, 0.01))
    coarse, _ = simulate_record(man, s, dt=0.04, x0=(0.003, 0.01))
    assert np.allclose(fine.t[::4], coarse.t, rtol=0, atol=1e-12)
    for ch in ("de", "alpha", "q", "az"):
        assert np.abs(fine[ch][::4] - coarse[ch]).max() <= REL * np.abs(coarse[ch]).max(), ch


def test_smooth_3211_agrees_with_lsim_on_a_fine_grid():
    """A raised-cosine 3-2-1-1 against scipy.signal.lsim (first-order hold) on a 0.25 ms grid.

    The hold's error on the input is h^2/8 |de''| = (2.5e-4)^2/8 * 20 = 1.6e-7 rad, which moves
    the outputs by well under 1e-6 of their peaks (measured: 2e-7 to 7e-7).
    """
    man = Manoeuvre(width=0.1)
    rec, _ = simulate_record(man, dt=0.02, duration=6.0)
    h = 2.5e-4
    tf = np.arange(round(6.0 / h) + 1) * h
    k = U_NAVION / G
    C = np.array([[1, 0], [0, 1], [k * P["Z_a"], k * P["Z_q"]]])
    D = np.array([[0], [0], [k * P["Z_de"]]])
    _, y, _ = signal.lsim(signal.StateSpace(A, B[:, None], C, D), man(tf), tf, interp=True)
    idx = np.round(rec.t / h).astype(int)
    for i, ch in enumerate(("alpha", "q", "az")):
        assert np.abs(rec[ch] - y[idx, i]).max() < 2e-6 * np.abs(y[:, i]).max(), ch


def test_step_offsets_give_the_apparent_input_delay():
    """The truth says how far each sampled step lies from mid-interval: 1.0137 s at 50 Hz is 3.7 ms."""
    _, truth = simulate_record(Manoeuvre(edge="step", start=1.0137, unit=0.3), dt=0.02)
    # edges at 1.0137 + 0.3 k: every one 3.7 ms after the middle of 1.00-1.02 (shifted by whole samples)
    assert truth["step_offsets"] == pytest.approx([0.0037] * 5, abs=1e-9)
    _, smooth = simulate_record(Manoeuvre(), dt=0.02)
    assert smooth["step_offsets"] == []


def test_noise_is_a_seeded_fraction_of_each_channels_rms():
    """Same seed, same record; the noise's std is the fraction of the clean channel's RMS."""
    man, s = Manoeuvre(), Sensors(x_alpha=1.0)
    clean, _ = simulate_record(man, s, dt=0.01)
    one, _ = simulate_record(man, s, dt=0.01, noise=0.05, rng=np.random.default_rng(7))
    two, _ = simulate_record(man, s, dt=0.01, noise=0.05, rng=np.random.default_rng(7))
    n = clean.n
    for ch in ("alpha", "q", "az"):
        assert np.array_equal(one[ch], two[ch])
        ratio = np.std(one[ch] - clean[ch]) / (0.05 * np.sqrt(np.mean(clean[ch] ** 2)))
        # the sample std of n = 1201 normals scatters by 1/sqrt(2n) = 2 %: 5 of those
        assert abs(ratio - 1) < 5 / np.sqrt(2 * n), ch
    assert np.array_equal(one["de"], clean["de"])


@pytest.mark.parametrize(
    "make, text",
    [
        (lambda: Sensors(delays={"theta": 0.01}), "unknown channel 'theta'"),
        (lambda: Sensors(scales={"de": 1.1}), "unknown channel 'de'"),
        (lambda: Sensors(delays={"alpha": -0.02}), "causal"),
        (lambda: Manoeuvre(edge="square"), "edge 'square' unknown"),
        (lambda: Manoeuvre(kind="sine"), "kind 'sine' unknown"),
        (lambda: Manoeuvre(width=0.5, unit=0.3), "width < unit"),
        (lambda: simulate_record(noise=0.1), "seeded numpy Generator"),
    ],
)
def test_bad_truth_is_refused_with_one_line(make, text):
    with pytest.raises(ValueError, match=text) as exc:
        make()
    assert "\n" not in str(exc.value)
