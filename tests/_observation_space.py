"""An independent reference of the self-calibration's observation equation
(the engine's: :mod:`strip_aerotri.bundle._observation_space`): the true
position ``x̂`` with ``x̂ + Δ(x̂) = x`` by Newton's method with numpy's
general 2 x 2 solver, the residual ``x̂ - x_obs``."""

from __future__ import annotations

import numpy as np

from strip_aerotri.geometry.camera_model import CameraModel


def true_xy(
    model: CameraModel, theta: np.ndarray, computed: np.ndarray, observed: np.ndarray
) -> np.ndarray:
    """``x̂`` (K, 2) by Newton's method from ``observed`` (to rounding)."""
    xhat = np.array(observed, dtype=float)
    for _ in range(8):
        f = xhat + model.correction(xhat, theta) - computed
        jac = np.eye(2) + model.xy_partials(xhat, theta)
        xhat = xhat - np.linalg.solve(jac, f[:, :, None])[:, :, 0]
    return xhat


def residuals(
    model: CameraModel, theta: np.ndarray, computed: np.ndarray, observed: np.ndarray
) -> np.ndarray:
    """``x̂ - x_obs`` (K, 2), mm."""
    out: np.ndarray = true_xy(model, theta, computed, observed) - observed
    return out
