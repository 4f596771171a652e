"""The score-test core (fdml.score), shared by every fit's adequacy check and the diagnosis."""

import subprocess
import sys

import numpy as np
import pytest

import fdml
from fdml import adequacy, score
from fdml.estimate import prepare
from fdml.models.effects import OutputEffect, Param, get_effect
from fdml.simulate import simulate_maneuver

NAVION = fdml.make_model("derivatives", "navion")
NOISE = {"alpha": 5e-4, "q": 1e-3, "az": 3e-3}


@pytest.fixture(scope="module")
def context():
    """The adequacy check's screen context on a converged 12 s Navion fit, and the fitted model."""
    rec = simulate_maneuver(NAVION, "3211", duration=12.0, noise=NOISE, seed=5)
    res = fdml.fit(rec, NAVION, adequacy=False)
    prob = prepare(rec, NAVION)
    assert prob.names == res.names
    theta = np.asarray(res.values, float)
    model = prob.model.with_values(prob.model_values(theta))
    # the estimator's prepare for the screen's generic path, the reference of these tests
    ctx, _ = adequacy._context(prob, model, theta, prob.residuals(theta), res.R, prepare=prepare)
    return ctx, model


def _candidate(ctx, model, key):
    eff = get_effect(key)
    nulls = eff.nulls(model)
    aug = eff.augment(model).with_values(nulls)
    test = [p for p in eff.param_list(model) if not p.nuisance]
    steps, one_sided = score._steps(test, nulls, aug)
    return eff, aug, [p.name for p in test], steps, one_sided


@pytest.mark.parametrize(
    "key",
    ["time_delay@alpha", "actuator_lag@de", "sensor_offset@az", "lift_lag@alpha", "downwash_lag@q", "time_delay@de"],
)
def test_adequacy_sensitivities_equal_the_screens_own(context, key):
    """Output-level (on the base response), matrix-level and free-parameter (evaluated) candidates.

    The reference is the screen's generic path: a problem prepared for the candidate model, predicted at
    +-h.  Both are the same central (or forward) difference; the measurement is linear in the response,
    so they differ by rounding only: the difference of two predictions of size |y| carries eps |y|,
    i.e. a relative error eps |y| / (h |dy/d eta|) < 1e-10 for these steps (h |dy/d eta| / |y| > 1e-4).
    """
    ctx, model = context
    _, aug, names, steps, one_sided = _candidate(ctx, model, key)
    fast = ctx.candidate_sensitivities(aug, names, steps, one_sided)
    ref = score.ScreenContext.candidate_sensitivities(ctx, aug, names, steps, one_sided)
    assert np.linalg.norm(fast - ref) <= 1e-9 * np.linalg.norm(ref)


def test_grid_of_a_structural_mode_at_once_equals_value_by_value(context):
    ctx, model = context
    _, aug, names, steps, one_sided = _candidate(ctx, model, "structural_mode@q,az")
    grid = np.geomspace(2.0, 10.0, 9)
    A = ctx.grid_sensitivities(aug, names, steps, one_sided, "omega_s", grid)
    for k, w in enumerate(grid):  # the screen's generic path, one grid value at a time
        ref = score.ScreenContext.candidate_sensitivities(
            ctx, aug.with_values({"omega_s": float(w)}), names, steps, one_sided
        )
        assert np.linalg.norm(A[:, :, k] - ref) <= 1e-9 * np.linalg.norm(ref)


def _notch(reduce):
    """A nuisance-grid effect on q whose function mishandles an array-valued frequency via ``reduce``."""

    def fn(s, p, G, H, P, root):
        w = reduce(p["omega_n"])
        G = G.copy()
        G[:, 1, 0] = G[:, 1, 0] + p["r_n"] * s * w / (s**2 + 0.1 * w * s + w**2)
        return G, H, P

    return OutputEffect(
        "notch_test",
        "q",
        (
            Param("r_n", 0.0, plausible=(-0.5, 0.5), start=0.01),
            Param("omega_n", 5.0, lower=0.1, upper=100.0, nuisance=True),
        ),
        fn,
        nuisance_grid={"omega_n": lambda lo, hi: np.geomspace(lo, hi, 12)},
    )


@pytest.mark.parametrize("reduce", [float, np.max], ids=["raises", "silently-wrong"])
def test_a_grid_effect_that_takes_scalars_only_is_screened_value_by_value(context, reduce):
    """``float`` raises on an array (caught); ``np.max`` broadcasts but is wrong (the end-point guard)."""
    ctx, model = context
    eff = _notch(reduce)
    nulls = eff.nulls(model)
    aug = eff.augment(model).with_values(nulls)
    grid = np.geomspace(2.0, 10.0, 12)
    A = ctx.grid_sensitivities(aug, ["r_n"], [0.01], [False], "omega_n", grid)
    for k, w in enumerate(grid):
        ref = score.ScreenContext.candidate_sensitivities(
            ctx, aug.with_values({"omega_n": float(w)}), ["r_n"], [0.01], [False]
        )
        assert np.linalg.norm(A[:, :, k] - ref) <= 1e-9 * np.linalg.norm(ref)


def test_the_diagnosis_uses_the_same_implementation():
    from fdml.diagnose import attribute, locate

    assert attribute.screen is score.screen and attribute.ScreenContext is score.ScreenContext
    assert attribute.p_value is score.p_value and attribute.davies_bound is score.davies_bound
    assert locate.holm is score.holm and locate.bh is score.bh


def test_a_fit_does_not_import_the_diagnosis():
    code = (
        "import sys, warnings; warnings.simplefilter('ignore'); import fdml\n"
        "from fdml.simulate import simulate_maneuver\n"
        "m = fdml.make_model('derivatives', 'navion')\n"
        "noise = {'alpha': 5e-4, 'q': 1e-3, 'az': 3e-3}\n"
        "r = fdml.fit(simulate_maneuver(m, '3211', duration=12.0, noise=noise, seed=1), m)\n"
        "assert r.adequacy is not None\n"
        "print(sorted(k for k in sys.modules if k.startswith('fdml.diagnose')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("level,df,power", [(0.05, 1, 0.8), (1e-3, 3, 0.9), (1e-6, 2, 0.5)])
def test_power_noncentrality_is_the_root_of_the_power_equation(level, df, power):
    """Against scipy.stats' non-central chi-square and a bracketing root search (independent of
    the Poisson mixture and bisection in fdml.tails that the code uses)."""
    from scipy import optimize, stats

    from fdml.score import power_noncentrality

    crit = stats.chi2.isf(level, df)
    ref = optimize.brentq(lambda lam: stats.ncx2.sf(crit, df, lam) - power, 1e-6, 1e4, xtol=1e-12)
    assert power_noncentrality(level, df, power) == pytest.approx(ref, rel=1e-9)
