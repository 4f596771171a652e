"""Could Klein's boundary terms cover every state of the realisation? (issue 22 item 3's question)

fdml estimates the boundary values x(0), x(T) of alpha and q (and of theta's integrator); the
unsteady model's lag states (x_w, x_t, x_G, docs/theory.md section 4) are not among them, so a
record that does not end at rest is misfit by the unsteady model itself (benchmarks/
compare_calibration.py: the multisine off its harmonics).  Measured here on the Navion unsteady
and Sundowner unsteady models with F = 0 (the downwash memory of the F term has no finite-state form, so
no boundary values), and a dimensional model with an elevator delay (Pade states):

1. the misfit at the true parameters, noise-free, after the best boundary values by linear least
   squares: with the states alpha, q only (fdml now) and with every state of the realisation
   (H = C (sI - A)^-1, two values per state and record);
2. what the misfit does to the estimate: the noise-free fit (bias) against the standard errors of
   the same fit at 2 % noise;
3. what every state's boundary values would cost: the standard errors with the lag states' columns
   added to the information (linear, at the truth), over those of the fit.

Two records, 50 Hz, band 0.1:10:0.1 rad/s: a 3-2-1-1 cut at 6 s (mid-response), and one period of
the exact periodic response to a 12 s multisine (compare_calibration's source (a), fitted off its
harmonics).  Run: ``python benchmarks/boundary_states.py`` (a few seconds).

Result (issue 22): on the periodic multisine every state's boundary values take the misfit at the
truth from 3.8e-2 (Navion, one lag state) and 2.5e-2 (Sundowner, three) to 1e-7, and the bias from
up to 1.1 standard errors (Sundowner Cz_de, 2 % noise) to zero, for standard errors at most 3 %
larger; on the 3-2-1-1 cut at 6 s the lags have settled and nothing changes.  With the Navion
preset's F term (compare_calibration's unsteady truth) the lag states' columns take 3.5e-2 to 3.3e-2
only: the F term's memory has no state.  Nor do 8 Pade states fix an exact 0.1 s elevator delay
(7.2e-2 to 6.9e-2): its memory is the input of the last 0.1 s, which the record holds.
"""

from __future__ import annotations

import warnings

import numpy as np

import fdml
from fdml.estimate import prepare
from fdml.maneuvers import make_input, time_vector
from fdml.models import realize
from fdml.record import Record, add_noise
from fdml.simulate import _delayed, _foh_march, _system
from fdml.spectral import spectra

THETA = ("CLa_w", "CLa_t", "deps_da", "Cm_de", "Cz_de")
OMEGA = np.arange(0.1, 10.0 + 1e-9, 0.1)


def transient(model, T=6.0, dt=0.02):
    """A 3-2-1-1 cut at T s, and every state at its ends (the exact first-order-hold march)."""
    t = time_vector(T, dt)
    de = make_input("3211", t, np.deg2rad(1.0))
    sys = _system(model, model.values())
    x = _foh_march(sys, dt, np.column_stack([_delayed(t - t[0], de, d, t - t[0]) for _, d in sys.channels]))
    y = x @ sys.C.T + de[:, None] @ sys.D.T
    rec = Record(t, {"de": de, **dict(zip(model.outputs, y.T))}, name="3211 cut")
    return rec, x[0], x[-1]


def periodic(model, T=12.0, dt=0.02, shift_input=0.0):
    """One period of the exact periodic response to a multisine (delayed by ``shift_input`` s): x(0) = x(T)."""
    t = np.arange(int(round(T / dt))) * dt
    de = make_input("multisine", t, np.deg2rad(1.0))
    real = realize(model)
    s = 2j * np.pi * np.fft.rfftfreq(t.size, dt)
    U = np.fft.rfft(de) * np.exp(-s * shift_input)  # the periodic input, delayed exactly
    X = np.linalg.solve(s[:, None, None] * np.eye(real.states) - real.A, real.B[None] * U[:, None, None])[..., 0]
    x = np.fft.irfft(X, n=t.size, axis=0)  # (n, states); s = 0 is regular (a stable model)
    y = x @ real.C.T + de[:, None] @ real.D.T
    rec = Record(t, {"de": de, **dict(zip(model.outputs, y.T))}, name="multisine, periodic")
    return rec, x[0], x[-1]


def _state_space(model, pade=None):
    """(A, B, C, D) of the model's realisation (with Pade states of its delays when ``pade`` is given)."""
    if pade is None:
        real = realize(model)
        return real.A, real.B, real.C, real.D
    from fdml.export import to_statespace

    ss = to_statespace(model, pade=pade)
    return ss.A, ss.B, ss.C, ss.D


def periodic_exact(model, T=12.0, dt=0.02):
    """One period of the exact periodic response to a multisine, from the model's own frequency response."""
    t = np.arange(int(round(T / dt))) * dt
    de = make_input("multisine", t, np.deg2rad(1.0))
    w = 2 * np.pi * np.fft.rfftfreq(t.size, dt)
    G = model.frequency_response(np.maximum(w, 1e-9))[:, 0, :]  # s = 0 by its limit
    y = np.fft.irfft(G * np.fft.rfft(de)[None, :], n=t.size, axis=1)
    return Record(t, {"de": de, **dict(zip(model.outputs, y))}, name="multisine, periodic")


def misfits(model, rec, x0=None, xT=None, pade=None, states_of=None):
    """Relative misfit after the best boundary values and output biases (linear least squares), noise-free.

    Columns: alpha and q's boundary values with the model's exact response (fdml now), and every state's
    with the realisation's response (its own, Pade for a delay), and, given, every state's true end values.
    """
    d = spectra(rec, OMEGA, trim="none")
    A, B, C, D = _state_space(states_of or model, pade)  # states_of: the F = 0 model of one with an F term
    s, shift = 1j * d.omega, np.exp(-1j * d.omega * d.T)
    Hs = np.einsum("ik,mkj->mij", C, np.linalg.inv(s[:, None, None] * np.eye(A.shape[0]) - A))
    Greal = Hs @ B + D
    ones = np.zeros((d.m, 3, 3), complex)
    ones[:, [0, 1, 2], [0, 1, 2]] = d.ones[:, None]
    out = []
    Gm = model.evaluate(d.omega).G
    for G, cols in ((Gm, slice(0, 2)), (Gm if states_of else Greal, slice(0, A.shape[0]))):
        r = d.z - (G @ d.u[:, :, None])[..., 0]
        N = np.concatenate([Hs[:, :, cols], -Hs[:, :, cols] * shift[:, None, None], ones], axis=2)
        X = N.reshape(-1, N.shape[2])
        X = X / np.linalg.norm(X, axis=0)  # the Pade states' columns span 17 decades: scale them
        eta = np.linalg.lstsq(np.vstack([X.real, X.imag]), np.concatenate([r.ravel().real, r.ravel().imag]))[0]
        out.append(np.linalg.norm(r.ravel() - X @ eta) / np.linalg.norm(d.z))
    if x0 is not None:
        r = d.z - (Greal @ d.u[:, :, None])[..., 0]
        N = np.concatenate([Hs, -Hs * shift[:, None, None]], axis=2)
        out.append(np.linalg.norm(r - N @ np.concatenate([x0, xT])) / np.linalg.norm(d.z))
    return out, Hs[:, :, 2:], shift


def bias_and_cost(model, rec, lag, shift):
    """First-order bias of the estimate (one Gauss-Newton step from the truth, noise-free record) and its
    standard errors, weighted by R of the same record at 2 % noise: with fdml's boundary values, and with
    the lag states' added.  (A noise-free fit itself says nothing: its residual, one missing column, makes
    R singular and det R zero at the truth.)"""
    noisy = add_noise(rec, 0.02, np.random.default_rng(1), relative=True)
    W = np.linalg.inv(np.asarray(fdml.fit(noisy, model, band=(0.1, 10.0, 0.1)).R))
    prob = prepare(rec, model, band=(0.1, 10.0, 0.1))
    theta0 = prob.initial()  # the truth, the measured ends, zero biases
    A, r0 = prob.sensitivities(theta0), prob.residuals(theta0)
    out = []
    for X in (A, np.concatenate([A, lag, -lag * shift[:, None, None]], axis=2)):
        info = np.real(np.einsum("mip,ij,mjq->pq", X.conj(), W, X))
        cov = np.linalg.inv(info)
        step = cov @ np.real(np.einsum("mip,ij,mj->p", X.conj(), W, r0))
        se = np.sqrt(np.diag(cov))
        out.append((step[: len(THETA)], se[: len(THETA)]))
    (b2, se2), (ball, seall) = out
    return b2 / se2, ball / seall, seall / se2


def main() -> None:
    warnings.simplefilter("ignore")
    print("| model | record | states | misfit: alpha & q boundary values | every state's | every state's true ends |")
    print("|---|---|---|---|---|---|")
    rows = []
    for ac in ("navion", "sundowner"):
        model = fdml.make_model("unsteady", ac).with_values(F=0.0)
        for rec, x0, xT in (transient(model), periodic(model)):
            m, lag, shift = misfits(model, rec, x0, xT)
            rows.append((model, ac, rec, lag, shift))
            n = realize(model).states
            print(f"| {ac} unsteady, F = 0 | {rec.name} | {n} | {m[0]:.2e} | {m[1]:.2e} | {m[2]:.2e} |")
    with_f = fdml.make_model("unsteady", "navion")  # the preset's F term: a memory with no states
    rec = periodic_exact(with_f)
    m, _, _ = misfits(with_f, rec, states_of=with_f.with_values(F=0.0))
    F = with_f.parameters["F"].value
    print(f"| navion unsteady, F = {F:g} | {rec.name} | 3 + F | {m[0]:.2e} | {m[1]:.2e} | - |")
    delayed = fdml.make_model("dimensional", "navion").with_values(tau_de=0.1)
    rec = periodic(delayed.with_values(tau_de=0.0), shift_input=0.1)[0]
    m, _, _ = misfits(delayed, rec, pade=8)
    print(f"| navion dimensional, tau_de 0.1 s (Pade 8) | {rec.name} | 10 | {m[0]:.2e} | {m[1]:.2e} | - |")
    print("\n| model | record | parameter | bias / s.e. (2 % noise), fdml now | every state | s.e. ratio |")
    print("|---|---|---|---|---|---|")
    for model, ac, rec, lag, shift in rows:
        now, every, ratio = bias_and_cost(model, rec, lag, shift)
        for k, n in enumerate(THETA):
            print(f"| {ac} | {rec.name} | {n} | {now[k]:+.2f} | {every[k]:+.2f} | {ratio[k]:.2f} |")


if __name__ == "__main__":
    main()
