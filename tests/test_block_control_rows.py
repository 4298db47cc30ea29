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


def test_restored_control_rows_are_added_once():
    """The refinement's restored points take their control rows again, each
    once: a restored control point that already has a row (its block rows all
    rejected, NaN in the block's solution) keeps the one row it has."""
    from dataclasses import replace

    from strip_aerotri.block.problem import _prepare
    from strip_aerotri.block.snooping import _snoop
    from strip_aerotri.block.strips import _form, _products, _with_restored_control
    from strip_aerotri.options import BlunderOptions, Construction, Route
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(n_strips=2, n_photos_per_strip=8, preset="film", seed=4)
    blunders = BlunderOptions()
    from strip_aerotri.geodesy import GroundCRS

    formed = tuple(_form(sim.observations, s, None, blunders) for s in sim.strips)
    p = _prepare(
        sim.observations, sim.control, GroundCRS.from_user_input(sim.crs), tuple(sim.strips),
        formed,
        Route.GEOCENTRIC, Construction.MODELS, 10,
    )  # fmt: skip
    sol, use_xy, use_z, keep_rows, rejections = _snoop(p, blunders)
    block = _products(p, sol, use_xy, use_z, keep_rows, rejections)
    # take two control rows out of the problem, as if the block had left their points out
    gone = np.array([0, 3])
    keep = np.setdiff1d(np.arange(p.idx.size), gone)
    cut = replace(
        p, control_rows=p.control_rows[keep], idx=p.idx[keep], given=p.given[keep],
        sigma=p.sigma[keep], use_xy=p.use_xy[keep], use_z=p.use_z[keep], check=p.check[keep],
    )  # fmt: skip
    cut_block = replace(
        block, control_index=cut.control_rows, is_check=cut.check,
        control_residuals=block.control_residuals[keep],
    )  # fmt: skip
    cut_sol = replace(sol, guess=sol.guess[keep])
    restored = np.zeros(p.observations.n_points, dtype=bool)
    restored[p.idx[gone]] = True  # the two left out ...
    restored[p.idx[keep[0]]] = True  # ... and one that still has its row
    points = np.zeros((p.observations.n_points, 3))
    q, _, new_block = _with_restored_control(cut, cut_sol, cut_block, restored, points)
    assert q.control_rows.size == p.control_rows.size  # two rows back, none twice
    assert np.unique(q.control_rows).size == q.control_rows.size
    np.testing.assert_array_equal(np.sort(q.control_rows), np.sort(p.control_rows))
    order = np.argsort(q.control_rows)
    np.testing.assert_array_equal(q.idx[order], p.idx[np.argsort(p.control_rows)])
    assert q.use_xy.size == q.use_z.size == q.control_rows.size
    assert np.all(np.isnan(new_block.control_residuals[-gone.size :]))
