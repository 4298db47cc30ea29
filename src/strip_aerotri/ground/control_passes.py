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

#: The guessed coordinates have settled when no coordinate moves more (m).
PASS_TOLERANCE_M = 1e-5


class ControlPasses:
    """The control of the active rows as the adjustment goes.

    After every iteration the missing coordinates are taken from the
    adjusted points; the control follows the iterations while these changes
    at least halve from one to the next (the two converge together), else
    it waits for the adjustment to settle on it, which ends a *pass*.  After
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

    @property
    def guessed(self) -> bool:
        """True when a used control point lacks a coordinate."""
        return bool(np.isnan(self.given[self.active]).any())

    def target(self) -> FloatArray:
        """Work-frame control of the active rows, NaN where not used."""
        target = self.work.to_work(self.guess)
        target[~self.use_xy, :2] = np.nan
        target[~self.use_z, 2] = np.nan
        return target[self.active]

    def update(self, points: FloatArray, converged: bool) -> FloatArray | None:
        """The control for the next iteration from the adjusted ``points``
        (P, 3, work frame), or None when it stays (settled, given up, or
        waiting for the adjustment to settle)."""
        if self.done:
            return None
        adjusted = self.work.from_work(points[self.idx])
        missing = np.isnan(self.given)
        new_guess = self.given.copy()
        new_guess[missing] = adjusted[missing]
        change = float(np.nanmax(np.abs(new_guess - self.guess), initial=0.0))
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
        self.last_change = np.inf
        return self.target()
