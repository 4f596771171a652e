"""fdml.Record as the README shows it: channels are attributes as well as items."""

import copy
import pickle

import numpy as np
import pytest

from fdml.record import Record


@pytest.fixture
def rec():
    t = np.arange(0.0, 2.0, 0.02)
    de = 0.01 * np.sin(t)
    return Record(t, {"de": de, "alpha": 0.5 * de, "q": 0.2 * de, "az": -de, "theta": 0.1 * de}, name="r1")


def test_channels_are_attributes_and_the_same_arrays_as_items(rec):
    for name in ("de", "alpha", "q", "az", "theta"):
        assert getattr(rec, name) is rec[name]
    assert rec.t is rec.t  # the fields are still the fields
    assert rec.name == "r1"


def test_a_missing_channel_is_an_attribute_error_naming_the_channels(rec):
    with pytest.raises(AttributeError) as exc:
        rec.alpha_w  # noqa: B018 - a known channel this record lacks
    msg = str(exc.value)
    assert "'alpha_w'" in msg and "r1" in msg
    assert "de, alpha, q, az, theta" in msg
    with pytest.raises(AttributeError, match="de, alpha, q, az, theta"):
        rec.elevator  # noqa: B018 - not a channel at all
    assert not hasattr(rec, "V") and getattr(rec, "V", None) is None


def test_copies_and_pickles_still_work(rec):
    for other in (copy.copy(rec), copy.deepcopy(rec), pickle.loads(pickle.dumps(rec))):
        np.testing.assert_array_equal(other.alpha, rec.alpha)
