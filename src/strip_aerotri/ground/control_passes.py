"""The plan/height iteration of an adjustment of units (the ground stage's
models, the block): control given in plan or in height only gets its other
coordinates from the adjusted point, and its work-frame coordinates are
computed again (the work frame is curved: a plan point's height moves its
X, Y), inside the iterations of
:func:`~strip_aerotri.geometry.simultaneous.adjust_units` (``control_update``)."""

from __future__ import annotations

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..frames import WorkFrame

#: The control has settled when no coordinate the adjustment uses moves more
#: (m, work frame).  A guessed coordinate moves them only through the
#: frame's curvature: a plan point's height its X, Y by the share of its
#: distance from the frame's origin over the earth's radius.  (Measured on
#: the guesses themselves, to 1e-5 m, the passes of a long strip followed
#: every step of the plan's weakest modes, for targets that moved by 1e-8
#: m: 7 iterations at 3000 photos against 5.  At 1e-5 m on the targets a
#: 1000-photo strip's points depended on the start by 3.6e-6 m; at 1e-6 m
#: by 9e-7 m.)
PASS_TOLERANCE_M = 1e-6


class ControlPasses:
    """The control of the active rows as the adjustment goes.

    After every iteration the missing coordinates are taken from the
    adjusted points; the control follows the iterations while the changes of
    its work-frame coordinates at least halve from one to the next (the two
    converge together), else it waits for the adjustment to settle on it,
    which ends a *pass*.  After
    ``max_passes`` passes it is left as it is (not settled).

    ``work`` the work frame, ``idx`` the point of each control row (C,),
    ``given`` (C, 3) as given (NaN where not), ``guess`` (C, 3) the start,
    ``use_xy``, ``use_z`` (C,) the components used."""

    def __init__(
        self,
        work: WorkFrame,
        idx: IntArray,
        given: FloatArray,
        guess: FloatArray,
        use_xy: BoolArray,
        use_z: BoolArray,
        max_passes: int,
    ) -> None:
        self.work, self.idx, self.given = work, idx, given
        self.guess = guess
        self.use_xy, self.use_z = use_xy, use_z
        self.active = use_xy | use_z
        self.max_passes = max_passes
        self.n_pass = 1
        self.settled = False
        self.done = False
        self.last_change = np.inf
        self._target: tuple[FloatArray, FloatArray] | None = None  # (guess, its target)

    @property
    def guessed(self) -> bool:
        """True when a used control point lacks a coordinate."""
        return bool(np.isnan(self.given[self.active]).any())

    def target(self) -> FloatArray:
        """Work-frame control of the active rows, NaN where not used (a copy)."""
        if self._target is None or self._target[0] is not self.guess:
            self._target = (self.guess, self._target_of(self.guess))
        return self._target[1].copy()

    def _target_of(self, guess: FloatArray) -> FloatArray:
        # only the active rows are converted (the transformation is point by point)
        target = self.work.to_work(guess[self.active])
        target[~self.use_xy[self.active], :2] = np.nan
        target[~self.use_z[self.active], 2] = np.nan
        return target

    def update(self, points: FloatArray, converged: bool) -> FloatArray | None:
        """The control for the next iteration from the adjusted ``points``
        (P, 3, work frame), or None when it stays (settled, given up, or
        waiting for the adjustment to settle)."""
        if self.done:
            return None
        missing = np.isnan(self.given)
        new_guess = self.given.copy()
        # only the rows that lack a coordinate are converted (point by point;
        # on a strip most control rows are full check points)
        rows = np.flatnonzero(missing.any(axis=1))
        if rows.size:
            adjusted = self.work.from_work(points[self.idx[rows]])
            new_guess[rows] = np.where(missing[rows], adjusted, self.given[rows])
        # what the adjustment sees: the used components in the work frame (a
        # plan point's height moves its X, Y there by a share of the distance
        # from the frame's origin over the earth's radius, 1e-3 at 6 km)
        target = self._target_of(new_guess)
        change = float(np.nanmax(np.abs(target - self.target()), initial=0.0))
        if change < PASS_TOLERANCE_M:
            self.guess = new_guess
            self.settled = self.done = True
            return None
        following = change <= 0.5 * self.last_change
        self.last_change = change
        if converged:
            if self.n_pass == self.max_passes:
                self.done = True
                return None
            self.n_pass += 1
        elif not following:
            return None
        self.guess = new_guess
        self._target = (new_guess, target)
        self.last_change = np.inf
        return self.target()
