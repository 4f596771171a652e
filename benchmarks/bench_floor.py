"""fdml.fit against the numpy floor of its numerics, as ratios measured in one run (issue 20).

Run with ``python benchmarks/bench_floor.py [--reps N] [--profile]`` (FDML_DATA
must name the shared data; default 15 repetitions).

The case is the issue's: Twin Otter record 017, the ``dimensional`` model, 71
frequencies of the band 0.6283:9.4248:0.12566 rad/s, output biases and
boundary values estimated, started from the model's default values.

**The floor** is the least a fit of this model can do in numpy, written here
independently of fdml (only the record's samples come from fdml.io):

* trim (first sample) removed and the transforms taken by direct sums
  (trapezoid rule, one complex matrix product);
* the 2 x 2 response and its sensitivities in closed form: with
  ``x = M^-1 (B u + d)`` the predicted state and ``P = C M^-1``,
  ``dy/dA_ij = P[:, i] x_j`` and ``dy/dB_i = P[:, i] u``;
* the seven nuisance values (three output biases, x(0) and x(T) of alpha and q)
  projected out by a QR factorisation of their exact, whitened columns;
* a Gauss-Newton step on ln det R (docs/theory.md Eqs. 23-25) with R from the
  residuals at the current theta (Eq. 24), for a fixed number of passes.

Candidates, on the same data, each to fdml's convergence test (every step below
1e-3 standard errors) or a cap of passes:

* the floor run on to convergence (it has a slow mode on this record: the
  residuals of the three outputs are 84-96 % correlated, so R moves with theta
  and a step that holds R ignores most of the curvature along one direction);
* R held fixed until theta settles, then re-estimated;
* exact Newton on ln det R (the Hessian of the concentrated likelihood, with the
  dependence of R on theta), the nuisance values eliminated by their Schur
  complement, with Levenberg-Marquardt damping where it is indefinite.

And fdml itself: ``fdml.fit`` with the data and adequacy checks off, and with its
defaults (both checks on), each as best of N interleaved with the floor so that
load from other processes inflates both alike, and the part of the defaults that
the adequacy check's kinematic evidence takes (:func:`fdml.kinematics.kinematic_evidence`
on the fit's spectra, timed alone).  Then the pieces of one pass:
the floor's pass against fdml's trial point, sensitivities (through
``Model.forced_sensitivity``, one batched solve, and the same by the derivative
matrices as before), gradient and Hessian, and step, with the number of passes
and trial points of the fit.  ``--profile`` adds a cProfile of the warm fit
(checks off), sorted by own time.

On a machine shared with other work, OpenBLAS's threads make the timings of
small matrix products erratic; ``OPENBLAS_NUM_THREADS=1`` gives steadier
figures (what a quiet machine shows).
"""

from __future__ import annotations

import argparse
import cProfile
import math
import pstats
import time
import warnings

import numpy as np

warnings.simplefilter("ignore")

import fdml  # noqa: E402
from fdml.constants import G0  # noqa: E402
from fdml.io import data_path, load_record  # noqa: E402

BAND = "0.6283:9.4248:0.12566"
NAMES = ("Z_a", "Z_q", "Z_de", "M_a", "M_q", "M_de")
TOL = 1e-3  # fdml's default: every step below 1e-3 standard errors


def band_grid() -> np.ndarray:
    """The issue's grid: 0.6283 + k 0.12566 rad/s, k = 0..70."""
    lo, hi, step = (float(x) for x in BAND.split(":"))
    return lo + step * np.arange(int(math.floor((hi - lo) / step + 1e-9)) + 1)


# --- the floor --------------------------------------------------------------------------


def transform(rec, omega):
    """Spectra of alpha, q, a_z and de (trim = first sample), and of a unit constant; direct sums."""
    x = np.column_stack([rec[k] - rec[k][0] for k in ("alpha", "q", "az", "de")] + [np.ones(rec.n)])
    w = np.full(rec.n, rec.dt)
    w[[0, -1]] *= 0.5  # trapezoid rule
    X = (np.exp(-1j * np.outer(omega, np.arange(rec.n) * rec.dt)) * w) @ x
    return {"z": X[:, :3], "u": X[:, 3], "ones": X[:, 4], "T": (rec.n - 1) * rec.dt, "omega": omega}


class Floor:
    """The dimensional model's residuals, sensitivities and nuisance columns at theta, in numpy."""

    def __init__(self, spec, U):
        self.z, self.u, self.ones = spec["z"], spec["u"], spec["ones"]
        self.s = 1j * spec["omega"]
        self.e = np.exp(-1j * spec["omega"] * spec["T"])
        self.k = U / G0  # a_z = (U/g)(alpha_dot - q), in g
        self.m = self.z.shape[0]

    def response(self, th):
        """M^-1 (m, 2, 2), P = C M^-1 (m, 3, 2), the response to de (m, 3) and the nuisance columns (m, 3, 7)."""
        Za, Zq, Zde, Ma, Mq, Mde = th
        s = self.s
        det = (s - Za) * (s - Mq) - (1.0 + Zq) * Ma
        inv = np.empty((self.m, 2, 2), complex)
        inv[:, 0, 0], inv[:, 0, 1] = (s - Mq) / det, (1.0 + Zq) / det
        inv[:, 1, 0], inv[:, 1, 1] = Ma / det, (s - Za) / det
        P = np.empty((self.m, 3, 2), complex)
        P[:, :2] = inv
        P[:, 2] = self.k * (s[:, None] * inv[:, 0] - inv[:, 1])
        G = P @ np.array([Zde, Mde])
        H = P.copy()
        H[:, 2, 0] -= self.k  # the transform of alpha_dot is s alpha~ - d_alpha
        C = np.zeros((self.m, 3, 7), complex)
        C[:, [0, 1, 2], [0, 1, 2]] = self.ones[:, None]
        C[:, :, 3:5] = H
        C[:, :, 5:7] = -H * self.e[:, None, None]
        return inv, P, G, C

    def jacobian(self, th, eta, inv, P):
        """dy/dtheta (m, 3, 6) at (theta, eta): P_i x_j for A_ij, P_i u for B_i."""
        d = eta[3:5][None, :] - eta[5:7][None, :] * self.e[:, None]
        x = (inv @ (np.array([th[2], th[5]])[None, :] * self.u[:, None] + d)[:, :, None])[:, :, 0]
        J = np.empty((self.m, 3, 6), complex)
        sources = (x[:, 0], x[:, 1], self.u)  # A_i0, A_i1 (alpha, q) and B_i for row i of (A, B)
        for col in range(6):
            J[:, :, col] = P[:, :, col // 3] * sources[col % 3][:, None]
        return J


def real_rows(X):
    """Complex rows (m, 3, ...) whitened elsewhere -> real stack [Re; Im] of shape (6m, ...)."""
    X = X.reshape((-1,) + X.shape[2:])
    return np.concatenate([X.real, X.imag])


def nuisance_fit(fl, r0, C, Li):
    """QR of the whitened nuisance columns; eta and the residual at its optimum."""
    Q, Rq = np.linalg.qr(real_rows(Li @ C))
    eta = np.linalg.solve(Rq, Q.T @ real_rows((r0 @ Li.T)[:, :, None])[:, 0])
    return Q, eta, r0 - C @ eta


def cov_R(v):
    """Eq. 24: R = (1/m) sum v v^H."""
    return v.T @ v.conj() / v.shape[0]


def floor_fit(fl, th0, passes=10, tol=None, hold=False):
    """Gauss-Newton on ln det R with the nuisance values projected out; (theta, eta, ln det R, passes).

    ``hold``: keep R fixed until the step falls below ``tol`` standard errors, then re-estimate it.
    """
    th = np.array(th0, float)
    Li = np.eye(3)
    fresh = True
    for it in range(1, passes + 1):
        inv, P, G, C = fl.response(th)
        r0 = fl.z - G * fl.u[:, None]
        Q, eta, v = nuisance_fit(fl, r0, C, Li)
        if fresh:  # R from the residuals at theta, then the projection in its metric
            Li = np.linalg.inv(np.linalg.cholesky(cov_R(v)))
            Q, eta, v = nuisance_fit(fl, r0, C, Li)
        J = real_rows(Li @ fl.jacobian(th, eta, inv, P))
        Jp = J - Q @ (Q.T @ J)
        step, *_ = np.linalg.lstsq(Jp, real_rows((v @ Li.T)[:, :, None])[:, 0], rcond=None)
        th = th + step
        if tol is not None:
            se = np.sqrt(np.diag(np.linalg.inv(Jp.T @ Jp)))
            small = np.max(np.abs(step) / se) < tol
            if small and (not hold or fresh):
                break
            fresh = small or not hold
    inv, P, G, C = fl.response(th)
    _, eta, v = nuisance_fit(fl, fl.z - G * fl.u[:, None], C, Li)
    return th, eta, float(np.linalg.slogdet(cov_R(v))[1]), it


def newton_fit(fl, th0, eta0, passes=60, tol=TOL):
    """Exact Newton on ln det R over (theta, eta) jointly, shifted where indefinite; (theta, eta, ln det R, passes)."""
    phi = np.r_[np.asarray(th0, float), eta0]
    N = fl.m

    def state(phi):
        inv, P, G, C = fl.response(phi[:6])
        v = fl.z - G * fl.u[:, None] - C @ phi[6:]
        return inv, P, C, v, float(np.linalg.slogdet(cov_R(v))[1])

    inv, P, C, v, J = state(phi)
    for it in range(1, passes + 1):
        Li = np.linalg.inv(np.linalg.cholesky(cov_R(v)))
        A = np.concatenate([fl.jacobian(phi[:6], phi[6:], inv, P), C], axis=2)  # dy/dphi (m, 3, 13)
        Aw, w = Li @ A, v @ Li.T
        Ar, wr = real_rows(Aw), real_rows(w[:, :, None])[:, 0]
        g = -(2.0 / N) * Ar.T @ wr
        H1 = (2.0 / N) * Ar.T @ Ar
        S = np.einsum("nip,nj->pij", Aw, w.conj())  # sum_n a~_nk w_n^H
        dR = -(S + np.conj(np.transpose(S, (0, 2, 1)))) / N  # whitened dR_k (R~ = I)
        X = dR.reshape(dR.shape[0], -1)
        Hc = H1 - np.real(X @ X.conj().T)
        D = np.sqrt(np.diag(H1))
        lam, Q = np.linalg.eigh(Hc / np.outer(D, D))
        top = lam.max()
        mu = 0.0 if lam.min() > 1e-10 * top else 2.0 * abs(lam.min()) + 1e-8 * top
        step = -(Q @ ((Q.T @ (g / D)) / (lam + mu))) / D
        se = np.sqrt(np.diag(np.linalg.inv(N * H1)))
        if np.max(np.abs(step) / se) < tol:
            return phi[:6], phi[6:], J, it - 1
        for _ in range(12):
            trial = state(phi + step)
            if trial[-1] <= J:
                break
            mu = 4.0 * mu if mu > 0 else 1e-3 * top
            step = -(Q @ ((Q.T @ (g / D)) / (lam + mu))) / D
        phi = phi + step
        inv, P, C, v, J = trial
    return phi[:6], phi[6:], J, passes


# --- measurement ------------------------------------------------------------------------


def interleaved(funcs: dict, reps: int) -> dict:
    """Best wall time of each function over ``reps`` rounds, the functions taking turns."""
    best = dict.fromkeys(funcs, math.inf)
    for _ in range(reps):
        for name, f in funcs.items():
            t0 = time.perf_counter()
            f()
            best[name] = min(best[name], time.perf_counter() - t0)
    return best


def convergence(rec, model, omega, fl, th0, eta0) -> None:
    """Passes, distance from the optimum and ln det R above it, per candidate (trapezoid spectra for all)."""
    ref = fdml.fit(rec, model, omega=omega, check=False, adequacy=False, end_correction="trapezoid")
    est = np.array([ref.params[n] for n in NAMES])
    se = np.array([ref.errors[n] for n in NAMES])
    ld_opt = math.log(ref.cost)
    runs = {
        "floor: Gauss-Newton on ln det R, 10 passes": lambda: floor_fit(fl, th0, passes=10),
        "floor run to convergence (cap 300 passes)": lambda: floor_fit(fl, th0, passes=300, tol=TOL),
        "R held until theta settles (cap 300)": lambda: floor_fit(fl, th0, passes=300, tol=TOL, hold=True),
        "exact Newton on ln det R, numpy": lambda: newton_fit(fl, th0, eta0),
    }
    print(f"  {'candidate':46s} {'passes':>6s} {'off by (se)':>11s} {'ln det R - opt':>15s}")
    for name, f in runs.items():
        th, _, ld, it = f()
        print(f"  {name:46s} {it:6d} {np.max(np.abs(th - est) / se):11.2g} {ld - ld_opt:15.2e}")
    print(f"  {'fdml.fit (end_correction=trapezoid)':46s} {ref.iterations:6d} {0.0:11.2g} {0.0:15.2e}")


def pass_costs(rec, model, omega, fl, th0, reps) -> dict:
    """Best times of the pieces of one pass: the floor's, and fdml's at its start."""
    from fdml.estimate import _cov_R, _grad_hess, _logdet, _naive_sigma, _proposal, prepare
    from fdml.models.base import ModelResponse

    prob = prepare(rec, model, omega=omega)
    th = prob.initial()
    V = prob.residuals(th)
    R = _cov_R(V)
    A = prob.sensitivities(th)
    g, H1, H = _grad_hess(A, V, R, True)
    active = np.ones(g.size, bool)
    names = [prob.slots[i].name for i in prob.model_slots]
    d = prob.data[0]

    def generic_sensitivities():  # the route before issue 20: derivative matrices, then the measurement
        _, dG, dH, _ = model.sensitivity(d.omega, prob.model_values(th), names, ("G", "H"))
        return prob.linear_predict(th, 0, ModelResponse(d.omega, dG, dH, None))

    pieces = {
        "floor: one pass": lambda: floor_fit(fl, th0, passes=1),
        "fdml: trial point (residuals, R, ln det R)": lambda: _logdet(_cov_R(prob.residuals(th))),
        "fdml: sensitivities, one batched solve": lambda: prob.sensitivities(th),
        "  model derivatives only (forced_sensitivity)": lambda: model.forced_sensitivity(
            d.omega, prob.model_values(th), names, *prob._forcing(prob._nuisance(th, 0), 0)
        ),
        "  the same by derivative matrices (before)": generic_sensitivities,
        "fdml: gradient and Hessian of ln det R": lambda: _grad_hess(A, V, R, True),
        "fdml: step test and Newton step": lambda: (_naive_sigma(prob.N * H1), _proposal(g, H1, H, active, True)),
    }
    return interleaved(pieces, reps * 20)


def counted_fit(rec, model, omega):
    """fdml.fit (checks off) with its passes and trial points counted."""
    from fdml import estimate

    calls = {"trial": 0}
    original = estimate._try

    def counting(*a, **k):
        calls["trial"] += 1
        return original(*a, **k)

    estimate._try = counting
    try:
        res = fdml.fit(rec, model, omega=omega, check=False, adequacy=False)
    finally:
        estimate._try = original
    return res.iterations, calls["trial"]


def kinematics_of(rec, model, omega):
    """The short-period identity the defaults' adequacy check runs (fdml.kinematics), on the fit's spectra."""
    from fdml.estimate import prepare
    from fdml.kinematics import kinematic_evidence, known_terms

    prob, known = prepare(rec, model, omega=omega), known_terms(model)
    return lambda: kinematic_evidence(prob.data, float(model.U), known=known)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    rec = load_record(data_path("twin_otter/totter_lon_020213f1_017.mat"))
    U = float(rec.meta["U"])
    omega = band_grid()
    model = fdml.make_model("dimensional", airspeed=U)
    th0 = [model.parameters[n].value for n in NAMES]
    fl = Floor(transform(rec, omega), U)
    eta0 = np.r_[np.zeros(3), 0.0, 0.0, [rec[k][-1] - rec[k][0] for k in ("alpha", "q")]]  # measured x(0), x(T)
    print(f"Twin Otter 017, dimensional, {omega.size} frequencies of {BAND} rad/s, {rec.n} samples\n")
    print("1. convergence from the model's default values (distance in fdml's standard errors)")
    convergence(rec, model, omega, fl, th0, eta0)

    timed = {
        "floor, 10 passes (transform included)": lambda: floor_fit(Floor(transform(rec, omega), U), th0, passes=10),
        "exact Newton on ln det R, numpy (to convergence)": lambda: newton_fit(fl, th0, eta0),
        "fdml.fit, data and adequacy checks off (target <= 2x)": lambda: fdml.fit(
            rec, model, omega=omega, check=False, adequacy=False
        ),
        "fdml.fit, defaults (target <= 3x)": lambda: fdml.fit(rec, model, omega=omega),
        "  of which the adequacy check's kinematic evidence": kinematics_of(rec, model, omega),
    }
    best = interleaved(timed, args.reps)
    floor = best["floor, 10 passes (transform included)"]
    print(f"\n2. whole fits, best of {args.reps} interleaved (ms, ratio to the floor)")
    for label, t in best.items():
        print(f"  {label:58s} {t * 1e3:8.2f} ms {t / floor:6.2f}x")

    passes, trials = counted_fit(rec, model, omega)
    print(f"\n3. one pass, best of {args.reps * 20} interleaved (fdml.fit: {passes} passes, {trials} trial points)")
    try:
        costs = pass_costs(rec, model, omega, fl, th0, args.reps)
    except (ImportError, AttributeError) as exc:  # an fdml from before issue 20
        print(f"  not measured: {exc}")
        costs = {}
    for label, t in costs.items():
        print(f"  {label:58s} {t * 1e3:8.3f} ms")
    if args.profile:
        prof = cProfile.Profile()
        prof.enable()
        for _ in range(20):
            timed["fdml.fit, data and adequacy checks off (target <= 2x)"]()
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(25)


if __name__ == "__main__":
    main()
