"""The attitude observations' residual on SO(3) and its Jacobian, for the
bundle's IMU rows (:mod:`strip_aerotri.bundle.adjust`)."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray
from ..geometry.rotation import rotvec_from_matrix, skew

__all__ = ["imu_residual", "right_jacobian_inv"]


def right_jacobian_inv(e: FloatArray) -> FloatArray:
    """Inverse right Jacobian of SO(3), ``log(exp(e) exp(d)) = e + Jr^-1(e) d + O(d^2)``."""
    theta = np.linalg.norm(e, axis=-1)
    small = theta < 1e-4
    t = np.where(small, 1.0, theta)
    coef = np.where(
        small,
        1.0 / 12.0 + theta**2 / 720.0,
        1.0 / t**2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)),
    )
    k = skew(e)
    return np.eye(3) + 0.5 * k + coef[..., None, None] * (k @ k)


def imu_residual(rotations: FloatArray, imu_rotations: FloatArray) -> FloatArray:
    """Attitude residuals ``e = log(R_imu.T @ R)``, shape (M, 3), radians.

    Their Jacobian with respect to ``delta`` is ``right_jacobian_inv(e)``.
    """
    return rotvec_from_matrix(np.einsum("mji,mjk->mik", imu_rotations, rotations))
