"""A self-calibrated c against simulated truth (benchmarks/bench_selfcal_c_pull.py's
drone blocks: c 0.05 mm off, GNSS centres): no pull, and the same c as the
reference bundle's re-solve with the residuals in the observations' space."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_selfcal_c_pull as pull  # noqa: E402


def test_c_is_not_pulled_and_equals_the_reference() -> None:
    """Over eight seeds of 3 x 8 photos (redundancy about 2150, sd(c) 0.00047
    mm), c's mean error is within one of its standard deviations of the truth
    (it was +1.8 sd with the residuals of the corrected observations, as
    ``sd(c) r / c`` predicts); each seed's c equals the scipy reference's
    re-solve with ``(I + ∂Δ/∂x)⁻¹``-mapped residuals (exact for c alone) to
    1e-6 of its increment."""
    rows = np.array([pull.one_block(8, seed) for seed in range(8)])
    error, reference_error, sd = rows[:, 0], rows[:, 1], rows[:, 2]
    z = error / sd
    assert abs(float(np.mean(z))) < 1.0, z
    increment = error + pull.ERROR_C_MM
    np.testing.assert_allclose(
        error, reference_error, rtol=0, atol=1e-6 * float(np.min(increment))
    )
