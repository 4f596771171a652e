"""Test for unmeasured turbulence on the part of the residual that is incoherent with the inputs.

Turbulence that was not measured drives every output through the model's gust
column g(w) = G_w(jw) (per unit gust angle): it adds to the residual a
component incoherent with the elevator but *correlated across channels along
g*.  Independent sensor noise, white or coloured, is uncorrelated across
channels.  So the test (docs/diagnosis_method.md 2.6 rule 2: disturbance effects on
non-excited lines, after the deterministic effects) is:

1. in each band, project the residual of the final deterministic model onto
   the orthogonal complement of every input times a low-order polynomial in
   w and a transient per record (the same regression as the gap map, with
   regressors that do not depend on the channel); with an orthonormal basis
   Q_b of that complement, ``x = Q_b^H e`` are m_b independent complex
   samples per band.  This works for any input (3-2-1-1, doublet, multisine)
   and removes smooth model error; it plays the role of the non-excited lines
   of a periodic multisine;
2. test ``S_b = diag(d_b) + sigma_w^2 M_b`` (H1) against ``diag(d_b)`` (H0) with
   Rao's score statistic (closed form at the null, no optimisation), with
   ``M_b = (1/m_b) sum_i w_i (pi T/U^2) Phi(w_i) g_i g_i^H``,
   Phi the one-sided Dryden spectrum of w_g for unit sigma (so that
   ``E|alpha_g~(w)|^2 = pi T Phi(w) / U^2`` for the finite transform over T)
   and w_i the complement's leverage of point i;
3. the null sigma_w = 0 lies on the boundary: one-sided score ~ 0.5 chi2_0 + 0.5 chi2_1.

Every channel is first divided by its own local residual RMS, which keeps
independent sensor noise independent (H0 stays exact) and makes the bands
nearly homoscedastic for coloured noise (without it the coloured-noise false
alarm rate was 13 % at the 5 % level).  The size sigma_w and its standard
error come from a separate maximum-likelihood fit of the same covariance
model point by point on the unscaled residual at the independent
frequencies.

The result's "shrink" for this noise-kind effect is the share of the
incoherent residual power that the gust term explains (it does not touch the
coherent gap, docs/diagnosis_method.md 2.3 step 7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from ..maneuvers import DRYDEN_L, dryden_psd
from ..models.effects import with_gust
from .data import AnalysisData
from .locate import _legendre, band_rows

__all__ = ["GustTest", "gust_test"]


@dataclass
class GustTest:
    """Result of the unmeasured-turbulence test.

    Parameters
    ----------
    lr : float
        Rao's score statistic (asymptotically 0.5 chi2_0 + 0.5 chi2_1 under no turbulence).
    p : float
        Its p-value.
    sigma_w : float
        Estimated RMS of the vertical gust velocity, m/s.
    sigma_w_se : float
        Standard error of ``sigma_w``, m/s.
    share : float
        Share of the incoherent residual power the gust term explains, 0 to 1.
    n_samples : int
        Independent complex samples the test used.
    note : str
        A remark on the result (empty by default).
    """

    lr: float
    p: float
    sigma_w: float
    sigma_w_se: float
    share: float
    n_samples: int
    note: str = ""


def _samples(data: AnalysisData, e: np.ndarray, out_idx, edges):
    """Per band: (samples (m, n_out), rows, leverage weights)."""
    rec = data.stacked_record()
    U = np.concatenate([d.u for d in data.spectra])
    out = []
    nb = edges.size - 1
    for b in range(nb):
        rows, x = band_rows(data, edges[b], edges[b + 1], b == nb - 1)
        if rows.size == 0:
            continue
        cols = [(rec[rows] == r)[:, None].astype(complex) for r in np.unique(rec[rows])]
        P = _legendre(x, 2)
        cols += [P * U[rows, j][:, None] for j in range(U.shape[1])]
        X = np.hstack(cols)
        m = rows.size - np.linalg.matrix_rank(X)
        if m < 2:
            continue
        Uq, s, _ = np.linalg.svd(X, full_matrices=True)
        Q = Uq[:, rows.size - m :]  # orthonormal complement of range(X)
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
        out[off : off + d.m] = sc[pos]
        off += d.m
    return np.where(out > 0, out, 1.0)


def _band_stats(data, e, g, out_idx, edges, phi):
    """Per band: sample covariance C_b of the projected residual, gust matrix M_b, sample count m_b."""
    bands = _samples(data, e, out_idx, edges)
    if not bands:
        return None
    ms = [xs.shape[0] for xs, _, _ in bands]
    Cs = [xs.T @ xs.conj() / xs.shape[0] for xs, _, _ in bands]  # sample covariance (v v^H convention)
    Ms = [np.einsum("i,ij,ik->jk", lev * phi[rows], g[rows], g[rows].conj()) / xs.shape[0] for xs, rows, lev in bands]
    return Cs, Ms, ms


def _score_test(Cs, Ms, ms) -> float:
    """Rao's score statistic for s2 = 0 in S_b = diag(d_b) + s2 M_b (one-sided; 0 when the score is < 0).

    With D = diag(C_b) (the H0 estimate) the score is ``sum_b m_b tr(D^-1 (C_b - D) D^-1 M_b)`` (only
    the cross-channel terms of C_b count) and the information, with the nuisance d_b projected out,
    ``sum_b m_b [tr(D^-1 M_b D^-1 M_b) - sum_k (M_b,kk / d_k)^2]`` (complex Gaussian samples).
    """
    score = info = 0.0
    for C, M, m in zip(Cs, Ms, ms):
        d = np.maximum(np.real(np.diag(C)), 1e-300)
        Di = np.diag(1.0 / d)
        A = Di @ M @ Di
        score += m * float(np.real(np.trace(A @ (C - np.diag(d)))))
        info += m * float(np.real(np.trace(Di @ M @ Di @ M)) - np.sum((np.real(np.diag(M)) / d) ** 2))
    if score <= 0 or info <= 0:
        return 0.0
    return score * score / info


def _size(E, G, phi, bidx):
    """ML of sigma_w^2 with S_i = diag(d_b(i)) + sigma^2 phi_i g_i g_i^H per point: (s2, se of sigma_w, share)."""
    bands, bi = np.unique(bidx, return_inverse=True)
    n = E.shape[1]
    nb = bands.size
    gg = np.einsum("i,ij,ik->ijk", phi, G, G.conj())

    def nll(z):
        d = np.exp(z[: nb * n].reshape(nb, n))[bi]  # (N, n)
        S = gg * z[-1] + np.einsum("ij,jk->ijk", d, np.eye(n))
        sign, ld = np.linalg.slogdet(S)
        if np.any(sign <= 0):
            return 1e300
        q = np.real(np.einsum("ij,ij->i", E.conj(), np.linalg.solve(S, E[:, :, None])[:, :, 0]))
        return float(np.sum(ld + q))

    d0 = np.concatenate([np.log(np.maximum(np.mean(np.abs(E[bi == k]) ** 2, axis=0), 1e-300)) for k in range(nb)])
    scale = float(np.mean(np.abs(E) ** 2) / max(np.mean(np.real(np.einsum("ijj->i", gg))), 1e-300))
    bounds = [(None, None)] * (nb * n) + [(0.0, None)]
    best = None
    for frac in (0.05, 0.5):
        z0 = np.concatenate([d0 + math.log(1 - frac), [frac]])
        r = optimize.minimize(
            lambda z: nll(np.concatenate([z[:-1], [z[-1] * scale]])), z0, method="L-BFGS-B", bounds=bounds
        )
        if best is None or r.fun < best.fun:
            best = r
    z1 = np.concatenate([best.x[:-1], [best.x[-1] * scale]])
    s2 = float(z1[-1])
    se, share = math.nan, 0.0
    if s2 > 0:
        h = np.zeros_like(z1)
        h[-1] = 1e-3 * s2
        d2 = (nll(z1 + h) - 2 * nll(z1) + nll(z1 - h)) / h[-1] ** 2
        if d2 > 0:  # observed information of sigma^2
            se = (1.0 / math.sqrt(d2)) / (2.0 * math.sqrt(s2))
        share = float(s2 * np.sum(np.real(np.einsum("ijj->i", gg))) / max(float(np.sum(np.abs(E) ** 2)), 1e-300))
    return s2, se, share


def gust_test(data: AnalysisData, fit, edges: np.ndarray, *, length: float = DRYDEN_L) -> GustTest | None:
    """Likelihood-ratio test for turbulence along the model's gust column (see module doc).

    Parameters
    ----------
    data : AnalysisData
        The records' spectra.
    fit : DiagFit
        The final deterministic fit.
    edges : numpy.ndarray
        Band edges, rad/s.
    length : float, optional
        Dryden scale length L, m.

    Returns
    -------
    GustTest or None
        None when fewer than two outputs are fitted or no band holds two samples.
    """
    model = fit.model
    out_idx = list(fit.prob.out_idx)
    if len(out_idx) < 2:
        return None
    e = fit.full_residual()
    gm = with_gust(model)
    vals = {k: v for k, v in fit.model_values().items() if k in gm.parameters}
    U = model.U
    om = data.stacked_omega()
    Tr = np.concatenate([np.full(d.m, d.T) for d in data.spectra])
    g = np.concatenate([gm.evaluate(d.omega, vals).G[:, :, 1] for d in data.spectra])
    phi = math.pi * Tr * dryden_psd(om, 1.0, U, length) / U**2  # E|alpha_g~|^2 per unit sigma_w^2
    # the test: channels scaled by their own local residual RMS (H0 exact, nearly homoscedastic bands)
    w = _local_scale(data, e)
    norm = _band_stats(data, e / w, g[:, out_idx] / w[:, out_idx], out_idx, edges, phi)
    if norm is None:
        return None
    lr = _score_test(*norm)  # asymptotically 0.5 chi2_0 + 0.5 chi2_1 under H0, like the LR
    p = 0.5 * float(stats.chi2.sf(lr, 1)) if lr > 0 else 1.0
    # the size: per-point likelihood on the unscaled residual at the independent frequencies
    # (physical units; the gust spectrum varies too much across a band to be averaged there)
    dft = data.stacked_dft()
    bidx = np.clip(np.searchsorted(edges, om, side="right") - 1, 0, edges.size - 2)[dft]
    s2, se, share = _size(e[dft][:, out_idx], g[dft][:, out_idx], phi[dft], bidx)
    return GustTest(
        lr=float(lr),
        p=float(p),
        sigma_w=float(math.sqrt(max(s2, 0.0))),
        sigma_w_se=float(se),
        share=min(max(share, 0.0), 1.0),
        n_samples=int(sum(norm[2])),
    )
