"""An independent reference of the self-calibration's observation equation
(the engine's: :mod:`strip_aerotri.bundle._observation_space`): the true
position ``x̂`` with ``x̂ + Δ(x̂) = x`` by Newton's method with numpy's
general 2 x 2 solver, the residual ``x̂ - x_obs``; with a rolling shutter
the row each ray is read at is x̂'s, found by a fixed point on it."""

from __future__ import annotations

from collections.abc import Callable

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


def rows_read(
    project_at: Callable[[np.ndarray], np.ndarray],
    fractions: Callable[[np.ndarray], np.ndarray],
    model: CameraModel | None,
    theta: np.ndarray,
    observed: np.ndarray,
) -> np.ndarray:
    """``x̂`` (K, 2) of a rolling shutter that reads each ray at its true
    position's row: ``x̂ + Δ(x̂) = x(s(x̂))``, by the fixed point on the
    fraction (each turn projects exactly at ``s(x̂)`` with ``project_at``,
    then solves for x̂ as :func:`true_xy`; it contracts by ``|u aᵀ|``, 1e-3
    and less), from ``observed``."""
    xhat = np.array(observed, dtype=float)
    for _ in range(12):
        computed = project_at(fractions(xhat))
        xhat = computed if model is None else true_xy(model, theta, computed, xhat)
    return xhat
