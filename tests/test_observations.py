"""ImageObservations builder: ordering, index mapping, no mutation of inputs;
ControlPoints' masks."""

import numpy as np
import pytest

from strip_aerotri.observations import ControlPoints, ControlType, ImageObservations


def test_from_ids_sorts_by_photo_then_point_and_keeps_strip_order():
    photo = np.array(["1202", "1201", "1202", "1201", "9999"])
    point = np.array(["b", "b", "a", "007", "a"])
    xy = np.arange(10.0).reshape(5, 2)
    xy_before = xy.copy()
    obs = ImageObservations.from_ids(photo, point, xy, 152.0, photo_ids=["1201", "1202"])
    assert obs.photo_ids == ("1201", "1202")
    assert obs.point_ids == ("007", "a", "b")  # leading zero kept
    np.testing.assert_array_equal(obs.photo, [0, 0, 1, 1])
    np.testing.assert_array_equal(obs.point, [0, 2, 1, 2])
    # rows follow the sort: (1201, 007) was row 3, (1201, b) row 1, ...
    np.testing.assert_array_equal(obs.xy, xy_before[[3, 1, 2, 0]])
    np.testing.assert_array_equal(xy, xy_before)
    np.testing.assert_array_equal(obs.photo_slices(), [0, 2, 4])
    vec = obs.image_vectors()
    assert vec.shape == (4, 3) and np.all(vec[:, 2] == -152.0)


def test_image_vectors_of_chosen_rows_are_those_rows_of_all_vectors():
    photo = np.array(["1", "1", "2", "2", "2"])
    point = np.array(["a", "b", "a", "b", "c"])
    xy = np.arange(10.0).reshape(5, 2) - 4.0
    obs = ImageObservations.from_ids(photo, point, xy, 100.5)
    rows = np.array([4, 0, 0, 2])
    np.testing.assert_array_equal(obs.image_vectors(rows), obs.image_vectors()[rows])
    assert obs.image_vectors(np.zeros(0, dtype=np.intp)).shape == (0, 3)


def test_control_masks_follow_the_kinds_given_as_members_or_values():
    kinds = (ControlType.FULL, "plan", ControlType.HEIGHT, "check", "full")
    control = ControlPoints(
        tuple("ABCDE"), np.zeros((5, 3)), kinds, np.full(5, 0.01), np.full(5, 0.01)
    )
    np.testing.assert_array_equal(control.uses_xy, [True, True, False, False, True])
    np.testing.assert_array_equal(control.uses_h, [True, False, True, False, True])
    np.testing.assert_array_equal(control.is_check, [False, False, False, True, False])
    # fresh arrays each time: a caller may change its own copy
    mask = control.uses_xy
    mask[:] = False
    assert control.uses_xy[0]


def test_control_with_an_unknown_kind_is_named():
    control = ControlPoints(("A",), np.zeros((1, 3)), ("fixed",), np.ones(1), np.ones(1))
    with pytest.raises(ValueError, match="'fixed'"):
        _ = control.uses_xy
