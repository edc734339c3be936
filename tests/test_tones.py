"""planner.modulation.tones: when the camera tells tones apart, the limits a tone must keep, tone classes as IDs."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.errors import InputError
from planner.graph import build_graph
from planner.modulation.tones import (
    assign_tones,
    check_tone_limits,
    highest_tone_hz,
    lowest_readable_hz,
    tone_classes,
    tones_apart,
)


def test_tones_apart_on_the_rule():
    # 39 rows (the bundled rig's smallest image): 3,500 and 4,000 Hz read within 4000 (1 +- 1/39) etc., apart
    assert tones_apart(3500.0, 4000.0, 39.0)
    # (3000 + 3100) / 39 = 156 Hz > 100 Hz: the reading intervals overlap
    assert not tones_apart(3000.0, 3100.0, 39.0)
    # the boundary: f2 - f1 > (f1 + f2) / rows, strictly
    assert not tones_apart(1000.0, 1100.0, 21.0)
    assert tones_apart(1000.0, 1100.0, 21.01)
    assert not tones_apart(2000.0, 2000.0, 1e6)


def test_lowest_readable_is_one_period_in_the_image():
    assert lowest_readable_hz(40.0, 20e-6) == pytest.approx(1250.0)


def test_highest_tone_names_its_limit():
    high, why = highest_tone_hz(20e-6, 20_000.0)  # drivers: 2 switchings a period
    assert high == 10_000.0 and "driver" in why
    high, why = highest_tone_hz(40e-6, 20_000.0)  # camera: half a period over 2 rows of 40 us
    assert high == pytest.approx(6250.0) and "row time" in why


def test_check_tone_limits_names_the_luminaire_and_the_limit():
    with pytest.raises(InputError, match=r"site.yaml: luminaire 'B''s tone_hz 15000 Hz is above 10,000 Hz: the drivers"):
        check_tone_limits(["A", "B"], np.array([2000.0, 15000.0]), 20e-6, 20_000.0, "site.yaml")
    with pytest.raises(InputError, match=r"above 12,500 Hz: a stripe"):
        check_tone_limits(["A", "B"], np.array([2000.0, 15000.0]), 20e-6, 40_000.0, "site.yaml")
    check_tone_limits(["A", "B"], np.array([2000.0, 10000.0]), 20e-6, 20_000.0, "site.yaml")  # on the limit: kept


def test_classes_chain_tones_the_camera_cannot_tell_apart():
    tones = np.array([3000.0, 2030.0, 2000.0, 2060.0, 4000.0])
    # 60 rows: 2,000 ~ 2,030 ~ 2,060 (30 Hz < 67 Hz), though 2,000 and 2,060 alone would read apart
    assert tones_apart(2000.0, 2060.0, 60.0) is not None
    np.testing.assert_array_equal(tone_classes(tones, 60.0), [2, 1, 1, 1, 3])
    np.testing.assert_array_equal(tone_classes(tones, 1000.0), [4, 2, 1, 3, 5])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(200.0, 20_000.0), min_size=1, max_size=30), st.floats(1.0, 2000.0))
def test_tones_of_different_classes_read_apart(tones, rows):
    tones = np.array(tones)
    classes = tone_classes(tones, rows)
    assert sorted(set(classes.tolist())) == list(range(1, classes.max() + 1))
    i, j = np.nonzero(classes[:, None] != classes[None, :])
    assert np.all(tones_apart(tones[i], tones[j], rows))
    order = np.argsort(tones)  # classes grow with the tone
    assert np.all(np.diff(classes[order]) >= 0)


def test_assign_tones_keeps_classes_as_ids():
    xy = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], dtype=float)
    a = assign_tones(np.array([2000.0, 2500.0, 2000.0, 3000.0]), 60.0, build_graph(xy))
    assert a.scheme == "tones"
    np.testing.assert_array_equal(a.ids, [1, 2, 1, 3])
    assert a.bits == 2 and a.max_id == 3
    assert a.detail["tones"] == 3 and a.detail["tone_classes"] == 3
