"""The fit's progress bar counts the fit's iterations (issue 21: it stopped at "1it")."""

import re

import numpy as np
import pytest

import fdml
from fdml.cli import main
from fdml.record import add_noise
from fdml.simulate import simulate_maneuver

pytest.importorskip("tqdm")

pytestmark = pytest.mark.filterwarnings("ignore::fdml.FdmlWarning")


@pytest.fixture(scope="module")
def record_csv(tmp_path_factory):
    truth = fdml.make_model("dimensional", airspeed=50.0)
    rec = simulate_maneuver(truth, "3211", duration=8.0, dt=0.05)
    rec = add_noise(rec, 0.02, np.random.default_rng(1), relative=True)
    path = tmp_path_factory.mktemp("progress") / "rec.csv"
    rec.to_csv(path)
    return path


def _last_count(stream: str) -> int:
    """The iteration count of the bar's last drawing (tqdm redraws with carriage returns)."""
    counts = re.findall(r"fdml fit: (\d+)it", stream)
    assert counts, stream
    return int(counts[-1])


def test_fit_progress_bar_ends_on_the_number_of_iterations(record_csv, capsys):
    code = main(["fit", str(record_csv), "--airspeed", "50", "--progress"])
    out, err = capsys.readouterr()
    iterations = int(re.search(r"converged after (\d+) iterations", out).group(1))
    assert code == 0 and iterations > 1
    assert _last_count(err) == iterations
