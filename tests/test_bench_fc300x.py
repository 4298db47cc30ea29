"""The FC300X split benchmark's RMSE differences and their bootstrap sd."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from bench_fc300x_splits import rmse_difference  # noqa: E402


def test_equal_residuals_differ_by_nothing() -> None:
    r = np.random.default_rng(1).normal(0, 0.02, (13, 3))
    assert np.allclose(rmse_difference(r, r), 0.0)


def test_difference_and_its_spread() -> None:
    """A uniform 10 % growth of every residual raises each RMSE by 10 %; the
    bootstrap sd is that of the RMSE difference over resampled points (about
    10 % of the RMSE's own bootstrap sd), and points with NaN are left out."""
    rng = np.random.default_rng(2)
    a = rng.normal(0, 0.02, (200, 3))
    b = 1.1 * a
    a_nan = np.vstack([a, [[np.nan, 0.0, 0.0]]])
    b_nan = np.vstack([b, [[1.0, 1.0, 1.0]]])
    d = rmse_difference(a_nan, b_nan, draws=4000)
    rmse = np.array([np.sqrt(np.mean(np.sum(a[:, :2] ** 2, 1))), np.sqrt(np.mean(a[:, 2] ** 2))])
    assert np.allclose(d[0], 0.1 * rmse)
    pick = np.random.default_rng(0).integers(0, 200, (4000, 200))
    own = np.sqrt(np.mean(a[pick, 2] ** 2, axis=1)).std()
    assert abs(d[1, 1] / (0.1 * own) - 1.0) < 0.05
