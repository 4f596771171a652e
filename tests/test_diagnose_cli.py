"""``fdml diagnose``: JSON schema, exit codes, bad input; the validation harness's scoring."""

import json

import pytest

import fdml
from fdml.cli import main
from fdml.diagnose import diagnose
from fdml.diagnose.truth import simulate_truth
from fdml.diagnose.validation import Scenario, run_scenario, score, tune_threshold, wilson


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def delay_csv(tmp_path_factory):
    d = tmp_path_factory.mktemp("diag")
    base = fdml.make_model("steady", "navion")
    a = d / "r1.csv"
    b = d / "r2.csv"
    simulate_truth(base, "time_delay@q", {"tau_q": 0.04}, maneuver="3211", noise=0.04, seed=3).to_csv(a)
    simulate_truth(base, "time_delay@q", {"tau_q": 0.04}, maneuver="doublet", noise=0.04, seed=4).to_csv(b)
    return a, b


def test_cli_json_schema_and_holdout(capsys, tmp_path, delay_csv):
    a, b = delay_csv
    out_file = tmp_path / "rep.json"
    code, out, _ = run(
        capsys,
        "diagnose",
        str(a),
        "--aircraft",
        "navion",
        "--model",
        "steady",
        "--band",
        "0.3:12",
        "--holdout",
        str(b),
        "--max-effects",
        "1",
        "--json",
        "-o",
        str(out_file),
    )
    assert code == 0
    d = json.loads(out)
    # the keys, exactly these names, first
    assert list(d)[:7] == [
        "verdict",
        "ranking",
        "ambiguous",
        "not_identifiable",
        "location",
        "footprint",
        "unexplained",
    ]
    assert d["verdict"] == "time_delay"
    top = d["ranking"][0]
    assert top["channel"] == "q" and top["label"] == "confirmed" and top["shrink_holdout"] is not None
    assert set(top["params"]["tau_q"]) >= {"value", "stderr"}
    assert d["holdout"]["records"] and json.loads(out_file.read_text())["verdict"] == "time_delay"


@pytest.mark.slow
def test_cli_text_and_figure(capsys, tmp_path, delay_csv):
    a, _ = delay_csv
    fig = tmp_path / "d.png"
    code, out, _ = run(
        capsys,
        "diagnose",
        str(a),
        "--aircraft",
        "navion",
        "--model",
        "steady",
        "--band",
        "0.3:12",
        "--library",
        "time_delay,actuator_lag",
        "--max-effects",
        "1",
        "--figure",
        str(fig),
    )
    assert code == 0 and "time_delay@q" in out and "accepted" in out
    assert fig.stat().st_size > 10_000


def test_cli_bad_input_exits_2_with_one_line(capsys, delay_csv):
    code, _, err = run(capsys, "diagnose")
    assert code == 2 and "RECORD" in err
    a, _ = delay_csv
    code, _, err = run(capsys, "diagnose", str(a), "--model", "steady")
    assert code == 2 and "--aircraft" in err
    code, _, err = run(capsys, "diagnose", str(a), "--aircraft", "navion", "--model", "steady", "--band", "5:1")
    assert code == 2 and "band" in err
    code, _, err = run(capsys, "diagnose", str(a), "--aircraft", "navion", "--library", "no_such_effect")
    assert code == 2 and "unknown effect" in err


@pytest.mark.slow
def test_cli_validate_prints_the_table(capsys, monkeypatch):
    import fdml.diagnose.validation as V

    rows = [
        run_scenario(Scenario("time_delay@q", {"tau_q": 0.04}, "large", "3211", 0.03, "white", 5, "time_delay@q")),
        run_scenario(Scenario(None, {}, "-", "3211", 0.03, "white", 6, "none-white")),
    ]
    monkeypatch.setattr(V, "validate", lambda **kw: V.ValidationResult(rows, V.score(rows), {"n": 2}))
    code, out, _ = run(capsys, "diagnose", "--validate", "--quick")
    assert code == 0 and "false alarms none-white" in out and "top-1" in out
    # the scores relabel at the diagnosis's own threshold: the label it gave.  The q delay is settled by
    # the kinematics, whose label judges the model as given (its hold-out map flags cells; the settled
    # model's map, flagged_before_holdout, flags none)
    assert rows[0]["label"] == "confirmed" and rows[0]["flagged_before_holdout"] == 0
    assert [V.relabel(r, V.SHRINK_CONFIRM) for r in rows] == [r["label"] for r in rows]


def test_scoring_counts_what_it_says():
    rows = [
        {
            "case": "time_delay@q",
            "truth": "time_delay@q",
            "truth_name": "time_delay",
            "size": "large",
            "verdict": "time_delay",
            "verdict_key": "time_delay@q",
            "ambiguous": "[]",
            "ambiguous_names": "[]",
            "shrink": 0.9,
            "flagged_before_holdout": 2,
            "unexplained_holdout": 0,
            "plausible": True,
            "elapsed": 1.0,
        },
        {
            "case": "time_delay@q",
            "truth": "time_delay@q",
            "truth_name": "time_delay",
            "size": "small",
            "verdict": "actuator_lag",
            "verdict_key": "actuator_lag@de",
            "ambiguous": '["time_delay@de"]',
            "ambiguous_names": '["time_delay"]',
            "shrink": 0.9,
            "flagged_before_holdout": 2,
            "unexplained_holdout": 0,
            "plausible": True,
            "elapsed": 1.0,
        },
        {
            "case": "none-white",
            "truth": None,
            "truth_name": "none",
            "size": "-",
            "verdict": "none",
            "verdict_key": "none",
            "elapsed": 1.0,
        },
        {
            "case": "vane_filter",
            "truth": "vane_filter",
            "truth_name": "vane_filter",
            "size": "large",
            "verdict": "time_delay",
            "verdict_key": "time_delay@alpha",
            "ambiguous": "[]",
            "ambiguous_names": "[]",
            "shrink": 0.7,
            "flagged_before_holdout": 2,
            "unexplained_holdout": 2,
            "unexplained_in_sample": 1,
            "plausible": True,
            "elapsed": 1.0,
        },
    ]
    s = score(rows, 0.5)
    e = s["effects"]["time_delay@q"]
    assert e["top1"] == 0.5 and e["in_set"] == 1.0 and e["channel"] == 0.5 and e["median_shrink"] == 0.9
    assert s["nulls"]["none-white"]["rate"] == 0.0
    assert s["out_of_library"]["vane_filter"]["confidently_wrong"] == 0.0  # flagged cells remain: partial
    assert 0.3 <= tune_threshold(rows) <= 0.9
    rows[3]["unexplained_in_sample"] = 0  # the out-of-library fit closed the in-sample gap: now "confirmed"
    assert score(rows, 0.5)["out_of_library"]["vane_filter"]["confidently_wrong"] == 1.0
    lo, hi = wilson(5, 100)
    assert lo < 0.05 < hi and hi - lo < 0.1


def test_library_call_accepts_a_fit_result():
    base = fdml.make_model("steady", "navion")
    rec = simulate_truth(base, "sensor_scale@alpha", {"k_alpha": 0.1}, maneuver="3211", noise=0.04, seed=8)
    res = fdml.fit(rec, base)
    rep = diagnose(base=res, band=(0.3, 12.0), library=["sensor_scale", "time_delay"], max_effects=1)
    assert rep.verdict == "sensor_scale" and rep.selected[0]["channel"] == "alpha"
    k = rep.selected[0]["params"]["k_alpha"]
    assert abs(k["value"] - 0.1) < 4 * k["stderr"]
