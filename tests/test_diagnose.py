"""fdml.diagnose end to end: small-scale withheld-effect validation, DIAGNOSIS.md 2.6 rules, bad input."""

import numpy as np
import pytest

import fdml
from fdml.diagnose import JSON_KEYS, diagnose
from fdml.diagnose.report import label_for
from fdml.diagnose.truth import simulate_truth

BAND = (0.3, 12.0)


def steady(gust=False):
    return fdml.make_model("steady", "navion", gust=gust)


def run(key, values, *, maneuver="3211", noise=0.04, seed=1, holdout=True, base=None, **kw):
    base = base or steady()
    rec = simulate_truth(base, key, values, maneuver=maneuver, noise=noise, seed=seed)
    hold = None
    if holdout:
        other = {"3211": "doublet", "doublet": "3211", "multisine": "multisine"}[maneuver]
        hold = simulate_truth(base, key, values, maneuver=other, noise=noise, seed=seed + 1000)
    return diagnose(rec, base, holdout=hold, band=BAND, **kw)


# --- withheld effects are attributed (small-scale validation) -----------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    "key,values",
    [
        ("time_delay@q", {"tau_q": 0.04}),
        ("actuator_lag@de", {"T_act": 0.05}),
        ("sensor_offset@az", {"x_az": 1.5}),
    ],
)
def test_clear_effect_is_attributed_and_confirmed(key, values):
    rep = run(key, values)
    assert rep.status == "ok"
    assert rep.verdict == key.split("@")[0]
    sel = rep.selected[0]
    assert sel["key"] == key
    assert sel["label"] == "confirmed"
    # the fitted size: within 4 standard errors of the truth (CRB with coloured-residual correction)
    ((name, truth),) = values.items()
    p = sel["params"][name]
    assert abs(p["value"] - truth) < 4 * p["stderr"]
    assert sel["shrink"] > 0.8  # held-out shrink of the coherent gap
    assert not rep.unexplained


@pytest.mark.slow
def test_no_effect_records_rarely_fire():
    # 10 no-effect records (white noise).  Family-wise level 0.05 per record: P(>= 3 of 10 fire) =
    # 0.012 under the nominal rate, so more than 2 means the tests are miscalibrated.
    fired = []
    for seed in range(10):
        rep = run(None, {}, maneuver=("3211", "doublet")[seed % 2], seed=300 + seed, holdout=False, max_effects=1)
        if rep.verdict != "none":
            fired.append(rep.verdict)
    assert len(fired) <= 2, fired


# --- DIAGNOSIS.md 2.6 rules ------------------------------------------------------------------------


def test_rule3_aliased_candidate_is_not_identifiable_with_a_reason():
    # C_m_alpha_dot with elevator input only on the two-state derivatives model is exactly aliased
    base = fdml.make_model("derivatives", "navion")
    rec = simulate_truth(steady(), None, {}, maneuver="3211", noise=0.04, seed=5)
    rep = diagnose(rec, base, band=BAND, library=["downwash_lag", "time_delay"], max_effects=1)
    ni = {n["key"]: n["reason"] for n in rep.not_identifiable}
    assert "downwash_lag@q" in ni and "aliased" in ni["downwash_lag@q"]
    assert all(r["key"] != "downwash_lag@q" for r in rep.ranking)  # spends no alpha


def test_rule4_small_delay_and_lag_are_an_ambiguity_set():
    # 10 ms elevator delay seen by a doublet: a delay and a first-order lag differ only at second
    # order in omega tau (0.1 at 10 rad/s), so the data must not pick one confidently
    rep = run("time_delay@de", {"tau_de": 0.01}, maneuver="doublet", noise=0.06, seed=11)
    names = {rep.selected[0]["key"]} | set(rep.ambiguous)
    assert {"time_delay@de", "actuator_lag@de"} <= names
    assert rep.selected[0]["label"] != "confirmed"


def test_rule5_mode_frequency_is_refined_between_grid_points():
    truth = {"r_q": 0.03, "r_az": 0.03, "omega_s": 8.37, "zeta_s": 0.04}
    rep = run("structural_mode@q,az", truth, maneuver="multisine", noise=0.03, seed=3, holdout=False, max_effects=1)
    sel = rep.selected[0]
    assert sel["key"] == "structural_mode@q,az"
    w = sel["params"]["omega_s"]["value"]
    # the grid is 5 % apart; after the continuous refinement the frequency is within 1 %
    assert abs(w - 8.37) < 0.01 * 8.37


def test_rule6_shrink_is_judged_only_on_flagged_cells():
    assert (
        label_for(
            significant=True, accepted=True, ambiguous=False, plausible=True, shrink=None, n_flagged=0, n_unexplained=0
        )
        == "tentative"
    )
    assert (
        label_for(
            significant=True, accepted=True, ambiguous=False, plausible=True, shrink=0.95, n_flagged=3, n_unexplained=0
        )
        == "confirmed"
    )
    assert (
        label_for(
            significant=True, accepted=True, ambiguous=False, plausible=True, shrink=0.3, n_flagged=3, n_unexplained=0
        )
        == "partial"
    )
    assert (
        label_for(
            significant=False, accepted=False, ambiguous=False, plausible=True, shrink=0.9, n_flagged=3, n_unexplained=0
        )
        is None
    )


def test_rule7_footprint_locates_the_effect_where_the_residual_map_may_not():
    # an accelerometer offset acts on a_z only; the refit smears the misfit into alpha and q through
    # the shared derivatives, but the footprint must put (nearly) all of the effect in a_z
    rep = run("sensor_offset@az", {"x_az": 1.5}, maneuver="doublet", noise=0.04, seed=2)
    fp = [f for f in rep.footprint if f["effect"] == "sensor_offset@az"]
    share_az = sum(f["share"] for f in fp if f["channel"] == "az")
    assert share_az > 0.99
    assert rep.compensation  # how the base derivatives bent is reported too


def test_rule8_effect_outside_the_library_is_not_confidently_wrong():
    # a second-order alpha-vane filter: no candidate models it; the best candidate (a delay on
    # alpha) leaves flagged cells on the held-out record and must be labelled partial
    rep = run("vane_filter", {"omega_f": 7.0, "zeta_f": 0.3}, noise=0.03, seed=4)
    assert rep.verdict != "none"
    assert rep.selected[0]["label"] == "partial"
    assert rep.unexplained


def test_rule2_turbulence_is_tested_after_the_deterministic_effects():
    # a strong delay with no turbulence: the turbulence test runs on the final model's
    # input-incoherent residual and must not fire
    rep = run("time_delay@q", {"tau_q": 0.04}, holdout=False)
    g = next(r for r in rep.ranking if r["effect"] == "unmeasured_gust")
    assert g["step"] == len(rep.selected) and not g["significant"]


# --- report and interfaces ------------------------------------------------------------------------------


def test_report_json_has_the_issue_keys_and_types():
    import json

    rep = run("time_delay@q", {"tau_q": 0.04}, holdout=False, max_effects=1)
    d = json.loads(rep.to_json())
    assert list(d)[: len(JSON_KEYS)] == list(JSON_KEYS)
    assert d["verdict"] == "time_delay"
    for r in d["ranking"]:
        assert {"effect", "channel", "lr", "p_value", "shrink", "label", "params"} <= set(r)
        assert r["label"] in (None, "confirmed", "tentative", "partial", "absorbs a model error", "set aside")
        assert r["channel"] in (
            "alpha",
            "q",
            "az",
            "de",
            "alpha_w",
            "tail",
            "q,az",
            "alpha,q",
            "alpha,az",
            "alpha,q,az",
        )
        assert r["shrink"] is None or 0.0 <= r["shrink"] <= 1.0
    for c in d["location"]:
        assert {"channel", "band", "excess", "gain_db", "phase_deg", "significant"} <= set(c)
        assert c["channel"] in ("alpha", "q", "az") and len(c["band"]) == 2
    q_high = [c for c in d["location"] if c["channel"] == "q" and c["band"][0] > 4]
    # a 40 ms q sensor delay: the data lag the model in the high band (phase of data over model < 0)
    assert q_high and q_high[0]["significant"] and q_high[0]["phase_deg"] < -5
    assert isinstance(d["footprint"], list) and isinstance(d["unexplained"], list)
    assert isinstance(d["ambiguous"], list) and isinstance(d["not_identifiable"], list)
    assert "tau_q" in d["summary"]


def _cell(channel, band, excess, gain_db, phase_deg, p):
    return {"channel": channel, "band": list(band), "excess": excess, "gain_db": gain_db, "phase_deg": phase_deg} | {
        "significant": True,
        "p_holm": p,
    }


def _located(cells, band=(0.1, 10.0)):
    """The fields of a report that the paragraph reads, with a gap map of ``cells`` and nothing attributed."""
    from types import SimpleNamespace

    settings = {"base_model": "dimensional model", "records": ["a", "b"], "band": list(band)}
    settings |= {"independent_frequencies": 21, "alpha": 0.05}
    return SimpleNamespace(
        settings=settings,
        location=cells,
        selected=[],
        ranking=[],
        verdict="none",
        ambiguous=[],
        unexplained=[],
        footprint=[],
    )


def test_a_gap_over_the_whole_band_is_said_to_be_across_it_with_the_worst_cell():
    """Short records give the gap map one band, the analysis band: "across the band", the worst channel named."""
    from fdml.diagnose.text import paragraph

    whole = (0.1, 10.0)
    cells = [_cell("alpha", whole, 48.0, -0.02, -3.0, 2e-9), _cell("q", whole, 34.0, 0.48, 0.5, 5e-8)]
    cells.append(_cell("az", whole, 70.0, 0.42, 3.7, 3e-11))
    text = paragraph(_located(cells))
    assert "rad/s (" not in text.split("independent frequencies.")[1]  # no cell "at 0.1-10 rad/s"
    assert "across the band" in text and "worst: az (measured/model +0.42 dB, +3.7 deg" in text
    # a map of several bands still says where
    text = paragraph(_located([_cell("q", (3.0, 10.0), 20.0, 0.5, -8.0, 1e-6)]))
    assert "q at 3-10 rad/s (measured/model +0.50 dB, -8.0 deg" in text and "across the band" not in text


@pytest.mark.slow
def test_figure_is_written(tmp_path):
    rep = run("actuator_lag@de", {"T_act": 0.05}, holdout=False, max_effects=1)
    path = tmp_path / "diag.png"
    rep.plot(path)
    assert path.stat().st_size > 10_000


# --- bad input ----------------------------------------------------------------------------------------------


def test_unconverged_base_fit_gives_no_verdict(monkeypatch):
    import fdml.diagnose.core as core

    real = core.fit_model

    def unconverged(*a, **k):
        f = real(*a, **k)
        f.converged = False
        f.message = "maximum number of iterations reached"
        return f

    monkeypatch.setattr(core, "fit_model", unconverged)
    rep = run("time_delay@q", {"tau_q": 0.04}, holdout=False)
    assert rep.status == "base_not_converged" and rep.verdict == "none"
    assert rep.ranking == [] and "did not converge" in rep.problems[0]


def test_band_without_excitation_is_said_plainly():
    # a 3-2-1-1 with 0.4 s units has little energy above ~40 rad/s: a band up to 60 rad/s,
    # split so that the top cells see only noise
    base = steady()
    rec = simulate_truth(base, None, {}, maneuver="3211", noise=0.05, seed=9)
    rep = diagnose(rec, base, band=(0.3, 60.0), bands=[0.3, 5.0, 30.0, 60.0], library=["sensor_scale"], max_effects=1)
    thin = [c for c in rep.location if c["excitation"] != "ok"]
    assert thin and all(not c["significant"] and c["p_value"] is None for c in thin)
    assert any("insufficient excitation" in p for p in rep.problems)


def test_no_band_with_excitation_means_no_verdict():
    # the map restricted to 110-150 rad/s, where the 3-2-1-1's response is below the noise in every
    # channel (gain resolvable to 4-7 dB only): no verdict, even though the record has a 50 ms q delay
    base = steady()
    rec = simulate_truth(base, "time_delay@q", {"tau_q": 0.05}, maneuver="3211", noise=0.05, seed=9)
    rep = diagnose(rec, base, band=(0.3, 150.0), bands=[110.0, 150.0], max_effects=1)
    assert rep.status == "insufficient_excitation" and rep.verdict == "none"


def test_gust_candidates_without_alpha_w_are_skipped_with_a_reason():
    rep = run("time_delay@q", {"tau_q": 0.04}, holdout=False, max_effects=1)
    ni = {n["key"]: n["reason"] for n in rep.not_identifiable}
    assert "alpha_w" in ni["gust_lag@alpha_w"]


def test_forward_selection_finds_a_second_effect():
    # a 40 ms q-sensor delay and a 10 % alpha gain error together: both are found (in either order,
    # the second tested against the model with the first), and the second is credited with the
    # remaining gap it closes
    from fdml.record import Record

    base = steady()
    recs = []
    for man, seed in (("3211", 21), ("doublet", 22)):
        r = simulate_truth(base, "time_delay@q", {"tau_q": 0.04}, maneuver=man, noise=0.0, seed=seed)
        rng = np.random.default_rng(seed)
        sig = dict(r.signals)
        sig["alpha"] = 1.1 * sig["alpha"]
        for k in ("alpha", "q", "az"):
            sig[k] = sig[k] + 0.04 * np.std(sig[k]) * rng.standard_normal(r.n)
        recs.append(Record(r.t, sig, name=f"two-{man}", check_units=False))
    rep = diagnose(recs[0], base, holdout=recs[1], band=BAND)
    keys = [s["key"] for s in rep.selected]
    assert sorted(keys) == ["sensor_scale@alpha", "time_delay@q"]
    assert rep.selected[1]["step"] == 1 and rep.selected[1]["shrink"] > 0.8
    assert not rep.unexplained
