"""Bad input on every command: exit code 2, one line naming the problem, nothing written (issue 9).

tests/test_bad_inputs.py holds the table for ``fit``, ``batch``, ``response`` and
``simulate`` (issue 14).  This table covers the commands it misses or barely
touches -- ``report``, ``aircraft``, ``effects``, ``check``, ``demo``, ``response``,
``montecarlo``, ``diagnose``, ``batch`` -- and the cases issue 9 lists.  Each case
runs through ``fdml.cli.main`` from a scratch working directory and asserts: exit
code 2, exactly one line on stderr starting ``fdml: error:`` and containing the
named texts, no traceback, and no file or folder left behind (the working
directory and the input folder are listed before and after).
"""

from __future__ import annotations

import json
import os
import warnings

import numpy as np
import pytest
from conftest import assert_refused_in_one_line

from fdml.cli import main
from fdml.estimate import fit
from fdml.models import make_model
from fdml.record import Record
from fdml.simulate import simulate_maneuver

STEADY = ["--aircraft", "navion", "--model", "steady"]
MAPPED = ["--columns", "t=t,de=de,alpha=alpha,q=q,az=az", "--units", "de=rad,alpha=rad,q=rad/s,az=g"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Inputs, good and bad, in one folder: name -> path (str); ``dir`` is the folder."""
    d = tmp_path_factory.mktemp("bad_inputs_more")
    model = make_model("steady", "navion")
    rec = simulate_maneuver(model, "3211", duration=10.0, noise=0.02, seed=1)
    out = {"dir": d, "a": rec.to_csv(d / "a.csv")}
    Record(rec.t, {**rec.signals, "de": np.full(rec.n, 0.01)}, name="flat").to_csv(d / "flat.csv")
    out["flat"] = d / "flat.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fit(rec.window(0.0, 4.0), model, band=(0.5, 8.0, 0.5))
    text = res.to_json()
    out["result"] = d / "result.json"
    out["result"].write_text(text)
    doc = json.loads(text)
    del doc["values"]
    for name, content in {
        "no_params": json.dumps(doc),
        "truncated": text[: len(text) // 2],
        "array": "[1, 2]",
        "garbage": "not json at all",
        "empty": "",
    }.items():
        (d / f"{name}.json").write_text(content)
        out[name] = d / f"{name}.json"
    (d / "latin1.json").write_bytes(text.replace('"fdml.FitResult"', '"fdml.FitResult\u00e9"').encode("latin-1"))
    out["latin1"] = d / "latin1.json"
    (d / "nonutf8.csv").write_bytes(b"t,de,alpha,q,az\n0,\xff\xfe,0,0,0\n")
    out["nonutf8"] = d / "nonutf8.csv"
    (d / "empty.csv").write_text("")
    out["empty_csv"] = d / "empty.csv"
    (d / "header_only.csv").write_text("t,de,alpha,q,az\n")
    out["header_only"] = d / "header_only.csv"
    (d / "folder").mkdir()
    out["folder"] = d / "folder"
    out["missing"] = d / "missing.csv"
    return {k: str(v) for k, v in out.items()}


# (id, command line with {placeholders} from `files`, texts the one stderr line must contain)
CASES = [
    # report
    ("report-missing", ["report", "{dir}/nope.json"], ["{dir}/nope.json"]),
    ("report-not-json", ["report", "{garbage}"], ["{garbage}", "JSON"]),
    ("report-truncated", ["report", "{truncated}"], ["{truncated}"]),
    ("report-array", ["report", "{array}"], ["{array}"]),
    ("report-empty", ["report", "{empty}"], ["{empty}"]),
    ("report-no-values", ["report", "{no_params}"], ["{no_params}", "values"]),
    ("report-latin1", ["report", "{latin1}"], ["{latin1}", "UTF-8"]),
    ("report-folder", ["report", "{folder}"], ["{folder}"]),
    ("report-a-record", ["report", "{a}"], ["{a}"]),
    ("report-out-is-a-file", ["report", "{result}", "-o", "{a}"], ["{a}"]),
    # aircraft
    ("aircraft-unknown", ["aircraft", "show", "concorde"], ["concorde"]),
    ("aircraft-bad-action", ["aircraft", "fly"], ["fly"]),
    ("aircraft-invalid-file", ["aircraft", "show", "{garbage}"], ["{garbage}"]),
    # effects
    ("effects-extra-argument", ["effects", "everything"], ["everything"]),
    ("effects-unknown-option", ["effects", "--all"], ["--all"]),
    # check
    ("check-missing", ["check", "{missing}"], ["{missing}"]),
    ("check-folder", ["check", "{folder}"], ["{folder}"]),
    ("check-empty", ["check", "{empty_csv}"], ["{empty_csv}"]),
    ("check-header-only", ["check", "{header_only}"], ["{header_only}"]),
    ("check-non-utf8", ["check", "{nonutf8}"], ["{nonutf8}"]),
    ("check-band-above-nyquist", ["check", "{a}", "--band", "1:500:1"], ["Nyquist"]),
    ("check-band-four-parts", ["check", "{a}", "--band", "1:5:0.1:2"], ["--band", "LO:HI[:STEP]"]),
    ("check-n-params-zero", ["check", "{a}", "--n-params", "0"], ["n_params", "got 0"]),
    ("check-window-inverted", ["check", "{a}", "--t0", "5", "--t1", "2"], ["{a}", "window"]),
    ("check-wrong-format", ["check", "{a}", "--format", "sidpac"], ["{a}"]),
    ("check-bad-columns", ["check", "{a}", "--columns", "t=time,de", "--units", "de=rad"], ["--columns"]),
    ("check-bad-unit", ["check", "{a}", *MAPPED[:2], "--units", "de=furlong,alpha=rad,q=rad/s,az=g"], ["furlong"]),
    # demo
    ("demo-negative-noise", ["demo", "--noise", "-0.1", "--no-figure"], ["noise"]),
    ("demo-noise-text", ["demo", "--noise", "lots", "--no-figure"], ["lots"]),
    ("demo-noise-nan", ["demo", "--noise", "nan", "--no-figure"], ["noise"]),
    ("demo-negative-seed", ["demo", "--seed", "-3", "--no-figure"], ["--seed", "-3"]),
    ("demo-out-is-a-file", ["demo", "-o", "{a}", "--no-figure"], ["{a}"]),
    # response
    ("response-unknown-model", ["response", "--model", "quantum"], ["quantum"]),
    ("response-set-not-number", ["response", *STEADY, "--set", "Cm_de=abc"], ["Cm_de=abc"]),
    ("response-set-no-value", ["response", *STEADY, "--set", "Cm_de"], ["Cm_de"]),
    ("response-set-unknown", ["response", *STEADY, "--set", "Cx_zz=1"], ["Cx_zz"]),
    ("response-set-nan", ["response", *STEADY, "--set", "Cm_de=nan"], ["Cm_de"]),
    ("response-unknown-aircraft", ["response", "--aircraft", "concorde", "--model", "steady"], ["concorde"]),
    ("response-unknown-effect", ["response", *STEADY, "--effect", "warp_drive"], ["warp_drive"]),
    ("response-negative-airspeed", ["response", "--model", "dimensional", "--airspeed", "-5"], ["airspeed"]),
    ("response-band-text", ["response", *STEADY, "--band", "low:high:step"], ["--band"]),
    # montecarlo
    ("montecarlo-n-zero", ["montecarlo", *STEADY, "-n", "0", "--no-progress"], ["n must be", "got 0"]),
    ("montecarlo-negative-noise", ["montecarlo", *STEADY, "-n", "2", "--noise", "-1", "--no-progress"], ["noise"]),
    ("montecarlo-noise-text", ["montecarlo", *STEADY, "-n", "2", "--noise", "alpha=x", "--no-progress"], ["alpha=x"]),
    ("montecarlo-zero-duration", ["montecarlo", *STEADY, "-n", "2", "--duration", "0", "--no-progress"], ["duration"]),
    ("montecarlo-zero-dt", ["montecarlo", *STEADY, "-n", "2", "--dt", "0", "--no-progress"], ["dt"]),
    ("montecarlo-unknown-fit-model", ["montecarlo", *STEADY, "-n", "2", "--fit-model", "quantum"], ["quantum"]),
    ("montecarlo-out-is-a-file", ["montecarlo", *STEADY, "-n", "2", "--no-progress", "-o", "{a}"], ["{a}"]),
    # diagnose
    ("diagnose-missing", ["diagnose", "{missing}", *STEADY], ["{missing}"]),
    ("diagnose-duplicate-outputs", ["diagnose", "{a}", *STEADY, "--outputs", "alpha,alpha"], ["alpha"]),
    ("diagnose-inverted-band", ["diagnose", "{a}", *STEADY, "--band", "10:1"], ["band", "below"]),
    ("diagnose-alpha-above-one", ["diagnose", "{a}", *STEADY, "--alpha", "2"], ["alpha", "2.0"]),
    ("diagnose-unknown-library", ["diagnose", "{a}", *STEADY, "--library", "warp_drive"], ["warp_drive"]),
    ("diagnose-negative-max-effects", ["diagnose", "{a}", *STEADY, "--max-effects", "-1"], ["max_effects", "-1"]),
    ("diagnose-missing-holdout", ["diagnose", "{a}", *STEADY, "--holdout", "{missing}"], ["{missing}"]),
    ("diagnose-output-is-input", ["diagnose", "{a}", *STEADY, "-o", "{a}"], ["{a}"]),
    ("diagnose-bands-text", ["diagnose", "{a}", *STEADY, "--bands", "x,y"], ["--bands"]),
    ("diagnose-flat-elevator", ["diagnose", "{flat}", *STEADY], ["'flat'", "no power in the band"]),
    # batch
    ("batch-no-records", ["batch", *STEADY, "--output", "{dir}/b_none", "--serial", "--no-progress"], ["required"]),
    (
        "batch-duplicate-outputs",
        ["batch", "{a}", *STEADY, "--outputs", "alpha,alpha", "--output", "{dir}/b_dup", "--serial", "--no-progress"],
        ["alpha"],
    ),
    (
        "batch-fix-not-number",
        ["batch", "{a}", *STEADY, "--fix", "Cm_de=abc", "--output", "{dir}/b_fix", "--serial", "--no-progress"],
        ["Cm_de=abc"],
    ),
    ("batch-out-is-a-file", ["batch", "{a}", *STEADY, "--output", "{a}", "--serial", "--no-progress"], ["{a}"]),
    (
        "batch-band-at-zero",
        ["batch", "{a}", *STEADY, "--band", "0:10:0.1", "--output", "{dir}/b_band", "--serial", "--no-progress"],
        ["--band", "positive"],
    ),
    (
        "batch-unknown-trim",
        ["batch", "{a}", *STEADY, "--trim", "median", "--output", "{dir}/b_trim", "--serial", "--no-progress"],
        ["median"],
    ),
    # fit and simulate: the cases issue 9 lists
    ("fit-flat-elevator", ["fit", "{flat}", *STEADY], ["'flat'", "no power in the band 0.1-10 rad/s"]),
    ("fit-duplicate-outputs", ["fit", "{a}", *STEADY, "--outputs", "alpha,alpha"], ["alpha"]),
    ("fit-empty-outputs", ["fit", "{a}", *STEADY, "--outputs", ","], ["--outputs"]),
    ("fit-output-is-a-folder", ["fit", "{a}", *STEADY, "-o", "{folder}"], ["{folder}"]),
    ("simulate-negative-noise", ["simulate", *STEADY, "--noise", "-0.1", "-o", "{dir}/s.csv"], ["noise"]),
    ("simulate-noise-text", ["simulate", *STEADY, "--noise", "lots", "-o", "{dir}/s.csv"], ["lots"]),
]


def _tree(*folders) -> set:
    return {os.path.join(root, n) for f in folders for root, dirs, names in os.walk(f) for n in dirs + names}


@pytest.mark.parametrize("argv, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_command_line_refuses_with_one_line_and_writes_nothing(files, tmp_path, monkeypatch, capsys, argv, expected):
    monkeypatch.chdir(tmp_path)  # default outputs (fdml-demo, ...) would land here
    before = _tree(files["dir"], tmp_path)
    try:
        code = main([a.format(**files) for a in argv])
    except SystemExit as exc:  # argparse usage errors exit through SystemExit(2)
        code = exc.code
    assert_refused_in_one_line(code, capsys.readouterr().err, [t.format(**files) for t in expected])
    assert _tree(files["dir"], tmp_path) == before, "a file was left behind"


def test_the_table_is_large_and_covers_every_command():
    commands = {c[1][0] for c in CASES}
    assert len(CASES) >= 60
    assert commands >= {
        "report",
        "aircraft",
        "effects",
        "check",
        "demo",
        "response",
        "montecarlo",
        "diagnose",
        "batch",
        "fit",
        "simulate",
    }
