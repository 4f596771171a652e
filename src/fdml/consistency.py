"""Do repeated manoeuvres agree?  A consistency test of estimates and their bounds.

Fits of repeated manoeuvres at one flight condition estimate the same
parameters.  If the reported standard errors are honest, the spread of the
estimates about their weighted mean is chi-square distributed with n - 1
degrees of freedom per parameter.  A large chi-square says the bounds are too
small (or the condition was not the same); the ratio sqrt(chi2/(n-1)) is the
factor by which they would have to grow.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np
from scipy import stats

from .errors import FdmlError
from .results import frozen

__all__ = ["ConsistencyResult", "consistency"]


@dataclass(frozen=True)
class ConsistencyResult:
    """Per-parameter agreement of several fits.

    Parameters
    ----------
    names : tuple of str
        The tested parameters.
    labels : tuple of str
        One label per fit (record names).
    estimates, stderr : ndarray, shape (n_fits, n_params)
        Estimate and standard error of each parameter in each fit, in the parameter's unit.
    mean : ndarray
        Inverse-variance weighted mean per parameter.
    chi2 : ndarray
        The sum ((theta_r - mean) / sigma_r)^2 per parameter.
    dof : int
        Degrees of freedom, n_fits - 1.
    p_value : ndarray
        Upper-tail chi-square probability per parameter.
    scale : ndarray
        The factor sqrt(chi2 / dof) the bounds would need to grow by.
    joint_chi2, joint_p : float
        Sum over parameters (treated as independent): an overall verdict.
    """

    names: tuple
    labels: tuple
    estimates: np.ndarray
    stderr: np.ndarray
    mean: np.ndarray
    chi2: np.ndarray
    dof: int
    p_value: np.ndarray
    scale: np.ndarray
    joint_chi2: float
    joint_p: float

    def __post_init__(self) -> None:
        for f in fields(self):  # a result is a record: its arrays are read-only
            object.__setattr__(self, f.name, frozen(getattr(self, f.name)))

    def agree(self, alpha: float = 0.05, joint: bool = False) -> bool:
        """True if no parameter's test rejects at level ``alpha`` (Bonferroni over parameters).

        With ``joint=True`` the joint chi-square test must not reject either.

        Parameters
        ----------
        alpha : float, optional
            Family-wise level.
        joint : bool, optional
            Also require the joint test to accept.

        Returns
        -------
        bool
            Whether the fits agree.
        """
        ok = bool(np.all(self.p_value > alpha / len(self.names)))
        return ok and (self.joint_p > alpha if joint else True)

    def summary(self) -> str:
        """A text table: estimates per fit, weighted mean, chi2, p, scale.

        Returns
        -------
        str
            The table and a verdict line.
        """
        w = max(24, max(len(lab) for lab in self.labels) + 2)
        head = f"{'parameter':12s}" + "".join(f"{lab:>{w}s}" for lab in self.labels)
        head += f"{'mean':>12s}{'chi2':>9s}{'p':>9s}{'scale':>8s}"
        lines = [f"consistency of {len(self.labels)} fits ({self.dof} degrees of freedom per parameter)", head]
        for j, n in enumerate(self.names):
            cells = "".join(
                f"{self.estimates[i, j]:>{w - 12}.4g} +/- {self.stderr[i, j]:<7.2g}" for i in range(len(self.labels))
            )
            lines.append(
                f"{n:12s}{cells}{self.mean[j]:>12.4g}{self.chi2[j]:>9.2f}{self.p_value[j]:>9.3g}{self.scale[j]:>8.2f}"
            )
        per = "agree" if self.agree() else "DISAGREE"
        jv = "agree" if self.joint_p > 0.05 else "DISAGREE"
        lines.append(f"per parameter (5 %, Bonferroni over {len(self.names)}): the fits {per} within their bounds")
        lines.append(
            f"joint: chi2 = {self.joint_chi2:.2f} on {self.dof * len(self.names)} dof, p = {self.joint_p:.3g}: "
            f"the fits {jv} (5 %); the bounds would need to grow by "
            f"{np.sqrt(self.joint_chi2 / (self.dof * len(self.names))):.2f} to explain the spread"
        )
        return "\n".join(lines)


def consistency(results: Sequence, names: Sequence[str] | None = None) -> ConsistencyResult:
    """Test whether fits of repeated manoeuvres agree within their standard errors.

    Parameters
    ----------
    results : sequence of FitResult
        At least two fits of the same model.
    names : sequence of str, optional
        Parameters to test (default: the model parameters common to all fits,
        without nuisance terms).

    Returns
    -------
    ConsistencyResult
        Per-parameter and joint chi-square tests of agreement.
    """
    results = list(results)
    if len(results) < 2:
        raise FdmlError("a consistency test needs at least two fits")
    if names is None:
        names = [n for n in results[0].model_names if all(n in r.names for r in results)]
    if not names:
        raise FdmlError("the fits share no estimated parameter to compare")
    for r in results:
        missing = [n for n in names if n not in r.names]
        if missing:
            raise FdmlError(f"fit of {', '.join(r.records)} did not estimate {', '.join(missing)}")
    est = np.array([[r.values[r.names.index(n)] for n in names] for r in results])
    se = np.array([[r.stderr[r.names.index(n)] for n in names] for r in results])
    if not np.all(np.isfinite(se)) or np.any(se <= 0):
        raise FdmlError("a standard error is zero or infinite: the test needs finite bounds")
    w = 1.0 / se**2
    mean = np.sum(w * est, axis=0) / np.sum(w, axis=0)
    chi2 = np.sum(((est - mean) / se) ** 2, axis=0)
    dof = len(results) - 1
    joint = float(np.sum(chi2))
    return ConsistencyResult(
        names=tuple(names),
        labels=tuple(", ".join(r.records) for r in results),
        estimates=est,
        stderr=se,
        mean=mean,
        chi2=chi2,
        dof=dof,
        p_value=stats.chi2.sf(chi2, dof),
        scale=np.sqrt(chi2 / dof),
        joint_chi2=joint,
        joint_p=float(stats.chi2.sf(joint, dof * len(names))),
    )
