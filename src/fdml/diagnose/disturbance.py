"""Test for unmeasured turbulence on the part of the residual that is incoherent with the inputs.

Turbulence that was not measured drives every output through the model's gust
column g(w) = G_w(jw) (per unit gust angle): it adds to the residual a
component incoherent with the elevator but *correlated across channels along
g*.  Independent sensor noise, white or coloured, is uncorrelated across
channels.  So the test (DIAGNOSIS.md 2.6 rule 2: disturbance effects on
non-excited lines, after the deterministic effects) is:

1. in each band, project the residual of the final deterministic model onto
   the orthogonal complement of every input times a low-order polynomial in
   w and a transient per record (the same regression as the gap map, with
   regressors that do not depend on the channel); with an orthonormal basis
   Q_b of that complement, ``x = Q_b^H e`` are m_b independent complex
   samples per band.  This works for any input (3-2-1-1, doublet, multisine)
   and removes smooth model error; it plays the role of the non-excited lines
   of a periodic multisine;
2. fit ``S_b = diag(d_b) + sigma_w^2 M_b`` (H1) against ``diag(d_b)`` (H0) by
   maximum likelihood, with ``M_b = (1/m_b) sum_i w_i (pi T/U^2) Phi(w_i) g_i g_i^H``,
   Phi the one-sided Dryden spectrum of w_g for unit sigma (so that
   ``E|alpha_g~(w)|^2 = pi T Phi(w) / U^2`` for the finite transform over T)
   and w_i the complement's leverage of point i;
3. the null sigma_w = 0 lies on the boundary: LR ~ 0.5 chi2_0 + 0.5 chi2_1.

The result's "shrink" for this noise-kind effect is the share of the
incoherent residual power that the gust term explains (it does not touch the
coherent gap, DIAGNOSIS.md 2.3 step 7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from ..maneuvers import DRYDEN_L, dryden_psd
from .data import AnalysisData
from .effects import with_gust
from .locate import _legendre

__all__ = ["GustTest", "gust_test"]


@dataclass
class GustTest:
    """Result of the unmeasured-turbulence test."""

    lr: float
    p: float
    sigma_w: float
    sigma_w_se: float
    share: float
    n_samples: int
    note: str = ""


def _samples(data: AnalysisData, e: np.ndarray, out_idx, edges):
    """Per band: (samples (m, n_out), rows, leverage weights)."""
    om = data.stacked_omega()
    rec = data.stacked_record()
    dft = data.stacked_dft()
    U = np.concatenate([d.u for d in data.spectra])
    out = []
    nb = edges.size - 1
    for b in range(nb):
        lo, hi = edges[b], edges[b + 1]
        inb = (om >= lo) & ((om <= hi) if b == nb - 1 else (om < hi)) & dft
        rows = np.flatnonzero(inb)
        if rows.size == 0:
            continue
        x = 2.0 * (np.log(om[rows]) - math.log(lo)) / (math.log(hi) - math.log(lo)) - 1.0
        cols = []
        for r in range(data.n_records):
            sel = (rec[rows] == r).astype(float)
            if sel.any():
                cols.append(sel[:, None].astype(complex))
        P = _legendre(x, 2)
        for j in range(U.shape[1]):
            cols.append(P * U[rows, j][:, None])
        X = np.hstack(cols)
        m = rows.size - np.linalg.matrix_rank(X)
        if m < 2:
            continue
        Uq, s, _ = np.linalg.svd(X, full_matrices=True)
        Q = Uq[:, rows.size - m:]  # orthonormal complement of range(X)
        xs = Q.conj().T @ e[rows][:, out_idx]  # (m, n_out)
        lev = np.sum(np.abs(Q) ** 2, axis=1)  # (rows,), sums to m
        out.append((xs, rows, lev))
    return out


def _local_scale(data: AnalysisData, e: np.ndarray, half: int = 3) -> np.ndarray:
    """RMS of each channel's residual over +-``half`` neighbouring DFT points (per record).

    Dividing every channel by a positive, channel-own scale keeps independent
    sensor noise independent across channels (H0 stays exact) while making
    the noise nearly homoscedastic within a band, which the band likelihood
    assumes; the gust column is divided by the same scale.
    """
    out = np.ones(e.shape)
    off = 0
    for d, m in zip(data.spectra, data.dft):
        idx = off + np.flatnonzero(m)
        p2 = np.abs(e[idx]) ** 2
        k = np.ones(2 * half + 1)
        num = np.apply_along_axis(lambda x: np.convolve(x, k, mode="same"), 0, p2)
        den = np.convolve(np.ones(idx.size), k, mode="same")[:, None]
        sc = np.sqrt(num / den)
        # every grid point takes the scale of its nearest DFT point
        pos = np.clip(np.searchsorted(d.omega[m], d.omega), 0, idx.size - 1)
        out[off: off + d.m] = sc[pos]
        off += d.m
    return np.where(out > 0, out, 1.0)


def gust_test(data: AnalysisData, fit, edges: np.ndarray, *, length: float = DRYDEN_L) -> GustTest | None:
    """Likelihood-ratio test for turbulence along the model's gust column (see module doc)."""
    model = fit.model
    out_idx = list(fit.prob.out_idx)
    n = len(out_idx)
    if n < 2:
        return None
    e = fit.full_residual()
    w = _local_scale(data, e)  # per-point, per-channel noise amplitude (positive real)
    bands = _samples(data, e / w, out_idx, edges)
    if not bands:
        return None
    gm = with_gust(model)
    vals = {k: v for k, v in fit.model_values().items() if k in gm.parameters}
    U = model.U
    om = data.stacked_omega()
    Tr = np.concatenate([np.full(d.m, d.T) for d in data.spectra])
    g = (np.concatenate([gm.evaluate(d.omega, vals).G[:, :, 1] for d in data.spectra]) / w)[:, out_idx]
    phi = math.pi * Tr * dryden_psd(om, 1.0, U, length) / U**2  # E|alpha_g~|^2 per unit sigma_w^2
    Cs, Ms, ms = [], [], []
    for xs, rows, lev in bands:
        m = xs.shape[0]
        C = xs.T @ xs.conj() / m  # sample covariance (v v^H convention)
        gg = g[rows]
        M = np.einsum("i,ij,ik->jk", lev * phi[rows], gg, gg.conj()) / m
        Cs.append(C)
        Ms.append(M)
        ms.append(m)
    nb = len(Cs)

    def nll(z):
        logd = z[: nb * n].reshape(nb, n)
        s2 = z[-1]
        tot = 0.0
        for b in range(nb):
            S = np.diag(np.exp(logd[b])) + s2 * Ms[b]
            sign, ld = np.linalg.slogdet(S)
            if sign <= 0:
                return 1e300
            tot += ms[b] * (ld + np.real(np.trace(np.linalg.solve(S, Cs[b]))))
        return tot

    d0 = np.concatenate([np.log(np.maximum(np.real(np.diag(C)), 1e-300)) for C in Cs])
    l0 = nll(np.concatenate([d0, [0.0]]))
    # scale of sigma^2: the gust term matching the mean diagonal power
    scale = np.mean([np.real(np.trace(C)) / max(np.real(np.trace(M)), 1e-300) for C, M in zip(Cs, Ms)])
    best = (l0, 0.0, None)
    for frac in (0.01, 0.3):
        z0 = np.concatenate([d0 + math.log(1 - frac), [frac * scale]])
        bounds = [(None, None)] * (nb * n) + [(0.0, None)]
        r = optimize.minimize(lambda z: nll(np.concatenate([z[:-1], [z[-1] * scale]])),
                              np.concatenate([z0[:-1], [z0[-1] / scale]]), method="L-BFGS-B", bounds=bounds)
        if r.fun < best[0]:
            best = (float(r.fun), float(r.x[-1] * scale), np.concatenate([r.x[:-1], [r.x[-1] * scale]]))
    l1, s2, z1 = best
    # complex Gaussian samples: -log L = sum_b m_b [ln det S_b + tr(S_b^-1 C_b)] + const, so LR = 2 (nll0 - nll1)
    lr = max(2.0 * (l0 - l1), 0.0)
    p = 0.5 * float(stats.chi2.sf(lr, 1)) if lr > 0 else 1.0
    se = math.nan
    share = 0.0
    if z1 is not None and s2 > 0:
        h = max(1e-3 * s2, 1e-12)
        zp, zm = z1.copy(), z1.copy()
        zp[-1] += h
        zm[-1] = max(zm[-1] - h, 0.0)
        d2 = (nll(zp) - 2 * nll(z1) + nll(zm)) / (h * (zp[-1] - z1[-1])) if zm[-1] < z1[-1] else math.nan
        # Fisher information of sigma^2 is d2 of -log L (one complex sample counts once)
        if d2 and d2 > 0:
            se2 = 1.0 / math.sqrt(d2)
            se = se2 / (2.0 * math.sqrt(s2))
        tot = sum(m * np.real(np.trace(C)) for m, C in zip(ms, Cs))
        share = float(sum(m * s2 * np.real(np.trace(M)) for m, M in zip(ms, Ms)) / max(tot, 1e-300))
    return GustTest(lr=float(lr), p=float(p), sigma_w=float(math.sqrt(max(s2, 0.0))), sigma_w_se=float(se),
                    share=min(max(share, 0.0), 1.0), n_samples=int(sum(ms)))
