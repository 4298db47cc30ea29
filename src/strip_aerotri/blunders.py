"""Gross-error detection: data snooping at every stage of the strip (method.md §7).

J's programs listed the residuals above a limit after each stage and let the
operator drop an equation and recompute.  This module does the same
automatically and reproducibly:

* **Test statistic.**  Baarda's w-test, ``w = v / (σ sqrt(r))`` with the
  observation's a priori standard deviation σ and its redundancy number r
  (the diagonal of ``I − A (AᵀPA)⁻¹ AᵀP``).  If the data are noisier than
  declared, σ is inflated by the robust variance factor
  ``(1.4826 · median |w|)²`` of the stage when that exceeds 1, so that a
  misjudged σ does not make good observations fail.
* **Critical value.**  Per stage, the family-wise false-alarm probability
  ``alpha`` (default 0.001) is shared over its n tests (Bonferroni):
  ``k = Φ⁻¹(1 − alpha / (2 n))``; about 3.3 for one test, 4.6 for 1000 tests,
  5.3 for 100 000.  A stage's value can be set directly.
* **One at a time.**  The largest |w| above k is rejected (per pair for the
  relative orientation, which solves pairs independently), the stage is
  solved again, and so on until none fails.
* **Report.**  Every rejection is a :class:`Rejection` with stage, photos,
  point, residual, test value, critical value and the change it made.

Stages: ``relative_orientation`` (y-parallaxes), ``tie_points``
(differences between the determinations of a point in consecutive models),
``models`` (a point's determination in a model against the adjusted point,
when the models are transformed at once: a 3-D test, chi-square with three
degrees of freedom),
``control`` (control deviations after the similarity and polynomial fit, and
in the bundle refinement), ``straight_line`` (line points), and in the bundle
refinement (:mod:`strip_aerotri.bundle.refine`) ``bundle`` (image coordinates),
``gnss`` (GNSS projection centres, tested along east, north, up, rejected as
a whole) and ``imu`` (IMU attitudes, tested about the image axes, rejected as
a whole).  The bundle refinement takes the single largest ``|w| / critical``
over its four stages in each round.
"""

from __future__ import annotations

import numpy as np

from ._stats import critical_value, sample_median
from ._typing import FloatArray
from .options import STAGES, BlunderOptions

__all__ = [
    "STAGES",
    "BlunderOptions",
    "critical_value",
    "robust_variance_factor",
]


def robust_variance_factor(w: FloatArray) -> float:
    """Variance factor of w statistics from their median absolute value, at least 1.

    For standard normal w, ``1.4826 · median |w|`` estimates 1; a larger
    value says the a priori sigmas were too optimistic.  Blunders barely move
    the median, so the estimate stays close to the noise level.
    """
    w = np.asarray(w, dtype=np.float64)
    w = w[np.isfinite(w)]
    if w.size < 5:
        return 1.0
    return max(1.0, (1.4826 * sample_median(np.abs(w))) ** 2)
