"""The control rows of a block (block/problem.py ``control_rows``): the rows
of the points asked for, in the control file's order, against a plain
lookup by dictionary."""

from __future__ import annotations

import numpy as np
import pytest

from strip_aerotri.block.problem import control_rows
from strip_aerotri.observations import ControlPoints, ControlType, ImageObservations


def _reference(obs, ctrl, points):
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    rows = [
        k for k, pid in enumerate(ctrl.point_ids) if pid in lookup and points[lookup[pid]]
    ]
    return np.array(rows, dtype=np.intp), np.array([lookup[ctrl.point_ids[k]] for k in rows])


@pytest.mark.parametrize("sorted_ids", [True, False], ids=["sorted", "unsorted"])
def test_control_rows_match_a_dictionary_lookup(sorted_ids):
    rng = np.random.default_rng(2345)
    names = [f"P{k:03d}" for k in range(40)]
    point_ids = tuple(names if sorted_ids else rng.permutation(names).tolist())
    obs = ImageObservations(
        photo_ids=("a", "b"), point_ids=point_ids, photo=np.zeros(0, np.intp),
        point=np.zeros(0, np.intp), xy=np.zeros((0, 2)), sigma=np.zeros(0),
        principal_distance=100.0,
    )  # fmt: skip
    # control in its own order, with ids not observed ("X1", "P999") among them
    ctrl_ids = (*rng.permutation(names[::3]).tolist(), "X1", "P999", "P001")
    kinds = [ControlType.FULL, ControlType.PLAN, ControlType.HEIGHT, ControlType.CHECK]
    n = len(ctrl_ids)
    ctrl = ControlPoints(
        point_ids=ctrl_ids, xyz=rng.normal(size=(n, 3)),
        kind=tuple(kinds[k % 4] for k in range(n)),
        sigma_xy=rng.uniform(0.01, 0.02, n), sigma_h=rng.uniform(0.02, 0.03, n),
    )  # fmt: skip
    points = rng.random(len(point_ids)) < 0.6
    got = control_rows(obs, ctrl, points)
    rows, idx = _reference(obs, ctrl, points)
    assert rows.size >= 5 and rows.size < n - 3  # some left out by ``points``
    np.testing.assert_array_equal(got.rows, rows)
    np.testing.assert_array_equal(got.idx, idx)
    np.testing.assert_array_equal(got.given, ctrl.xyz[rows])
    np.testing.assert_array_equal(got.sigma[:, 0], ctrl.sigma_xy[rows])
    np.testing.assert_array_equal(got.sigma[:, 1], ctrl.sigma_xy[rows])
    np.testing.assert_array_equal(got.sigma[:, 2], ctrl.sigma_h[rows])
    kind = [ctrl.kind[k] for k in rows]
    np.testing.assert_array_equal(got.check, [k is ControlType.CHECK for k in kind])
    np.testing.assert_array_equal(
        got.use_xy, [k in (ControlType.FULL, ControlType.PLAN) for k in kind]
    )
    np.testing.assert_array_equal(
        got.use_z, [k in (ControlType.FULL, ControlType.HEIGHT) for k in kind]
    )
