"""The plan/height control of an adjustment of units as it goes
(ground/control_passes.py): settled by what the adjustment uses."""

from __future__ import annotations

import numpy as np

from strip_aerotri.frames import make_work_frame
from strip_aerotri.geodesy import GroundCRS
from strip_aerotri.ground.control_passes import PASS_TOLERANCE_M, ControlPasses
from strip_aerotri.options import Route


def _passes():
    """Three control points in UTM 34N about a tangent work frame: a full
    point at the frame's origin, a height point 6 km away (its plan guessed)
    and a plan point 6 km away the other way (its height guessed)."""
    crs = GroundCRS.from_user_input("EPSG:32634")
    given = np.array(
        [
            [500000.0, 5540000.0, 150.0],
            [np.nan, np.nan, 160.0],
            [494000.0, 5540000.0, np.nan],
        ]
    )
    guess = np.array(
        [[500000.0, 5540000.0, 150.0], [506000.0, 5540000.0, 160.0], [494000.0, 5540000.0, 155.0]]
    )
    work = make_work_frame(Route.GEOCENTRIC, crs, guess, 0.0)
    use_xy = np.array([True, False, True])
    use_z = np.array([True, True, False])
    passes = ControlPasses(work, np.arange(3), given, guess.copy(), use_xy, use_z, 8)
    return passes, work, guess


def test_a_guess_that_moves_the_targets_by_nothing_that_counts_has_settled():
    """The height point's plan guess moving 0.1 mm moves its work-frame
    height by 1e-7 m (6 km from the origin: 1e-3 of it): settled, the guess
    taken; 1 m moves it by 1 mm: not settled, the control follows."""
    passes, work, guess = _passes()
    assert passes.guessed
    moved = guess.copy()
    moved[1, 0] += 1e-4
    before = passes.target()
    assert passes.update(work.to_work(moved), converged=False) is None
    assert passes.settled
    np.testing.assert_allclose(passes.guess[1], moved[1])
    shift = np.nanmax(np.abs(passes.target() - before))
    assert 0.0 < shift < PASS_TOLERANCE_M

    passes, work, guess = _passes()
    moved = guess.copy()
    moved[1, 0] += 1.0
    target = passes.update(work.to_work(moved), converged=False)
    assert target is not None and not passes.settled
    # the target moved by the curvature's share of the 1 m: about 1 mm in height
    assert 5e-4 < abs(target[1, 2] - work.to_work(guess)[1, 2]) < 2e-3
    assert np.isnan(target[1, :2]).all() and np.isnan(target[2, 2])
