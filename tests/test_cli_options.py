"""One option spec for every command (fdml.commands._options), checked over every parser.

In the spirit of python-control's kwargs test: walk ``fdml.cli.build_parser()``
and assert the rules of the spec, so that a new command or option that breaks
them fails here, not in a user's hands.  Then: every repeatable option
accumulates, per command; ``--outputs`` refuses duplicates; ``fdml fit`` takes
the record's airspeed and warns when a model's airspeed differs; ``fdml batch``
reads what ``fdml fit`` reads.
"""

import argparse
import json

import numpy as np
import pytest

from fdml.cli import build_parser, main
from fdml.commands._options import DEFAULT_BAND_TEXT, MODEL_CHOICES, default_model

#: Commands that write files, and those that only print.
WRITERS = {"demo", "fit", "compare", "simulate", "report", "batch", "montecarlo", "diagnose", "design", "aircraft"}
PRINTERS = {"check", "response", "effects"}

#: What each shared flag means: its dest, and how it parses (action, nargs).  A flag not in this
#: table is used by one command only; one that is must mean the same everywhere it is shown.
MEANINGS = {
    "--aircraft": ("aircraft", "store", None),
    "--model": ("model", "store", None),
    "--airspeed": ("airspeed", "store", None),
    "--effect": ("effect", "extend", None),
    "--band": ("band", "store", None),
    "--outputs": ("outputs", "store", None),
    "--fix": ("fix", "extend", "+"),
    "--free": ("free", "extend", "+"),
    "--set": ("set", "extend", "+"),
    "--holdout": ("holdout", "extend", "+"),
    "--boundary": ("boundary", "store", None),
    "--biases": ("biases", "store", None),
    "--trim": ("trim", "store", None),
    "--method": ("method", "store", None),
    "--stop": ("stop", "store", None),
    "--cov-type": ("cov_type", "store", None),
    "--sensitivity": ("sensitivity", "store", None),
    "--state-biases": ("state_biases", "store_true", 0),
    "--input-bias": ("input_bias", "store_true", 0),
    "--input-edges": ("input_edges", "store", None),
    "--format": ("format", "store", None),
    "--t0": ("t0", "store", None),
    "--t1": ("t1", "store", None),
    "--columns": ("columns", "store", None),
    "--units": ("units", "store", None),
    "--sign": ("sign", "store", None),
    "--layout": ("layout", "store", None),
    "--variable": ("variable", "store", None),
    "--delimiter": ("delimiter", "store", None),
    "--no-unit-check": ("check_units", "store_false", 0),
    "--output": ("output", "store", None),
    "-o": ("output", "store", None),
    "--workers": ("workers", "store", None),
    "--progress": ("progress", "boolean_optional", 0),
    "--no-progress": ("progress", "boolean_optional", 0),
    "--json": ("json", "store_true", 0),
    "--strict": ("strict", "store_true", 0),
    "--noise": ("noise", "store", None),
    "--seed": ("seed", "store", None),
    "--scheduler": ("scheduler", "store", None),
    "--maneuver": ("maneuver", "store", None),
    "--duration": ("duration", "store", None),
    "--dt": ("dt", "store", None),
    "--amplitude": ("amplitude", "store", None),
    "--steady": ("steady", "store", None),
    "--gust": ("gust", "store_true", 0),
    "-v": ("verbose", "store_true", 0),
    "--verbose": ("verbose", "store_true", 0),
}
#: Shown flags that parse differently on purpose: simulate's --gust takes an optional STD (m/s).
DIFFERENT = {("simulate", "--gust"): ("gust", "store", "?")}
#: Options of the shared spec: their defaults are None, so the library's default applies.
SHARED_DESTS = {
    "aircraft",
    "model",
    "gust",
    "airspeed",
    "effect",
    "band",
    "outputs",
    "fix",
    "free",
    "set",
    "holdout",
    "boundary",
    "biases",
    "trim",
    "method",
    "stop",
    "cov_type",
    "sensitivity",
    "state_biases",
    "input_bias",
    "format",
    "t0",
    "t1",
    "columns",
    "units",
    "sign",
    "layout",
    "variable",
    "delimiter",
    "check_units",
    "output",
    "workers",
    "progress",
    "json",
    "strict",
    "noise",
    "noise_model",
}


def _subparsers():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _kind(action) -> str:
    names = {
        argparse._StoreAction: "store",
        argparse._StoreTrueAction: "store_true",
        argparse._ExtendAction: "extend",
        argparse._AppendAction: "append",
        argparse.BooleanOptionalAction: "boolean_optional",
        argparse._StoreConstAction: "store_const",
        argparse._StoreFalseAction: "store_false",
        argparse._HelpAction: "help",
    }
    return names.get(type(action), type(action).__name__)


def _shown(parser):
    return [a for a in parser._actions if a.option_strings and a.help != argparse.SUPPRESS and a.dest != "help"]


def _hidden(parser):
    return [a for a in parser._actions if a.option_strings and a.help == argparse.SUPPRESS]


PARSERS = _subparsers()


def test_every_command_is_classified_and_every_writer_has_dash_o_output():
    assert set(PARSERS) == WRITERS | PRINTERS  # a new command is classified here
    for name, p in PARSERS.items():
        flags = {f for a in _shown(p) for f in a.option_strings}
        if name in WRITERS:
            out = next(a for a in _shown(p) if a.dest == "output")
            assert out.option_strings == ["-o", "--output"], name
            assert "file" in out.help or "folder" in out.help, name  # --help says which
        else:
            assert "-o" not in flags and "--output" not in flags, name


@pytest.mark.parametrize("name", sorted(PARSERS))
def test_one_flag_one_meaning(name):
    for a in _shown(PARSERS[name]):
        nargs = 0 if _kind(a) in ("store_true", "boolean_optional") else a.nargs
        for flag in a.option_strings:
            want = DIFFERENT.get((name, flag), MEANINGS.get(flag))
            if want is None:
                assert all(
                    flag not in {f for b in _shown(q) for f in b.option_strings}
                    for other, q in PARSERS.items()
                    if other != name
                ), f"{flag} on {name}: add to MEANINGS"
                continue
            assert (a.dest, _kind(a), nargs) == want, f"{name} {flag}"


@pytest.mark.parametrize("name", sorted(PARSERS))
def test_every_list_option_accumulates(name):
    for a in PARSERS[name]._actions:
        if a.option_strings and a.nargs in ("+", "*"):
            assert _kind(a) in ("extend", "append"), f"{name} {a.option_strings}: repeats would be lost"


@pytest.mark.parametrize("name", sorted(PARSERS))
def test_shared_options_default_to_none(name):
    for a in _shown(PARSERS[name]):
        if a.dest in SHARED_DESTS:
            assert a.default is None, f"{name} {a.option_strings} default {a.default!r}"


@pytest.mark.parametrize("name", sorted(PARSERS))
def test_no_hidden_spellings(name):
    """Issue 22: an option has the one spelling --help shows; the old hidden aliases are gone."""
    assert [a.option_strings for a in _hidden(PARSERS[name])] == []


@pytest.mark.parametrize(
    "argv",
    [
        ["diagnose", "r.csv", "--base", "steady"],
        ["diagnose", "--validate", "--processes", "2"],
        ["response", "--omega", "0.5:2:0.5"],
    ],
)
def test_old_spellings_are_refused(argv, capsys):
    from fdml.cli import main

    with pytest.raises(SystemExit) as exc:  # argparse's usage error: exit 2 through SystemExit
        main(argv)
    assert exc.value.code == 2
    assert f"unrecognized arguments: {argv[-2]}" in capsys.readouterr().err


def test_choices_and_band_default_come_from_the_library():
    from fdml.models import MODEL_KINDS
    from fdml.spectral import DEFAULT_BAND

    assert MODEL_CHOICES == tuple(MODEL_KINDS)
    assert tuple(float(x) for x in DEFAULT_BAND_TEXT.split(":")) == DEFAULT_BAND
    for name, p in PARSERS.items():
        for a in p._actions:
            if a.dest in ("model", "fit_model") and a.choices is not None:
                assert tuple(a.choices) == MODEL_CHOICES, name


def test_the_model_rule():
    ns = argparse.Namespace
    assert default_model(ns(model=None, aircraft="navion")) == "unsteady"
    assert default_model(ns(model=None, aircraft=None)) == "dimensional"
    assert default_model(ns(model="steady", aircraft=None)) == "steady"
    from fdml.commands._options import MODEL_RULE

    for name in ("fit", "diagnose"):  # the same rule, stated in both --help texts
        assert MODEL_RULE in PARSERS[name].description
        model = next(a for a in PARSERS[name]._actions if a.dest == "model" and a.help != argparse.SUPPRESS)
        assert MODEL_RULE in model.help and model.default is None


# --- repeatable options accumulate, per command -------------------------------------------------
@pytest.mark.parametrize(
    "name, argv, dest, want",
    [
        ("fit", ["r.csv", "--fix", "M_q=-3", "--fix", "Z_q=0"], "fix", ["M_q=-3", "Z_q=0"]),
        ("fit", ["r.csv", "--free", "a", "b", "--free", "c"], "free", ["a", "b", "c"]),
        (
            "fit",
            ["r.csv", "--effect", "time_delay:q", "--effect", "sensor_offset:az"],
            "effect",
            ["time_delay:q", "sensor_offset:az"],
        ),
        ("batch", ["d", "--fix", "A=1", "--fix", "B=2"], "fix", ["A=1", "B=2"]),
        ("batch", ["d", "--free", "A", "--free", "B"], "free", ["A", "B"]),
        ("response", ["--set", "A=1", "--set", "B=2"], "set", ["A=1", "B=2"]),
        ("simulate", ["-o", "x.csv", "--set", "A=1", "--set", "B=2"], "set", ["A=1", "B=2"]),
        ("montecarlo", ["--set", "A=1", "--set", "B=2"], "set", ["A=1", "B=2"]),
        ("diagnose", ["r.csv", "--holdout", "h1.csv", "--holdout", "h2.csv"], "holdout", ["h1.csv", "h2.csv"]),
        (
            "diagnose",
            ["r.csv", "--effect", "time_delay:q", "--effect", "actuator_lag"],
            "effect",
            ["time_delay:q", "actuator_lag"],
        ),
    ],
)
def test_repeated_options_accumulate(name, argv, dest, want):
    assert getattr(PARSERS[name].parse_args(argv), dest) == want


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """A Navion dimensional 3-2-1-1 (U = 53.6448 m/s) as fdml CSV and as a mapped CSV with airspeed V."""
    from fdml.models import make_model
    from fdml.record import add_noise
    from fdml.simulate import simulate_maneuver

    d = tmp_path_factory.mktemp("opts")
    rec = simulate_maneuver(make_model("dimensional", "navion"), "3211", duration=12.0, seed=4)
    rec = add_noise(rec, 0.02, np.random.default_rng(4), relative=True)
    plain = d / "r.csv"
    rec.to_csv(plain)
    mapped = d / "m.csv"
    V = 53.6448 + 0.1 * np.sin(rec.t)  # mean 53.6 m/s over the record
    cols = ["time", "elev", "aoa", "pitch_rate", "nz", "tas"]
    rows = np.column_stack([rec.t, *(rec.signals[k] for k in ("de", "alpha", "q", "az")), V])
    mapped.write_text(",".join(cols) + "\n" + "\n".join(",".join(f"{x:.12g}" for x in r) for r in rows) + "\n")
    return plain, mapped


MAP = [
    "--columns",
    "t=time,de=elev,alpha=aoa,q=pitch_rate,az=nz,V=tas",
    "--units",
    "de=rad,alpha=rad,q=rad/s,az=g,V=m/s",
]


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_fit_fix_twice_fixes_both(sim, capsys):
    code, out, err = _run(
        capsys,
        "fit",
        sim[0],
        "--model",
        "dimensional",
        "--airspeed",
        "53.6448",
        "--fix",
        "M_q=-3",
        "--fix",
        "Z_q=0",
        "--json",
    )
    d = json.loads(out)
    assert code in (0, 1), err
    assert {"M_q": -3.0, "Z_q": 0.0}.items() <= d["fixed"].items() and not {"M_q", "Z_q"} & set(d["params"])


def test_response_set_twice_sets_both(capsys):
    import fdml

    code, out, _ = _run(
        capsys,
        "response",
        "--aircraft",
        "navion",
        "--model",
        "steady",
        "--set",
        "CLa_t=3",
        "--set",
        "Cm_de=-1",
        "--band",
        "1:2:1",
        "--json",
    )
    G = np.array(json.loads(out)["real"]) + 1j * np.array(json.loads(out)["imag"])
    ref = fdml.make_model("steady", "navion").with_values({"CLa_t": 3.0, "Cm_de": -1.0}).frequency_response([1.0, 2.0])
    assert code == 0 and np.allclose(G, ref, rtol=1e-12)


# --- --outputs: each once -----------------------------------------------------------------------
@pytest.mark.parametrize(
    "text, fragment",
    [
        ("alpha,alpha", "alpha given more than once"),
        ("", "empty"),
        ("alpha,,q", "empty item"),
        ("alpha,beta", "unknown output"),
    ],
)
def test_outputs_refuse_duplicates_and_empty(sim, capsys, text, fragment):
    from fdml.errors import FdmlError
    from fdml.estimate import parse_outputs

    with pytest.raises(FdmlError, match=fragment):
        parse_outputs(text)
    code, _, err = _run(capsys, "fit", sim[0], "--model", "dimensional", "--airspeed", "53.6", "--outputs", text)
    assert code == 2 and fragment in err and "--outputs" in err and err.count("\n") == 1


def test_parse_outputs_keeps_order_and_defaults():
    from fdml.estimate import parse_outputs

    assert parse_outputs(None) == ("alpha", "q", "az")
    assert parse_outputs("q, alpha") == ("q", "alpha") and parse_outputs(["az"]) == ("az",)


# --- the record's airspeed --------------------------------------------------------------------------
def test_fit_takes_the_records_airspeed_and_says_so(sim, capsys):
    code, out, err = _run(capsys, "fit", sim[1], *MAP, "--json")  # no --model, no --aircraft, no --airspeed
    d = json.loads(out)
    assert code == 0, err
    assert d["model"] == "dimensional"
    air = d["provenance"]["airspeed"]
    assert air["source"] == "record" and air["value"] == pytest.approx(53.6448, rel=1e-3)  # window mean of V
    assert not [f for f in d["findings"] if f["code"] == "airspeed.mismatch"]


def test_an_explicit_airspeed_overrides_and_a_mismatch_is_a_finding(sim, tmp_path, capsys):
    res_file = tmp_path / "res.json"
    # 60 m/s against the record's 53.6: 11.8 % > 5 %, so the a_z gain would be wrong by 11.8 %
    code, out, err = _run(capsys, "fit", sim[1], *MAP, "--airspeed", "60", "--json", "-o", res_file)
    d = json.loads(out)
    assert code in (0, 1) and "airspeed.mismatch" not in err  # warnings are off without -v; kept in the result
    assert d["provenance"]["airspeed"] == {"value": 60.0, "unit": "m/s", "source": "--airspeed"}
    found = [f for f in d["findings"] if f["code"] == "airspeed.mismatch"]
    assert len(found) == 1 and found[0]["kind"] == "estimation"
    assert found[0]["value"] == 60.0 and found[0]["expected"] == pytest.approx(53.6448, rel=1e-3)
    saved = json.loads(res_file.read_text())
    assert saved["provenance"]["airspeed"]["source"] == "--airspeed"
    assert "airspeed.mismatch" in [f["code"] for f in saved["findings"]]


def test_aircraft_airspeed_mismatch_warns(sim, capsys):
    # the Do 128 preset flies at 70 m/s, the record at 53.6 m/s: +30 %
    code, out, _ = _run(capsys, "fit", sim[1], *MAP, "--aircraft", "do128", "--model", "dimensional", "--json")
    d = json.loads(out)
    assert code in (0, 1)
    assert d["provenance"]["airspeed"]["source"] == "aircraft"
    assert [f["code"] for f in d["findings"]].count("airspeed.mismatch") == 1


def test_airspeed_findings_threshold():
    from fdml.conditions import AIRSPEED_TOLERANCE, airspeed_findings, record_airspeed
    from fdml.record import Record

    t = np.arange(0, 1, 0.1)
    rec = Record(t, {s: np.zeros_like(t) for s in ("de", "alpha", "q", "az")}, name="r", meta={"U": 50.0})
    near = type("M", (), {"U": 50.0 * (1 + 0.9 * AIRSPEED_TOLERANCE)})()
    far = type("M", (), {"U": 50.0 * (1 + 1.1 * AIRSPEED_TOLERANCE)})()
    assert airspeed_findings(near, [rec]) == [] and len(airspeed_findings(far, [rec])) == 1
    assert record_airspeed([rec]) == 50.0
    assert record_airspeed([rec, Record(t, dict(rec.signals), name="s")]) is None  # one record lacks U


def test_dimensional_without_any_airspeed_is_refused(sim, capsys):
    code, _, err = _run(capsys, "fit", sim[0])
    assert code == 2 and "needs --airspeed" in err and "record that carries its airspeed" in err


# --- fit options exposed; batch reads what fit reads ------------------------------------------------------
def test_fit_exposes_cov_type_and_nuisance_options(sim, tmp_path, capsys):
    res_file = tmp_path / "res.json"
    code, out, err = _run(
        capsys,
        "fit",
        sim[0],
        "--airspeed",
        "53.6448",
        "--cov-type",
        "colored",
        "--state-biases",
        "--sensitivity",
        "fd",
        "--json",
        "-o",
        res_file,
    )
    d = json.loads(out)
    assert code in (0, 1), err
    assert d["cov_type"] == "colored"
    assert {"bias_alpha_dot", "bias_q_dot"} <= set(d["params"])
    assert json.loads(res_file.read_text())["options"]["state_biases"] is True


def test_batch_reads_mapped_columns(sim, tmp_path, capsys):
    out_dir = tmp_path / "b"
    base = ["batch", sim[1], "--airspeed", "53.6448", "--serial", "--no-progress", "--json", "-o", out_dir]
    code, out, _ = _run(capsys, *base)  # without the column map the record cannot be read
    assert code == 1 and json.loads(out)["failed"] == 1
    code, out, err = _run(capsys, *base, *MAP, "--cov-type", "colored", "--t1", "10")
    s = json.loads(out)
    assert code == 0 and s["failed"] == 0, err
    res = json.loads(next((out_dir / "results").glob("m@*.json")).read_text())  # the windowed key
    assert res["options"]["cov_type"] == "colored" and res["batch"]["window"] == [None, 10.0]
