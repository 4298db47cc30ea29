"""Camera parameters as a dense border of the bundle's normal equations (method.md 6B, 6C).

The k self-calibration parameters θ (:mod:`strip_aerotri.geometry.camera_model`)
are shared by every photo, so they couple all unknowns: the normal matrix is

    N = [[U,  W,  Tp],
         [Wᵀ, V,  Tq],
         [Tpᵀ, Tqᵀ, G]]

with U the photo blocks, V the 3 x 3 point blocks, W their couplings, Tp
(M, 6, k) and Tq (P, 3, k) the couplings of photos and points with θ and G
(k, k) the camera's own block.  The points are eliminated first (as without
the border), then the photos by the reduced matrix S's factorisation; what is
left is the k x k Schur complement C = G - Tqᵀ V⁻¹ Tq - Fᵀ S⁻¹ F of the
border, F = Tp - W V⁻¹ Tq, solved densely.  Cost: k more solves with the
factor of S per step.

The observation equation of an image coordinate is ``x(S, R, X) - (x_obs +
Δ(x_obs; θ))``; its design with respect to θ is ``-∂Δ/∂θ``.

Precision: with A the photo-and-point part of N and B its border,
``N⁻¹ = [[A⁻¹ + X C⁻¹ Xᵀ, -X C⁻¹], [-C⁻¹ Xᵀ, C⁻¹]]`` where ``X = A⁻¹ B``:
its photo rows are ``S⁻¹ F`` (at hand from the solution) and its point rows
``V⁻¹ (Tq - Wᵀ S⁻¹ F)``.  So the cofactors of photos and points are those
without the border plus ``X C⁻¹ Xᵀ``, at no further solve.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import GeometryError
from ..geometry.camera_model import CameraModel

if TYPE_CHECKING:
    import scipy.sparse as sp

__all__ = [
    "BorderNormals",
    "BorderStep",
    "CameraUndetermined",
    "border_normals",
    "border_precision",
    "solve_border",
]

#: Relative pivot (of the border's Schur complement scaled to unit diagonal)
#: below which a camera parameter counts as not determined.
_SINGULAR_BORDER = 1e-10


class CameraUndetermined(GeometryError):
    """A camera parameter (``name``; empty when several together) is not determined."""

    def __init__(self, message: str, name: str) -> None:
        super().__init__(message)
        self.name = name


@dataclass(frozen=True)
class BorderNormals:
    """The border's blocks of the whitened normal equations."""

    t_photo: FloatArray  # (M, 6, k)
    t_point: FloatArray  # (P, 3, k)
    g: FloatArray  # (k, k)
    b_camera: FloatArray  # (k,)
    correction_mm: FloatArray  # (K, 2), Δ at the current values


@dataclass(frozen=True)
class BorderStep:
    """A solution of the bordered system and what its precision needs."""

    d_photo: FloatArray  # (M, 6)
    d_camera: FloatArray  # (k,)
    x_photo: FloatArray  # (M, 6, k), S⁻¹ F
    c_inv: FloatArray  # (k, k), cofactor of θ
    c_diag: FloatArray  # (k,), diagonal of the Schur complement C
    g_diag: FloatArray  # (k,), diagonal of G


def border_normals(
    model: CameraModel,
    xy_obs: FloatArray,
    values: FloatArray,
    a_t: FloatArray,
    b_t: FloatArray,
    r: FloatArray,
    inv_s: FloatArray,
    photo_sum: sp.csr_matrix,
    point_sum: sp.csr_matrix,
) -> BorderNormals:
    """The border blocks from the whitened photo and point designs.

    ``a_t`` (K, 6, 2) and ``b_t`` (K, 3, 2) are the transposed whitened
    designs of the image coordinates, ``r`` (K, 2) their whitened residuals
    (computed minus corrected observed), ``inv_s`` (K,) 1/sigma.
    """
    kk, k = xy_obs.shape[0], len(model.estimated)
    jt = -model.partials(xy_obs, values) * inv_s[:, None, None]  # (K, 2, k)
    t_photo = (photo_sum @ (a_t @ jt).reshape(kk, 6 * k)).reshape(-1, 6, k)
    t_point = (point_sum @ (b_t @ jt).reshape(kk, 3 * k)).reshape(-1, 3, k)
    g = np.einsum("nai,naj->ij", jt, jt)
    b_camera = -np.einsum("nai,na->i", jt, r)
    return BorderNormals(t_photo, t_point, g, b_camera, model.correction(xy_obs, values))


def solve_border(
    border: BorderNormals,
    solve_s: Callable[[FloatArray], FloatArray],
    y: FloatArray,
    v_inv: FloatArray,
    point: IntArray,
    photo_sum: sp.csr_matrix,
    rhs_photo: FloatArray,
    b_point: FloatArray,
    lam: float,
    names: tuple[str, ...],
) -> BorderStep:
    """Eliminate the photos (``solve_s`` applies S⁻¹ to (6M,) or (6M, n)), solve the border.

    ``y`` (K, 6, 3) is ``W V⁻¹`` per observation, ``rhs_photo`` (M, 6) the
    right-hand side reduced by the points, ``b_point`` (P, 3) the points' own.
    Raises GeometryError naming a camera parameter the data do not determine.
    """
    m, k = rhs_photo.shape[0], border.g.shape[0]
    t_point = border.t_point
    vt = v_inv @ t_point  # (P, 3, k)
    f = border.t_photo - (photo_sum @ (y @ t_point[point]).reshape(-1, 6 * k)).reshape(m, 6, k)
    g = border.g.copy()
    g_diag = np.diag(border.g).copy()
    if lam > 0.0:
        g[np.diag_indices(k)] *= 1.0 + lam
    g_red = g - np.einsum("pai,paj->ij", t_point, vt)
    rhs_c = border.b_camera - np.einsum("pai,pa->i", vt, b_point)
    f_flat = f.reshape(6 * m, k)
    x = solve_s(f_flat)
    z = solve_s(rhs_photo.ravel())
    c = g_red - f_flat.T @ x
    c = 0.5 * (c + c.T)
    c_diag = np.diag(c).copy()
    _check_border(c, c_diag, g_diag, names)
    c_inv = np.linalg.inv(c)
    d_camera = c_inv @ (rhs_c - f_flat.T @ z)
    d_photo = (z - x @ d_camera).reshape(m, 6)
    return BorderStep(d_photo, d_camera, x.reshape(m, 6, k), c_inv, c_diag, g_diag)


def _check_border(
    c: FloatArray, c_diag: FloatArray, g_diag: FloatArray, names: tuple[str, ...]
) -> None:
    """GeometryError when a camera parameter is not determined by the data."""
    weak = ~(c_diag > _SINGULAR_BORDER * np.maximum(g_diag, 1e-300))
    if np.any(weak):
        j = int(np.flatnonzero(weak)[0])
        raise CameraUndetermined(
            f"the camera parameter {names[j]} is not determined: the exterior orientation "
            "absorbs it entirely (e.g. c with the flying height over flat ground, x0 and y0 "
            'with the centres); leave it out of self_calibration or use "auto"',
            names[j],
        )
    scale = 1.0 / np.sqrt(c_diag)
    ev = np.linalg.eigvalsh(c * scale[:, None] * scale[None, :])
    if not ev[0] > _SINGULAR_BORDER:
        raise CameraUndetermined(
            "the camera parameters "
            + ", ".join(names)
            + " are not determined together (they are nearly linearly dependent); "
            'estimate fewer of them or use "auto"',
            "",
        )


def border_precision(
    step: BorderStep,
    v_inv: FloatArray,
    t_point: FloatArray,
    w: FloatArray,
    photo: IntArray,
    point_sum: sp.csr_matrix,
) -> tuple[FloatArray, FloatArray]:
    """What the border adds to the cofactors: photo blocks (M, 6, 6) and point diagonals (P, 3).

    ``w`` (K, 6, 3) are the photo-point couplings per observation.
    """
    k = step.c_inv.shape[0]
    xp = step.x_photo
    w_t = np.swapaxes(w, 1, 2)  # (K, 3, 6)
    coupling = (point_sum @ (w_t @ xp[photo]).reshape(-1, 3 * k)).reshape(-1, 3, k)
    xq = v_inv @ (t_point - coupling)  # (P, 3, k)
    add_photo = xp @ step.c_inv @ np.swapaxes(xp, 1, 2)
    add_point = np.einsum("pai,ij,paj->pa", xq, step.c_inv, xq)
    return add_photo, add_point
