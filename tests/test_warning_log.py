"""fdml.warning_log: warnings recorded with their category and raised again for the caller's filters."""

import warnings

import pytest

from fdml.errors import ConvergenceWarning, DataWarning
from fdml.warning_log import RecordedWarning, as_recorded, recording


def test_records_category_and_message_and_reemits():
    with pytest.warns(DataWarning, match="far from trim"):
        with recording() as log:
            warnings.warn("ends far from trim", DataWarning)
            warnings.warn("ends far from trim", DataWarning)  # a repeat is kept once
            warnings.warn("stopped at 60 passes", ConvergenceWarning)
    assert log == [
        RecordedWarning("DataWarning", "ends far from trim"),
        RecordedWarning("ConvergenceWarning", "stopped at 60 passes"),
    ]


def test_recorded_even_when_the_caller_ignores_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a re-emitted warning would raise here
        with recording(reemit=False) as log:
            warnings.warn("x", DataWarning)
    assert [str(w) for w in log] == ["DataWarning: x"]


def test_nested_recordings_both_keep_the_warning():
    with recording(reemit=False) as outer:
        with recording() as inner:
            warnings.warn("inner", DataWarning)
    assert inner == outer == [RecordedWarning("DataWarning", "inner")]


@pytest.mark.parametrize(
    "value, expected",
    [
        ({"category": "DataWarning", "message": "m"}, RecordedWarning("DataWarning", "m")),
        ("ConvergenceWarning: a: b", RecordedWarning("ConvergenceWarning", "a: b")),
        ("plain text: with colon", RecordedWarning("UserWarning", "plain text: with colon")),
    ],
)
def test_from_value_round_trips(value, expected):
    assert RecordedWarning.from_value(value) == expected
    assert RecordedWarning.from_value(expected.to_dict()) == expected
    assert as_recorded([value, expected]) == (expected,)
