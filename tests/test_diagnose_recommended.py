"""The diagnosis hands back a fitted model: ``recommended``, as ``fdml fit --json`` prints a fit (issue 8)."""

import json

import pytest

import fdml
from fdml.cli import main
from fdml.diagnose import diagnose
from fdml.diagnose.report import RECOMMENDATION_KEYS
from fdml.diagnose.truth import simulate_truth
from fdml.results import load_result

TAU = 0.04  # s, the withheld pitch-rate delay


def cli(*argv):
    """(exit code, stdout) of ``fdml ARGV`` in-process (module-scoped fixtures cannot use capsys)."""
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main([str(a) for a in argv])
    return code, buf.getvalue()


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    """``fdml diagnose --json --recommended-output FIT.json`` and ``fdml fit --json`` of one delayed record."""
    d = tmp_path_factory.mktemp("rec")
    rec, fit_file = d / "r1.csv", d / "fit.json"
    simulate_truth(
        fdml.make_model("steady", "navion"), "time_delay@q", {"tau_q": TAU}, maneuver="3211", noise=0.04, seed=3
    ).to_csv(rec)
    code_d, out_d = cli(
        "diagnose",
        rec,
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
        "--json",
        "--recommended-output",
        fit_file,
    )
    code_f, out_f = cli("fit", rec, "--aircraft", "navion", "--model", "steady", "--band", "0.3:12:0.1", "--json")
    return ((code_d, json.loads(out_d)), (code_f, json.loads(out_f))), fit_file


def test_recommended_has_the_schema_of_fit_json(diagnosed):
    ((code_d, rep), (code_f, fit_json)), _ = diagnosed
    assert code_d == 0 and code_f in (0, 1)
    rec = rep["recommended"]
    # fdml fit --json's keys, less the two the command line adds (timing, the file written), plus the
    # diagnosis's own: what the kinematics settled, whether the choice is ambiguous, the derivatives
    assert set(rec) == set(fit_json) - {"timing", "result_file"} | set(RECOMMENDATION_KEYS)
    assert {"model", "params", "derived", "cost", "converged", "band"} <= set(rec)
    assert rec["converged"] is True and rec["ambiguous"] is False
    # the accepted effect is part of the fitted model near the withheld truth: the kinematics settle a
    # q-sensor delay (q lags alpha and a_z), so it is fixed at its kinematic value, whose standard error
    # the fit carries (3 standard errors: the estimate is unbiased, so this fails about 0.3 % of seeds)
    assert rec["settled_by_kinematics"] == ["time_delay@q"]
    tau = rec["effects"][0]["parameters"]["tau_q"]
    assert tau["known"] and abs(tau["value"] - TAU) < 3 * tau["stderr"]
    assert set(rec["params"]) == set(fit_json["params"])  # the base fit's estimates (tau_q is fixed)


@pytest.mark.slow
def test_recommended_file_reloads_and_reports(diagnosed, tmp_path):
    ((_, rep), _), fit_file = diagnosed
    res = load_result(fit_file)
    rec = rep["recommended"]
    assert res.converged and set(res.names) == set(rec["params"])
    for name in res.names:  # the file holds the estimates the report printed (JSON round trip: exact)
        assert res.params[name] == rec["params"][name]["value"]
    # the kinematics settled the delay: fixed at its kinematic value, its uncertainty carried
    assert "tau_q" in res.model.parameters and not res.model.parameters["tau_q"].free
    assert res.options["known_uncertainty"]["tau_q"]["stderr"] > 0
    out = tmp_path / "report"
    code, _ = cli("report", fit_file, "-o", out)
    assert code == 0 and any(out.iterdir())


def test_recommended_without_an_effect_is_the_base_fit():
    base = fdml.make_model("steady", "navion")
    rec = simulate_truth(base, None, {}, maneuver="3211", noise=0.04, seed=11)
    rep = diagnose(rec, base, band=(0.3, 12.0), library=["time_delay@q"], max_effects=1)
    assert rep.verdict == "none"
    assert rep.recommended is not None and not rep.recommended.model.parts
    assert set(rep.recommended.params) == set(rep.details["base_fit"].names)
    with pytest.raises(AttributeError):  # the report is frozen
        rep.verdict = "time_delay"


def test_fit_json_names_the_effects_with_their_parameters(diagnosed):
    ((_, rep), (_, fit_json)), _ = diagnosed
    assert fit_json["effects"] == []  # the plain fit: no effects (its model field reads "steady")
    rec = rep["recommended"]
    assert [e["key"] for e in rec["effects"]] == ["time_delay@q"]
    tau = rec["effects"][0]["parameters"]["tau_q"]
    assert tau["unit"] == "s"
    # the same estimate and standard error as the params entry (one fit, two views of it)
    # fixed at its kinematic estimate: the value the kinematics gave, their standard error
    settled = rep["kinematics"]["settled"][0]
    assert (tau["value"], tau["stderr"]) == (settled["value"], settled["stderr"])
