"""``fdml design``: the table, the CSV for the card, the figure, --json, --input, and one-line refusals."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import assert_refused_in_one_line

from fdml.cli import main
from fdml.record import read_csv

NAVION = ["design", "--aircraft", "navion", "--model", "unsteady", "--duration", "12", "--refine", "4"]


def _run(args, cwd):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, "-m", "fdml", *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=120
    )


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    d = tmp_path_factory.mktemp("design")
    args = NAVION + ["--criterion", "discriminate", "--amplitude", "2deg", "--band", "0.5:10", "-o", "in.csv"]
    return d, _run(args + ["--json"], d)


@pytest.mark.slow
def test_design_writes_csv_and_figure_and_json(designed):
    d, proc = designed
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["input"] == "in.csv"
    assert (d / "in.png").stat().st_size > 0
    rec = read_csv(d / "in.csv", require=("de",))
    assert list(rec.signals) == ["de"]
    assert np.max(np.abs(rec["de"])) == pytest.approx(math.radians(2.0), rel=1e-9)  # peak at the limit
    assert rec.duration == pytest.approx(12.0)
    pred = out["predicted"]
    assert set(pred["baselines"]) == {"3211", "sweep"}
    for name, row in pred["parameters"].items():
        assert row["stderr"] > 0
        assert pred["baselines"]["3211"][name]["stderr"] > 0
    disc = out["discrimination"]
    assert 0 <= disc["3211"]["probability"] <= 1 and disc["3211"]["df"] == 1


@pytest.mark.slow
def test_design_predicts_for_a_given_input(designed, tmp_path):
    d, _ = designed
    proc = _run(["design", "--aircraft", "navion", "--input", str(d / "in.csv"), "--band", "0.5:10", "--json"], d)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["criterion"] == "given" and out["predicted"]["baselines"] == {}
    assert out["discrimination"]["in"]["noncentrality"] > 0


@pytest.mark.slow
def test_design_prints_a_table(tmp_path, capsys):
    args = ["--criterion", "discriminate", "--band", "0.5:8", "--detect", "time_delay:alpha"]
    code = main(NAVION + args + ["-o", str(tmp_path / "x.csv")])
    out = capsys.readouterr().out
    assert code == 0
    assert "3211" in out and "sweep" in out and "P(detect)" in out and "tau_alpha" in out
    assert (tmp_path / "x.csv").exists() and (tmp_path / "x.png").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "extra, expected",
    [
        (["--band", "0.5:200"], ["Nyquist"]),
        (["--amplitude", "3deg", "--rate", "1deg/s"], ["rate limit"]),
        (["--amplitude=-1deg"], ["--amplitude"]),
        (["--criterion", "a-optimal", "--targets", "F"], ["F is fixed"]),
        (["--criterion", "a-optimal", "--targets", "b1"], ["not in the"]),
        (["--criterion", "a-optimal"], ["target"]),
        (["--model", "steady", "--criterion", "discriminate"], ["unsteady"]),
        (["--detect", "no_such_effect"], ["no_such_effect"]),
    ],
)
def test_design_refuses_in_one_line(tmp_path, capsys, extra, expected):
    out = tmp_path / "x.csv"
    code = main(NAVION + extra + ["-o", str(out)])
    assert_refused_in_one_line(code, capsys.readouterr().err, expected)
    assert not out.exists() and not out.with_suffix(".png").exists()
