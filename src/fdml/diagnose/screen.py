"""Score (Lagrange-multiplier) screen of candidate effects from the current fit only.

At the current estimate theta_hat (null values eta_0 for the candidate), with
the band-whitened, real-stacked residual r and sensitivities J_theta (all
estimated quantities, nuisance terms included) and J_eta (the candidate's
parameters, by central differences):

    LM = 2 r' P r / K,   P = projection on (I - P_theta) J_eta

is the likelihood-ratio statistic of the linearised refit (Rao 1948); it needs
no refit.  From the same matrices:

* aliasing per parameter ``a_j = 1 - [J_eta'(I - P_theta) J_eta]_jj / [J_eta' J_eta]_jj``:
  the share of the effect's signature that the base parameters can mimic;
* the Fisher information in LR units ``I = 2 J_eta'(I - P_theta) J_eta / K``
  and the minimum detectable effect ``MDE_j = sqrt(lambda* [I^-1]_jj)``, the
  size that would be found with 80 % power at the family level (lambda* the
  non-centrality giving that power);
* the linearised estimate ``eta_lin``, used as the refit's start value.

For an effect whose parameter is not identified under the null (a structural
mode's frequency), the statistic is profiled over a grid of that parameter.

Aliasing and the MDE describe the design and the noise, not the current
misfit, so they are computed with the gap map's noise floors (per channel and
band, diagonal; model error that is smooth across a band does not enter
them).  The residual covariance R_b of a biased base fit holds model error and
strong cross-channel correlation, and whitening with it made a 1.5 m
accelerometer offset look 99.8 % aliased; the LM statistic itself keeps the
likelihood's own weighting (R_b), which is what the refit's LR uses.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from ..estimate import prepare
from ..models.effects import Effect
from .likelihood import DiagFit, whitener

__all__ = ["ScreenContext", "ScreenResult", "screen", "power_noncentrality"]

#: Aliasing above which a candidate is "not identifiable" (DIAGNOSIS.md 2.3).
ALIAS_LIMIT = 0.99


@functools.lru_cache(maxsize=256)  # a root search of ncx2.sf: the same (level, df) for every candidate
def power_noncentrality(level: float, df: int = 1, power: float = 0.8) -> float:
    """Non-centrality lambda* of a chi-square(df) test at ``level`` with the given power."""
    crit = stats.chi2.isf(level, df)
    f = lambda lam: stats.ncx2.sf(crit, df, lam) - power  # noqa: E731
    return float(optimize.brentq(f, 1e-6, 1e4))


@dataclass
class ScreenResult:
    """What the screen says about one candidate."""

    key: str
    lm: float
    eta_lin: dict
    aliasing: dict
    mde: dict
    identifiable: bool
    reason: str | None = None
    grid: dict | None = None  # {"omega_s": (grid, lm_profile)} for nuisance-grid effects
    nuisance: dict = field(default_factory=dict)  # best grid values


class ScreenContext:
    """Whitened residual and base sensitivities of the current fit (computed once per step)."""

    def __init__(self, fit: DiagFit, rows: np.ndarray, oversample: int, spectra, fit_options: dict,
                 floor_weights: np.ndarray | None = None):
        self.fit = fit
        self.rows = rows
        self.K = oversample
        self.spectra = list(spectra)
        self.options = fit_options
        Ls = whitener(fit.Rs)
        self.L = np.stack(Ls)[rows]  # (N, n, n)
        A = fit.prob.sensitivities(fit.theta)
        self.r = self._real(self._white(fit.V))
        self.Q = self._basis(self._real_cols(self._white_cols(A)))
        # noise-floor metric (diagonal) for aliasing and MDE
        n = fit.V.shape[1]
        fw = np.ones((fit.V.shape[0], n)) if floor_weights is None else floor_weights
        self.Lf = np.einsum("nj,jk->njk", fw, np.eye(n))
        self.Qf = self._basis(self._real_cols(np.einsum("njk,nkp->njp", self.Lf, A)))

    @staticmethod
    def _basis(J):
        """Orthonormal basis of the columns of J (numerically dead directions dropped)."""
        U, s, _ = np.linalg.svd(J, full_matrices=False)
        keep = s > 1e-10 * (s[0] if s.size else 1.0)
        return U[:, keep]

    def _white(self, V):
        return np.einsum("njk,nk->nj", self.L, V)

    def _white_cols(self, A):
        return np.einsum("njk,nkp->njp", self.L, A)

    @staticmethod
    def _real(v):
        v = v.ravel()
        return np.concatenate([v.real, v.imag])

    @staticmethod
    def _real_cols(A):
        N, n, p = A.shape
        M = A.reshape(N * n, p)
        return np.vstack([M.real, M.imag])

    def perp(self, X):
        return X - self.Q @ (self.Q.T @ X)

    def perp_floor(self, X):
        return X - self.Qf @ (self.Qf.T @ X)

    def candidate_jacobian(self, model, names, steps, one_sided):
        """(likelihood-whitened, floor-whitened) real-stacked d(prediction)/d(eta) at the model's values."""
        prob = prepare(self.spectra, model, sensitivity="central", **self.options)
        theta = np.array([self.fit.params.get(n, model.parameters.values.get(n, 0.0)) for n in prob.names])
        idx = {n: i for i, n in enumerate(prob.names)}
        cols = []
        for n, h, os_ in zip(names, steps, one_sided):
            i = idx[n]
            tp = theta.copy()
            tp[i] += h
            yp = _stack(prob, tp)
            if os_:
                y0 = _stack(prob, theta)
                cols.append((yp - y0) / h)
            else:
                tm = theta.copy()
                tm[i] -= h
                cols.append((yp - _stack(prob, tm)) / (2 * h))
        A = np.stack(cols, axis=-1)  # (N, n_out, q)
        return (self._real_cols(self._white_cols(A)),
                self._real_cols(np.einsum("njk,nkp->njp", self.Lf, A)))


def _stack(prob, theta):
    return np.concatenate([y[:, prob.out_idx] for y in prob.predict(theta)])


def _lm(ctx: ScreenContext, Jpair):
    """LM statistic and linearised estimate (likelihood metric); information and aliasing (floor metric)."""
    Je, Jf = Jpair
    Jp = ctx.perp(Je)
    rp = ctx.perp(ctx.r)
    G = Jp.T @ Jp
    b = Jp.T @ rp
    try:
        eta = np.linalg.solve(G, b)
    except np.linalg.LinAlgError:
        eta = np.linalg.lstsq(G, b, rcond=1e-12)[0]
    lm = 2.0 * float(b @ eta) / ctx.K
    Jfp = ctx.perp_floor(Jf)
    Gf = Jfp.T @ Jfp
    full = np.einsum("ij,ij->j", Jf, Jf)
    alias = 1.0 - np.diag(Gf) / np.where(full > 0, full, np.inf)
    info = 2.0 * Gf / ctx.K
    return max(lm, 0.0), eta, info, np.clip(alias, 0.0, 1.0)


def screen(ctx: ScreenContext, effect: Effect, *, level: float, band: tuple) -> ScreenResult:
    """Screen one candidate effect at the current fit."""
    cur = ctx.fit.model
    aug = effect.augment(cur)
    plist = [p for p in effect.param_list(cur)]
    nulls = effect.nulls(cur)
    aug = aug.with_values(nulls)
    test = [p for p in plist if not p.nuisance]
    names = [p.name for p in test]
    steps, one_sided = [], []
    for p in test:
        h = p.typical()
        at_lo = nulls[p.name] <= p.lower or (aug.parameters[p.name].lower >= nulls[p.name])
        steps.append(h)
        one_sided.append(bool(at_lo))
    grid_out, best_nuis = None, {}
    grids = effect.nuisance_grid or {}
    if grids:
        (gname, gfun), = grids.items()
        grid = np.asarray(gfun(max(band[0], band[1] / 5.0), band[1]))
        prof = []
        best = None
        for w in grid:
            m = aug.with_values({gname: float(w)})
            Je = ctx.candidate_jacobian(m, names, steps, one_sided)
            lm, eta, info, alias = _lm(ctx, Je)
            prof.append(lm)
            if best is None or lm > best[0]:
                best = (lm, eta, info, alias, float(w))
        lm, eta, info, alias, wbest = best
        grid_out = {gname: (grid, np.array(prof))}
        best_nuis = {gname: wbest}
    else:
        Je = ctx.candidate_jacobian(aug, names, steps, one_sided)
        lm, eta, info, alias = _lm(ctx, Je)
    # one-sided nulls: a linearised step into the infeasible side means no evidence
    for j, p in enumerate(test):
        if one_sided[j] and eta[j] < 0 and len(test) == 1:
            lm = 0.0
    q = len(test)
    n_family = max(int(getattr(ctx, "family_size", 1)), 1)
    lam = power_noncentrality(level / n_family, q)
    try:
        Iinv = np.linalg.inv(info)
        mde = {n: float(math.sqrt(max(lam * Iinv[j, j], 0.0))) for j, n in enumerate(names)}
    except np.linalg.LinAlgError:
        mde = {n: math.inf for n in names}
    aliasing = {n: float(alias[j]) for j, n in enumerate(names)}
    reason = None
    worst = max(aliasing.values()) if aliasing else 0.0
    if worst > ALIAS_LIMIT:
        n_ = max(aliasing, key=aliasing.get)
        reason = (f"aliased: {100 * aliasing[n_]:.1f} % of the {n_} signature is absorbed by the base parameters "
                  "with these inputs")
    elif not grids:
        for p in test:
            if p.plausible is not None and math.isfinite(mde[p.name]):
                span = max(abs(p.plausible[0] - nulls[p.name]), abs(p.plausible[1] - nulls[p.name]))
                if mde[p.name] > span:
                    reason = (f"too little information: the smallest detectable {p.name} is {mde[p.name]:.3g} "
                              f"{p.unit}, beyond its plausible range {p.plausible}")
                    break
    eta_lin = {n: float(nulls[n] + eta[j]) for j, n in enumerate(names)}
    return ScreenResult(effect.key, float(lm), eta_lin, aliasing, mde, reason is None, reason, grid_out, best_nuis)
