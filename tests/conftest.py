"""Shared fixtures: reference data made independently of fdml's own simulator.

Tests that read the real flight records get them through :func:`fdml.io.data_path`,
which needs ``FDML_DATA`` (fdml never searches the tree for a data folder).  When
``FDML_DATA`` is unset, such a test is skipped with a reason naming it (below); when
it is set but a file is missing, the test fails naming the file.
"""

import os

import numpy as np
import pytest
from scipy import signal

import fdml.io.paths as _paths
from fdml.constants import G0
from fdml.record import Record


def three_two_one_one(t, amplitude=0.02, start=1.0, unit=0.3, rise=0.08):
    """A 3-2-1-1 elevator input (rad) with raised-cosine edges of ``rise`` seconds.

    Written out here so tests do not depend on fdml.maneuvers.  Smooth edges
    make the sampled input a faithful picture of the continuous one, so that
    lsim's first-order hold and the Fourier transform's cubic interpolation
    see the same signal (a sampled step is ambiguous between samples).
    """
    de = np.zeros_like(t)
    a = start
    level = 0.0
    for width, sign in ((3, 1), (2, -1), (1, 1), (1, -1), (0, 0)):
        target = sign * amplitude
        ramp = np.clip((t - a) / rise, 0.0, 1.0)
        de += (target - level) * 0.5 * (1 - np.cos(np.pi * ramp))
        level = target
        a += width * unit
    return de


def lsim_dimensional(model, t, de):
    """Noise-free outputs of a dimensional model by scipy.signal.lsim (first-order hold)."""
    p = model.parameters.values
    A = np.array([[p["Z_a"], 1 + p["Z_q"]], [p["M_a"], p["M_q"]]])
    B = np.array([[p["Z_de"]], [p["M_de"]]])
    k = model.U / G0
    C = np.array([[1, 0], [0, 1], [k * p["Z_a"], k * p["Z_q"]]])
    D = np.array([[0], [0], [k * p["Z_de"]]])
    _, y, _ = signal.lsim(signal.StateSpace(A, B, C, D), de, t, interp=True)
    return y


@pytest.fixture
def dimensional_case():
    """(model, t, de, y): Navion dimensional model, 3-2-1-1, 10 s at 50 Hz, noise-free."""
    from fdml.models import make_model

    m = make_model("dimensional", "navion")
    t = np.arange(0, 10 + 1e-9, 0.02)
    de = three_two_one_one(t)
    return m, t, de, lsim_dimensional(m, t, de)


def noisy_record(t, de, y, rng, fraction=0.05, name="sim"):
    """Record with white noise of ``fraction`` times each output's standard deviation."""
    sd = fraction * y.std(axis=0)
    yn = y + rng.normal(size=y.shape) * sd
    return Record(t, {"de": de, "alpha": yn[:, 0], "q": yn[:, 1], "az": yn[:, 2]}, name=name)


# --- hypothesis profiles ------------------------------------------------------------------------
# "ci" (default): a bounded number of examples, tests/test_properties.py in well under a minute.
# "long" (pytest --hypothesis-profile=long): the fuzzing run, over 100,000 examples in all.
# Both keep no example database (no .hypothesis folder in the checkout) and give every example
# a deadline; test_properties.py also guards each example against hangs with SIGALRM.
try:
    from datetime import timedelta

    from hypothesis import settings as _hsettings
except ImportError:  # hypothesis is in the test extra
    pass
else:
    _hsettings.register_profile("ci", max_examples=50, deadline=timedelta(seconds=5), database=None, print_blob=True)
    _hsettings.register_profile(
        "long", max_examples=7000, deadline=timedelta(seconds=10), database=None, print_blob=True
    )
    _hsettings.load_profile("ci")


# --- real flight records: skip, naming FDML_DATA, when it is unset ---------------------------------
_library_data_dir = _paths.data_dir


def _data_dir_or_skip():
    """fdml.io.paths.data_dir for the tests: a skip naming FDML_DATA when it is unset."""
    if not os.environ.get(_paths.DATA_ENV):
        pytest.skip(f"needs the real flight records: set {_paths.DATA_ENV}=/path/to/shared/data")
    return _library_data_dir()


_paths.data_dir = _data_dir_or_skip  # data_path looks data_dir up here at call time


def assert_refused_in_one_line(code, err: str, expected=()) -> None:
    """A command-line refusal: exit code 2, one ``fdml: error:`` line holding every ``expected`` text."""
    lines = err.splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("fdml: error: ")
    assert "internal error" not in err and "Traceback" not in err
    for text in expected:
        assert text in lines[0], (text, lines[0])
