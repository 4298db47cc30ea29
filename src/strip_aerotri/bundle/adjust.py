"""Rigorous bundle adjustment of a strip by the collinearity equations.

The optional final step after the strip method: the photos' exterior
orientation and the ground coordinates of all points found by partially
dependent models serve as initial values of a least-squares adjustment of all
image coordinates at once, with ground control, GNSS projection centres and
IMU attitudes entering as weighted observations.  The adjustment works in a
local Cartesian frame in metres (the local-tangent frame of the geocentric
route, method.md section 6.2).

Model (conventions of method.md section 2): the image vector of an
observation is ``(x, y, -c)``; a photo's rotation ``R`` maps image vectors to
the frame, so with ``v = R.T @ (X - S)``

    x = -c v_x / v_z,        y = -c v_y / v_z.

Unknowns per photo are a shift of the centre ``dS`` (m) and a small rotation
``delta`` (rad) applied on the right, ``R <- R @ exp([delta]x)``, i.e. about
the axes of the photo's own image system; three per point.  The normal
equations are reduced to the photos by the Schur complement on the 3 x 3
point blocks; the reduced system (6M x 6M, banded for a strip) is solved by a
sparse LU factorisation.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import ConvergenceError, GeometryError, StripAerotriWarning
from ..geometry.camera_model import CameraModel
from ..geometry.collinearity import collinearity_jacobians, project
from ..geometry.rotation import matrix_from_rotvec, rotvec_from_matrix, skew
from ..observations import ImageObservations
from ..options import DEFAULT_MAX_ITERATIONS
from ..results import BundleResult, CameraEstimate
from .border import BorderNormals, BorderStep, border_normals, border_precision, solve_border

if TYPE_CHECKING:
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

__all__ = ["BundleResult", "bundle_adjust"]

#: Relative pivot (of the Jacobi-scaled reduced matrix, whose diagonal is 1)
#: below which the reduced normal matrix is taken as singular.
_SINGULAR_PIVOT = 1e-11
#: Relative pivot below which a near-singular reduced matrix is warned about.
_WEAK_PIVOT = 1e-8
#: Ratio of smallest to largest singular value of the datum matrix (unit
#: weights, coordinates reduced to the centroid and scaled by the net's size)
#: below which a similarity degree of freedom counts as free.
_DATUM_RANK_TOL = 1e-9
#: Ratio of smallest to largest eigenvalue of a point's 3 x 3 normal block
#: below which the point counts as undetermined (e.g. seen on one photo only).
_POINT_RANK_TOL = 1e-10
#: Largest number of float64 entries of one block of unit-vector solves.
_SOLVE_CHUNK = 4_000_000

_MOTION_NAMES = (
    "shift along X",
    "shift along Y",
    "shift along Z",
    "rotation about X",
    "rotation about Y",
    "rotation about Z",
    "scale",
)
_PHOTO_PARAMETER_NAMES = (
    "X0",
    "Y0",
    "Z0",
    "rotation about x",
    "rotation about y",
    "rotation about z",
)


# ----------------------------------------------------------------------------
# SO(3) kernels
# ----------------------------------------------------------------------------


def _right_jacobian_inv(e: FloatArray) -> FloatArray:
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


# ----------------------------------------------------------------------------
# Observation equations
# ----------------------------------------------------------------------------


def _imu_residual(rotations: FloatArray, imu_rotations: FloatArray) -> FloatArray:
    """Attitude residuals ``e = log(R_imu.T @ R)``, shape (M, 3), radians.

    Their Jacobian with respect to ``delta`` is ``_right_jacobian_inv(e)``.
    """
    return rotvec_from_matrix(np.einsum("mji,mjk->mik", imu_rotations, rotations))


# ----------------------------------------------------------------------------
# Problem data
# ----------------------------------------------------------------------------


@dataclass(frozen=True)
class _Problem:
    photo_ids: tuple[str, ...]
    photo: IntArray
    point: IntArray
    xy: FloatArray
    sigma: FloatArray
    c: float
    n_photos: int
    n_points: int
    control_xyz: FloatArray  # (P, 3), 0 where unused
    control_weight: FloatArray  # (P, 3), 0 where unused
    gnss_xyz: FloatArray
    gnss_weight: FloatArray
    imu_rot: FloatArray  # (M, 3, 3), identity where unused
    imu_weight: FloatArray  # (M, 3), 0 where unused
    photo_sum: sp.csr_matrix  # (M, K) incidence
    point_sum: sp.csr_matrix  # (P, K) incidence
    pair_k1: IntArray  # observation pairs on the same point
    pair_k2: IntArray
    pair_point_sum: sp.csr_matrix  # (P, n_pairs)
    # CSC pattern of the reduced matrix; entry j of the COO list (photo blocks,
    # then observation pairs) adds into data[slot[j]].
    slot: IntArray
    indices: IntArray
    indptr: IntArray
    entry_col: IntArray  # column of each CSC entry
    camera: CameraModel | None = None  # self-calibration: the border's parameters

    @property
    def n_camera(self) -> int:
        return 0 if self.camera is None else len(self.camera.estimated)

    @property
    def n_observations(self) -> int:
        return int(
            2 * self.photo.size
            + np.count_nonzero(self.control_weight)
            + np.count_nonzero(self.gnss_weight)
            + np.count_nonzero(self.imu_weight)
        )


def _incidence(index: IntArray, n: int) -> sp.csr_matrix:
    import scipy.sparse as sp

    k = index.size
    return sp.csr_matrix((np.ones(k), (index, np.arange(k))), shape=(n, k))


def _observation_pairs(point: IntArray, n_points: int) -> tuple[IntArray, IntArray]:
    """All ordered pairs (k1, k2) of observations of the same point (k1 == k2 included)."""
    order = np.argsort(point, kind="stable")
    counts = np.bincount(point, minlength=n_points)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    per_obs = counts[point[order]]  # partners of each sorted observation
    first = np.repeat(np.arange(order.size), per_obs)
    group_start = np.repeat(np.cumsum(per_obs) - per_obs, per_obs)
    offset = np.arange(first.size) - group_start
    second = starts[point[order][first]] + offset
    return order[first], order[second]


def _block_pattern(a: IntArray, b: IntArray) -> tuple[IntArray, IntArray]:
    """Row and column indices (n, 6, 6) of the 6 x 6 blocks (a, b) of a 6M x 6M matrix."""
    blk = np.arange(6)
    rows = 6 * a[:, None, None] + blk[None, :, None]
    cols = 6 * b[:, None, None] + blk[None, None, :]
    rows, cols = np.broadcast_arrays(rows, cols)
    return rows, cols


def observed_with_sigma(
    values: ArrayLike,
    sigma: ArrayLike | None,
    shape: tuple[int, ...],
    name: str,
    sigma_name: str,
) -> tuple[FloatArray, FloatArray]:
    """Observations of ``shape`` (NaN where absent) and their standard
    deviations, broadcast to (shape[0], 3): three per point or photo (the
    coordinates of a point or centre, the angles of an attitude); `name` and
    `sigma_name` are the arguments' names for the messages."""
    vals = np.asarray(values, dtype=np.float64)
    if vals.shape != shape:
        raise ValueError(f"Expected `{name}` to have shape {shape}, got {vals.shape}")
    if sigma is None:
        raise ValueError(f"`{name}` given without its standard deviations (`{sigma_name}`)")
    return vals, np.broadcast_to(np.asarray(sigma, dtype=np.float64), (shape[0], 3))


def _weights(
    values: ArrayLike | None,
    sigma: ArrayLike | None,
    shape: tuple[int, ...],
    name: str,
    sigma_name: str,
) -> tuple[FloatArray, FloatArray]:
    """Given values with NaN where absent and their sigmas -> (values 0-filled, weights)."""
    if values is None:
        return np.zeros(shape), np.zeros(shape)
    vals, sig = observed_with_sigma(values, sigma, shape, name, sigma_name)
    used = np.isfinite(vals) & np.isfinite(sig)
    if np.any(sig[used] <= 0.0):
        raise ValueError(f"Expected positive standard deviations for `{name}`")
    weight = np.zeros(shape)
    weight[used] = 1.0 / sig[used] ** 2
    return np.where(used, vals, 0.0), weight


def _check_rotations(rotations: FloatArray, name: str) -> None:
    err = np.abs(np.einsum("...ji,...jk->...ik", rotations, rotations) - np.eye(3))
    bad = ~np.all(err < 1e-6, axis=(-2, -1)) | ~(np.linalg.det(rotations) > 0.0)
    if np.any(bad):
        raise ValueError(
            f"Expected `{name}` to hold proper rotation matrices, "
            f"entry {int(np.flatnonzero(bad)[0])} is not"
        )


def _make_problem(
    obs: ImageObservations,
    centres: FloatArray,
    rotations: FloatArray,
    points: FloatArray,
    control_xyz: ArrayLike | None,
    control_sigma: ArrayLike | None,
    gnss_centres: ArrayLike | None,
    gnss_sigma: ArrayLike | None,
    imu_rotations: ArrayLike | None,
    imu_sigma: ArrayLike | None,
) -> _Problem:
    m, p = centres.shape[0], points.shape[0]
    photo = np.asarray(obs.photo, dtype=np.intp)
    point = np.asarray(obs.point, dtype=np.intp)
    xy = np.asarray(obs.xy, dtype=np.float64)
    k = photo.size
    sigma = np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), (k,))
    if point.shape != (k,) or xy.shape != (k, 2):
        raise ValueError(
            f"Expected observations with photo (K,), point (K,), xy (K, 2); got "
            f"{photo.shape}, {point.shape}, {xy.shape}"
        )
    if k and (photo.min() < 0 or photo.max() >= m or point.min() < 0 or point.max() >= p):
        raise ValueError("Observation indices out of range of `centres0` / `points0`")
    if not (np.all(np.isfinite(xy)) and np.all(np.isfinite(sigma)) and np.all(sigma > 0)):
        raise ValueError("Expected finite image coordinates and positive finite sigma")
    c = float(obs.principal_distance)
    if not (np.isfinite(c) and c > 0.0):
        raise ValueError(f"Expected a positive principal distance, got {c}")
    cxyz, cw = _weights(control_xyz, control_sigma, (p, 3), "control_xyz", "control_sigma")
    gxyz, gw = _weights(gnss_centres, gnss_sigma, (m, 3), "gnss_centres", "gnss_sigma")
    if imu_rotations is None:
        imu = np.broadcast_to(np.eye(3), (m, 3, 3)).copy()
        iw = np.zeros((m, 3))
    else:
        imu, sig = observed_with_sigma(
            imu_rotations, imu_sigma, (m, 3, 3), "imu_rotations", "imu_sigma"
        )
        present = np.all(np.isfinite(imu), axis=(1, 2))
        imu = np.where(present[:, None, None], imu, np.eye(3))
        _check_rotations(imu, "imu_rotations")
        used = present[:, None] & np.isfinite(sig)
        if np.any(sig[used] <= 0.0):
            raise ValueError("Expected positive standard deviations for `imu_rotations`")
        iw = np.zeros((m, 3))
        iw[used] = 1.0 / sig[used] ** 2
    k1, k2 = _observation_pairs(point, p)
    rows_u, cols_u = _block_pattern(np.arange(m), np.arange(m))
    rows_p, cols_p = _block_pattern(photo[k1], photo[k2])
    n = 6 * m
    keys = np.concatenate([cols_u.ravel(), cols_p.ravel()]) * n + np.concatenate(
        [rows_u.ravel(), rows_p.ravel()]
    )
    unique_keys, slot = np.unique(keys, return_inverse=True)
    entry_col = unique_keys // n
    indices = unique_keys % n
    indptr = np.searchsorted(entry_col, np.arange(n + 1)).astype(np.intp)
    return _Problem(
        photo_ids=tuple(obs.photo_ids),
        photo=photo,
        point=point,
        xy=xy,
        sigma=np.array(sigma),
        c=c,
        n_photos=m,
        n_points=p,
        control_xyz=cxyz,
        control_weight=cw,
        gnss_xyz=gxyz,
        gnss_weight=gw,
        imu_rot=imu,
        imu_weight=iw,
        photo_sum=_incidence(photo, m),
        point_sum=_incidence(point, p),
        pair_k1=k1,
        pair_k2=k2,
        pair_point_sum=_incidence(point[k1], p),
        slot=slot,
        indices=indices,
        indptr=indptr,
        entry_col=entry_col,
    )


# ----------------------------------------------------------------------------
# Normal equations
# ----------------------------------------------------------------------------


@dataclass(frozen=True)
class _State:
    centres: FloatArray
    rotations: FloatArray
    points: FloatArray
    camera: FloatArray = field(default_factory=lambda: np.zeros(0))  # (k,) increments


@dataclass(frozen=True)
class _Normals:
    """Whitened normal equations ``N d = b`` split into photo and point blocks."""

    u: FloatArray  # (M, 6, 6)
    v: FloatArray  # (P, 3, 3)
    w: FloatArray  # (K, 6, 3), one block per observation
    b_photo: FloatArray  # (M, 6)
    b_point: FloatArray  # (P, 3)
    cost: float
    residuals_mm: FloatArray  # (K, 2), computed - observed (corrected by the camera)
    border: BorderNormals | None = None


@dataclass(frozen=True)
class _Reduced:
    d_photo: FloatArray  # (M, 6)
    d_point: FloatArray  # (P, 3)
    lu: spla.SuperLU
    scale: FloatArray  # (6M,) Jacobi scale, S^-1 = D Stilde^-1 D
    v_inv: FloatArray  # (P, 3, 3)
    y: FloatArray  # (K, 6, 3), W_k V_p^-1
    min_pivot: float
    min_pivot_index: int
    border: BorderStep | None = None


def _cost(prob: _Problem, state: _State) -> float:
    """Weighted sum of squared residuals; inf when a point lies behind a photo."""
    xy, v = project(state.centres, state.rotations, state.points, prob.photo, prob.point, prob.c)
    if not np.all(v[:, 2] < 0.0) or not np.all(np.isfinite(xy)):
        return float("inf")
    e_img = (xy - _observed(prob, state)) / prob.sigma[:, None]
    e_ctrl = state.points - prob.control_xyz
    e_gnss = state.centres - prob.gnss_xyz
    e_imu = _imu_residual(state.rotations, prob.imu_rot)
    return float(
        np.sum(e_img**2)
        + np.sum(prob.control_weight * e_ctrl**2)
        + np.sum(prob.gnss_weight * e_gnss**2)
        + np.sum(prob.imu_weight * e_imu**2)
    )


def _observed(prob: _Problem, state: _State) -> FloatArray:
    """The image observations corrected by the camera's parameters (mm)."""
    if prob.camera is None:
        return prob.xy
    out: FloatArray = prob.xy + prob.camera.correction(prob.xy, state.camera)
    return out


def _normals(prob: _Problem, state: _State) -> _Normals:
    """Linearise all observation equations at ``state`` and form the normal blocks."""
    m, p, k = prob.n_photos, prob.n_points, prob.photo.size
    xy, _, jac_photo, jac_point = collinearity_jacobians(
        state.centres, state.rotations, state.points, prob.photo, prob.point, prob.c
    )
    res = xy - _observed(prob, state)
    inv_s = 1.0 / prob.sigma
    r = res * inv_s[:, None]
    a = jac_photo * inv_s[:, None, None]
    b = jac_point * inv_s[:, None, None]
    a_t = np.swapaxes(a, 1, 2)
    b_t = np.swapaxes(b, 1, 2)
    u = (prob.photo_sum @ (a_t @ a).reshape(k, 36)).reshape(m, 6, 6)
    v = (prob.point_sum @ (b_t @ b).reshape(k, 9)).reshape(p, 3, 3)
    w = a_t @ b
    b_photo = -(prob.photo_sum @ (a_t @ r[:, :, None])[:, :, 0])
    b_point = -(prob.point_sum @ (b_t @ r[:, :, None])[:, :, 0])
    # Control: X - X_c (m), design = identity.
    e_ctrl = state.points - prob.control_xyz
    idx3 = np.arange(3)
    v[:, idx3, idx3] += prob.control_weight
    b_point -= prob.control_weight * e_ctrl
    # GNSS centres: S - S_g (m).
    e_gnss = state.centres - prob.gnss_xyz
    u[:, idx3, idx3] += prob.gnss_weight
    b_photo[:, :3] -= prob.gnss_weight * e_gnss
    # IMU attitudes: log(R_imu.T R) (rad), design Jr^-1(e).
    e_imu = _imu_residual(state.rotations, prob.imu_rot)
    j_imu = _right_jacobian_inv(e_imu)
    wj = prob.imu_weight[:, :, None] * j_imu
    u[:, 3:, 3:] += np.einsum("mai,maj->mij", j_imu, wj)
    b_photo[:, 3:] -= np.einsum("mai,ma->mi", wj, e_imu)
    cost = float(
        np.sum(r**2)
        + np.sum(prob.control_weight * e_ctrl**2)
        + np.sum(prob.gnss_weight * e_gnss**2)
        + np.sum(prob.imu_weight * e_imu**2)
    )
    border = None
    if prob.camera is not None:
        border = border_normals(
            prob.camera, prob.xy, state.camera, a_t, b_t, r, inv_s, prob.photo_sum, prob.point_sum
        )
    return _Normals(u, v, w, b_photo, b_point, cost, res, border)


def _check_points(prob: _Problem, normals: _Normals, point_ids: tuple[str, ...]) -> None:
    """Raise GeometryError for points whose 3 x 3 normal block is (near) singular."""
    ev = np.linalg.eigvalsh(normals.v)
    bad = ~(ev[:, 0] > _POINT_RANK_TOL * ev[:, 2])
    if np.any(bad):
        n_rays = np.bincount(prob.point, minlength=prob.n_points)
        idx = np.flatnonzero(bad)
        listed = ", ".join(f"'{point_ids[i]}' ({n_rays[i]} photo(s))" for i in idx[:5])
        more = f" and {idx.size - 5} more" if idx.size > 5 else ""
        raise GeometryError(
            f"{idx.size} point(s) cannot be determined: {listed}{more}; a point needs "
            "rays from two photos, or one ray and control that fixes it"
        )


def _solve(prob: _Problem, normals: _Normals, lam: float) -> _Reduced:
    """Reduce to the photos (Schur complement on the point blocks), solve, back-substitute.

    ``lam`` is the Levenberg-Marquardt factor: the diagonals of U and V are
    multiplied by ``1 + lam``.
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    m = prob.n_photos
    u, v = normals.u, normals.v
    if lam > 0.0:
        i6, i3 = np.arange(6), np.arange(3)
        u = u.copy()
        v = v.copy()
        u[:, i6, i6] *= 1.0 + lam
        v[:, i3, i3] *= 1.0 + lam
    # float64 in, float64 out (the stubs say floating)
    v_inv: FloatArray = np.linalg.inv(v)  # type: ignore[assignment]
    y = normals.w @ v_inv[prob.point]
    pair_blocks = y[prob.pair_k1] @ np.swapaxes(normals.w[prob.pair_k2], 1, 2)
    entries = np.concatenate([u.ravel(), -pair_blocks.ravel()])
    data = np.bincount(prob.slot, weights=entries, minlength=prob.indices.size)
    rhs = normals.b_photo - prob.photo_sum @ (y @ normals.b_point[prob.point][:, :, None])[:, :, 0]
    is_diag = prob.indices == prob.entry_col
    diag = np.zeros(6 * m)
    diag[prob.indices[is_diag]] = data[is_diag]
    if not np.all(diag > 0.0):
        j = int(np.flatnonzero(~(diag > 0.0))[0])
        raise GeometryError(
            f"photo '{prob.photo_ids[j // 6]}' is not determined: no observation constrains its "
            f"{_PHOTO_PARAMETER_NAMES[j % 6]}"
        )
    scale = 1.0 / np.sqrt(diag)
    s_tilde = sp.csc_matrix(
        (data * scale[prob.indices] * scale[prob.entry_col], prob.indices, prob.indptr),
        shape=(6 * m, 6 * m),
    )
    try:
        lu = spla.splu(
            s_tilde,
            permc_spec="MMD_AT_PLUS_A",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise GeometryError(
            "the reduced normal matrix is singular: the datum or a photo's orientation is "
            "not determined by the observations"
        ) from exc
    pivots = np.abs(lu.U.diagonal())[lu.perm_c]
    j = int(np.argmin(pivots))
    border_step = None
    if normals.border is None or prob.camera is None:
        d_photo = (scale * lu.solve(scale * rhs.ravel())).reshape(m, 6)
    else:

        def solve_s(b: FloatArray) -> FloatArray:
            d = scale if b.ndim == 1 else scale[:, None]
            out: FloatArray = d * lu.solve(d * b)
            return out

        border_step = solve_border(
            normals.border,
            solve_s,
            y,
            v_inv,
            prob.point,
            prob.photo_sum,
            rhs,
            normals.b_point,
            lam,
            prob.camera.estimated,
        )
        d_photo = border_step.d_photo
    t = (
        normals.b_point
        - prob.point_sum
        @ (np.swapaxes(normals.w, 1, 2) @ d_photo[prob.photo][:, :, None])[:, :, 0]
    )
    if border_step is not None and normals.border is not None:
        t = t - normals.border.t_point @ border_step.d_camera
    d_point = (v_inv @ t[:, :, None])[:, :, 0]
    return _Reduced(d_photo, d_point, lu, scale, v_inv, y, float(pivots[j]), j, border_step)


def _apply(state: _State, step: _Reduced) -> _State:
    return _State(
        centres=state.centres + step.d_photo[:, :3],
        rotations=state.rotations @ matrix_from_rotvec(step.d_photo[:, 3:]),
        points=state.points + step.d_point,
        camera=state.camera if step.border is None else state.camera + step.border.d_camera,
    )


# ----------------------------------------------------------------------------
# Datum
# ----------------------------------------------------------------------------


def _free_motions(prob: _Problem, state: _State) -> list[str]:
    """Describe the similarity degrees of freedom left free by control, GNSS and IMU.

    The 7 infinitesimal similarity motions of the whole net (shifts, rotations
    about the frame axes through the centroid, scale; coordinates scaled by
    the net's size) are applied to the observed quantities; the rank of that
    n x 7 matrix (unit weights) tells which motions the observations fix.
    """
    ref = np.concatenate([state.points, state.centres])
    x0 = ref.mean(axis=0)
    size = float(np.sqrt(np.mean(np.sum((ref - x0) ** 2, axis=1)))) or 1.0

    def motion_rows(xyz: FloatArray) -> FloatArray:
        q = (xyz - x0) / size
        g = np.zeros((xyz.shape[0], 3, 7))
        g[:, :, :3] = np.eye(3)
        g[:, :, 3:6] = -skew(q)  # d(omega x q)/d(omega)
        g[:, :, 6] = q
        return g

    g_imu = np.zeros((prob.n_photos, 3, 7))
    g_imu[:, :, 3:6] = np.swapaxes(state.rotations, 1, 2)  # e -> e + R.T omega
    g = np.concatenate(
        [
            motion_rows(state.points)[prob.control_weight > 0],
            motion_rows(state.centres)[prob.gnss_weight > 0],
            g_imu[prob.imu_weight > 0],
        ]
    )
    if g.shape[0] == 0:
        return list(_MOTION_NAMES)
    r_factor = np.zeros((7, 7))
    # same singular values, at most 7 x 7; mode "r" gives R alone (the stubs say QRResult)
    r_part: FloatArray = np.linalg.qr(g, mode="r")  # type: ignore[assignment]
    r_factor[: r_part.shape[0]] = r_part
    _, sv, vt = np.linalg.svd(r_factor)
    rank = int(np.count_nonzero(sv > _DATUM_RANK_TOL * sv[0]))
    null = vt[rank:]  # (7 - rank, 7) orthonormal basis of the free motions
    if null.shape[0] == 0:
        return []
    share = np.sum(null**2, axis=0)  # squared length of each motion in the null space
    whole = share > 1.0 - 1e-6
    free = [_MOTION_NAMES[i] for i in np.flatnonzero(whole)]
    rest = null.shape[0] - len(free)
    if rest > 0:
        parts = [_MOTION_NAMES[i] for i in np.flatnonzero(~whole & (share > 1e-3))]
        free.append(f"{rest} combination(s) of {', '.join(parts)}")
    return free


# ----------------------------------------------------------------------------
# Precision
# ----------------------------------------------------------------------------


def _photo_covariance_blocks(
    prob: _Problem, red: _Reduced, a: IntArray, b: IntArray
) -> FloatArray:
    """Blocks ``(a, b)`` of ``S^-1`` (6 x 6 each), by sparse LU solves with unit vectors.

    Columns of ``S^-1`` are found for the photos in chunks of at most
    ``_SOLVE_CHUNK / (6 M)`` unit vectors; cost ``6 M`` triangular solves
    with the LU factors (O(M * bandwidth^2) each for a strip) and
    ``O(M * chunk)`` memory.
    """
    m = prob.n_photos
    n = 6 * m
    out = np.empty((a.size, 6, 6))
    per_chunk = max(1, _SOLVE_CHUNK // (n * 6))
    blk = np.arange(6)
    for b0 in range(0, m, per_chunk):
        b1 = min(m, b0 + per_chunk)
        sel = np.flatnonzero((b >= b0) & (b < b1))
        if sel.size == 0:
            continue
        cols = np.arange(6 * b0, 6 * b1)
        e = np.zeros((n, cols.size))
        e[cols, np.arange(cols.size)] = 1.0
        x = red.scale[:, None] * red.lu.solve(e) * red.scale[cols][None, :]
        rows_i = 6 * a[sel][:, None, None] + blk[None, :, None]
        cols_i = 6 * (b[sel] - b0)[:, None, None] + blk[None, None, :]
        out[sel] = x[rows_i, cols_i]
    return out


def _precision(prob: _Problem, red: _Reduced) -> tuple[FloatArray, FloatArray]:
    """Cofactors: photo blocks (M, 6, 6) of S^-1, point diagonals (P, 3) via the Schur structure.

    ``Q_pp = V^-1 + V^-1 W.T S^-1 W V^-1``; its 3 x 3 diagonal blocks need only
    the blocks of ``S^-1`` for photo pairs that share a point.
    """
    m = prob.n_photos
    pa, pb = prob.photo[prob.pair_k1], prob.photo[prob.pair_k2]
    keys = np.concatenate([pa * m + pb, np.arange(m) * (m + 1)])
    uniq, inverse = np.unique(keys, return_inverse=True)
    blocks = _photo_covariance_blocks(prob, red, uniq // m, uniq % m)
    diag_blocks = blocks[inverse[pa.size :]]
    y1, y2 = red.y[prob.pair_k1], red.y[prob.pair_k2]
    terms = np.swapaxes(y1, 1, 2) @ blocks[inverse[: pa.size]] @ y2
    q_point = red.v_inv + (prob.pair_point_sum @ terms.reshape(-1, 9)).reshape(-1, 3, 3)
    return diag_blocks, np.diagonal(q_point, axis1=1, axis2=2)


def _residual_cofactor(weight: FloatArray, q_hat: FloatArray) -> FloatArray:
    """``P^-1 - Q_hat`` (M, 3, 3) for direct observations with diagonal weights (M, 3).

    Rows and columns of unobserved components (weight 0) are NaN.
    """
    used = weight > 0.0
    i3 = np.arange(3)
    out = -np.array(q_hat, dtype=np.float64)
    out[:, i3, i3] += 1.0 / np.where(used, weight, 1.0)
    return np.where(used[:, :, None] & used[:, None, :], out, np.nan)


# ----------------------------------------------------------------------------
# Driver
# ----------------------------------------------------------------------------


def bundle_adjust(
    observations: ImageObservations,
    centres0: ArrayLike,
    rotations0: ArrayLike,
    points0: ArrayLike,
    *,
    control_xyz: ArrayLike | None = None,
    control_sigma: ArrayLike | None = None,
    gnss_centres: ArrayLike | None = None,
    gnss_sigma: ArrayLike | None = None,
    imu_rotations: ArrayLike | None = None,
    imu_sigma: ArrayLike | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    tolerance: float = 1e-10,
    compute_precision: bool = True,
    camera: CameraModel | None = None,
    camera0: ArrayLike | None = None,
) -> BundleResult:
    """Least-squares bundle adjustment of a strip by the collinearity equations.

    Parameters
    ----------
    observations : ImageObservations
        Image coordinates (K observations) in mm with their sigmas; photo and
        point indices refer to the rows of ``centres0`` and ``points0``.
    centres0 : array_like, shape (M, 3)
        Initial projection centres in metres, local Cartesian frame.
    rotations0 : array_like, shape (M, 3, 3)
        Initial rotations, image -> frame (``l = R @ (x, y, -c)``).
    points0 : array_like, shape (P, 3)
        Initial point coordinates in metres, ``P = len(observations.point_ids)``.
    control_xyz : array_like, shape (P, 3), optional
        Ground coordinates of the control in the same frame, NaN for
        components without control (full: 3 given, plan-only: X, Y, height-only:
        Z).  They enter as observations of the point coordinates.
    control_sigma : array_like, shape (P, 3) or broadcastable, optional
        Their standard deviations in metres (inf or NaN where none).
    gnss_centres : array_like, shape (M, 3), optional
        Observed projection centres in metres, NaN where none.
    gnss_sigma : array_like, shape (M, 3) or broadcastable, optional
        Their standard deviations in metres.
    imu_rotations : array_like, shape (M, 3, 3), optional
        Observed rotations (image -> frame), NaN matrices where none.  The
        observation is ``log(R_imu.T @ R) = 0``: the small rotation vector
        about the photo's own x, y, z axes that takes the observed attitude
        to the adjusted one.
    imu_sigma : float or array_like, shape (M, 3), optional
        Standard deviations of those rotation components in radians.
    max_iterations : int
        Largest number of accepted steps.
    tolerance : float
        Stop when the objective changes by less than ``tolerance`` relative,
        or when the largest correction is below ``tolerance`` (radians, and
        metres relative to the mean point depth below the photos).
    compute_precision : bool
        Compute ``point_std``, ``centre_std`` and ``rotation_std`` (else NaN).
    camera : CameraModel, optional
        Self-calibration: the camera parameters estimated with the block, a
        dense border of the normal equations (:mod:`strip_aerotri.bundle.border`);
        the image coordinates are then corrected by ``Δ(x_obs; θ)``.
    camera0 : array_like, shape (k,), optional
        Start values of the camera parameters (default 0: the start camera).

    Returns
    -------
    BundleResult
        Adjusted orientations and points, residuals, sigma0 and precision.

    Raises
    ------
    ValueError
        Bad shapes, non-rotation matrices, non-positive sigmas.
    GeometryError
        The datum is not defined by the control / GNSS / IMU observations (the
        message names the free similarity motions), a point or photo is not
        determined, a point lies behind a photo at the initial values, or the
        reduced normal matrix is singular.
    ConvergenceError
        The objective cannot be reduced (the iteration diverges).

    Warns
    -----
    StripAerotriWarning
        Not converged within ``max_iterations``; nearly singular reduced
        normal matrix; no redundancy.

    Notes
    -----
    Observation equations (weights ``1 / sigma**2``, a priori sigma0 = 1):
    image ``x(S, R, X) - x_obs``, control ``X - X_c``, GNSS ``S - S_g``, IMU
    ``log(R_imu.T R)`` with design ``Jr^-1`` (the inverse right Jacobian of
    SO(3)).  Unknowns per photo: ``dS`` and ``delta`` with the
    right-multiplied update ``R <- R @ exp([delta]x)``, so ``delta`` is a
    rotation about the photo's own image axes; ``dv/d(delta) = [v]x`` with
    ``v = R.T (X - S)``.

    Each iteration forms the normal blocks ``U`` (6 x 6 per photo), ``V`` (3 x 3
    per point) and ``W`` (6 x 3 per observation) as whole arrays, reduces to
    the photos, ``S = U - W V^-1 W.T``, which is assembled in COO form from
    one 6 x 6 block per pair of observations of the same point, scaled to
    unit diagonal and factorised by a sparse LU (SuperLU, symmetric mode,
    minimum-degree ordering); the points follow by back-substitution.
    Levenberg-Marquardt damping (diagonals times ``1 + lambda``) is used only
    when a Gauss-Newton step fails to reduce the objective.

    The datum must come from the observations: before iterating, the seven
    similarity motions of the net are tested against the control, GNSS and
    IMU observations; a pivot of the scaled reduced matrix below 1e-11
    likewise means a singular system.

    Precision: ``Q = N^-1`` at the solution (undamped).  Photo blocks of
    ``S^-1`` are found by solving with the LU factors for the 6 unit vectors
    of every photo (``6 M`` solves in chunks, each O(nnz(LU)), i.e.
    O(M^2 * bandwidth) in total for a strip: about 0.1 s for M = 200 and 7 s
    for M = 1000 photos on a small machine), keeping only the blocks of photo
    pairs that share a point; the 3 x 3 point blocks follow from
    ``Q_pp = V^-1 + V^-1 W.T S^-1 W V^-1`` as one batched product over the
    pairs of observations.  Standard deviations are
    ``sigma0 * sqrt(diag(Q))``.  The cofactors of the GNSS and IMU residuals
    follow from the photos' own 6 x 6 blocks of ``Q`` at no further cost:
    ``Q_vv = P^-1 - A Q A.T`` with ``A`` the identity (GNSS) or ``Jr^-1``
    (IMU).

    Examples
    --------
    Two vertical photos 600 m apart at 1200 m over six points, two of them
    full control and one more height (noise-free, perturbed start):

    >>> import numpy as np
    >>> from strip_aerotri.observations import ImageObservations
    >>> centres = np.array([[0.0, 0.0, 1200.0], [600.0, 0.0, 1200.0]])
    >>> rotations = np.stack([np.eye(3), np.eye(3)])
    >>> points = np.array([[100.0, 400, 0], [500, 400, 10], [100, -400, 5],
    ...                    [500, -400, 0], [300, 0, 20], [300, 300, -10]])
    >>> photo, point = np.repeat([0, 1], 6), np.tile(np.arange(6), 2)
    >>> v = points[point] - centres[photo]
    >>> xy = -152.0 * v[:, :2] / v[:, 2:]
    >>> obs = ImageObservations(("1", "2"), tuple("abcdef"), photo, point, xy,
    ...                         np.full(12, 0.005), 152.0)
    >>> control = np.full((6, 3), np.nan)
    >>> control[:2] = points[:2]
    >>> control[2, 2] = points[2, 2]
    >>> result = bundle_adjust(obs, centres + 3.0, rotations, points - 2.0,
    ...                        control_xyz=control, control_sigma=0.01)
    >>> bool(np.allclose(result.points, points, atol=1e-6)), result.redundancy
    (True, 1)
    """
    centres, rotations, points = _checked_start(
        observations, centres0, rotations0, points0, max_iterations, tolerance
    )
    m, p = centres.shape[0], points.shape[0]
    prob = _make_problem(
        observations,
        centres,
        rotations,
        points,
        control_xyz,
        control_sigma,
        gnss_centres,
        gnss_sigma,
        imu_rotations,
        imu_sigma,
    )
    if camera is not None:
        prob = dataclasses.replace(prob, camera=camera)
    start_camera = np.zeros(prob.n_camera) if camera0 is None else np.asarray(camera0, float)
    if start_camera.shape != (prob.n_camera,):
        raise ValueError(f"Expected `camera0` of shape ({prob.n_camera},), got {start_camera.shape}")
    state = _State(centres.copy(), rotations.copy(), points.copy(), start_camera.copy())
    depth = _check_datum_and_sides(prob, state, observations)
    redundancy = prob.n_observations - 6 * m - 3 * p - prob.n_camera

    def sigma0_of(cost: float) -> float:
        return float(np.sqrt(cost / redundancy)) if redundancy > 0 else float("nan")

    normals = _normals(prob, state)
    _check_points(prob, normals, observations.point_ids)
    state, normals, history, iterations, converged = _iterate(
        prob, state, normals, depth, int(max_iterations), tolerance, observations, sigma0_of
    )
    if not converged:
        warnings.warn(
            f"bundle adjustment did not converge in {max_iterations} iterations "
            f"(sigma0 {history[-1]:.4g})",
            StripAerotriWarning,
            stacklevel=2,
        )
    sigma0 = sigma0_of(normals.cost)
    if redundancy <= 0:
        warnings.warn(
            "bundle adjustment has no redundancy: sigma0 and precision are undefined",
            StripAerotriWarning,
            stacklevel=2,
        )
    precision = _precision_products(prob, state, normals, sigma0, compute_precision)
    control_used = prob.control_weight > 0
    return BundleResult(
        centres=state.centres,
        rotations=state.rotations,
        points=state.points,
        sigma0=sigma0,
        redundancy=int(redundancy),
        iterations=iterations,
        converged=converged,
        residuals_mm=normals.residuals_mm,
        control_residuals=np.where(control_used, state.points - prob.control_xyz, np.nan),
        point_std=precision.point_std,
        centre_std=precision.centre_std,
        rotation_std=precision.rotation_std,
        history=np.asarray(history),
        n_observations=prob.n_observations,
        gnss_residuals=np.where(prob.gnss_weight > 0, state.centres - prob.gnss_xyz, np.nan),
        imu_residuals=np.where(prob.imu_weight > 0, precision.imu_residuals, np.nan),
        gnss_residual_cofactor=precision.gnss_cofactor,
        imu_residual_cofactor=precision.imu_cofactor,
        camera=precision.camera,
    )


def _checked_start(
    observations: ImageObservations,
    centres0: ArrayLike,
    rotations0: ArrayLike,
    points0: ArrayLike,
    max_iterations: int,
    tolerance: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The start values as arrays, their shapes and the settings checked."""
    if not isinstance(observations, ImageObservations):
        raise TypeError(
            f"Expected `observations` to be ImageObservations, got {type(observations).__name__}"
        )
    centres = np.asarray(centres0, dtype=np.float64)
    rotations = np.asarray(rotations0, dtype=np.float64)
    points = np.asarray(points0, dtype=np.float64)
    m = centres.shape[0] if centres.ndim == 2 else -1
    if centres.shape != (m, 3) or m < 1:
        raise ValueError(f"Expected `centres0` to have shape (M, 3), got {centres.shape}")
    if rotations.shape != (m, 3, 3):
        raise ValueError(f"Expected `rotations0` to have shape {(m, 3, 3)}, got {rotations.shape}")
    p = len(observations.point_ids)
    if points.shape != (p, 3):
        raise ValueError(f"Expected `points0` to have shape {(p, 3)}, got {points.shape}")
    if len(observations.photo_ids) != m:
        raise ValueError(
            f"`centres0` has {m} rows but observations list {len(observations.photo_ids)} photos"
        )
    if not (np.all(np.isfinite(centres)) and np.all(np.isfinite(points))):
        raise ValueError("Expected finite `centres0` and `points0`")
    _check_rotations(rotations, "rotations0")
    if int(max_iterations) < 1:
        raise ValueError(f"Expected `max_iterations` >= 1, got {max_iterations}")
    if not tolerance > 0.0:
        raise ValueError(f"Expected a positive `tolerance`, got {tolerance}")
    return centres, rotations, points


def _check_datum_and_sides(
    prob: _Problem, state: _State, observations: ImageObservations
) -> float:
    """GeometryError when the control, GNSS and IMU leave the datum free or a
    point lies behind a photo at the start values; returns the median depth
    of the points below their photos (the scale of the steps' test)."""
    free = _free_motions(prob, state)
    if free:
        counts = (
            f"{np.count_nonzero(prob.control_weight)} control coordinate(s), "
            f"{np.count_nonzero(prob.gnss_weight)} GNSS centre coordinate(s) and "
            f"{np.count_nonzero(np.any(prob.imu_weight > 0, axis=1))} IMU attitude(s)"
        )
        raise GeometryError(
            f"the datum is not defined: {counts} leave free: {'; '.join(free)}. "
            "A 3D similarity needs at least two full control points and one more height "
            "point, not all in one vertical plane (or GNSS centres plus control that fixes "
            "the roll about the strip axis)"
        )
    _, v0 = project(state.centres, state.rotations, state.points, prob.photo, prob.point, prob.c)
    behind = ~(v0[:, 2] < 0.0)
    if np.any(behind):
        kk = int(np.flatnonzero(behind)[0])
        raise GeometryError(
            f"point '{observations.point_ids[prob.point[kk]]}' lies behind photo "
            f"'{observations.photo_ids[prob.photo[kk]]}' at the initial values"
        )
    return float(np.median(-v0[:, 2])) if v0.size else 1.0


def _iterate(
    prob: _Problem,
    state: _State,
    normals: _Normals,
    depth: float,
    max_iterations: int,
    tolerance: float,
    observations: ImageObservations,
    sigma0_of: Callable[[float], float],
) -> tuple[_State, _Normals, list[float], int, bool]:
    """Gauss-Newton with Levenberg-Marquardt damping when a step does not
    lower the cost.  Returns the last state and its normals, sigma0 after
    each step, the number of steps and whether it converged."""
    history = [sigma0_of(normals.cost)]
    lam = 0.0
    iterations = 0
    warned_weak = False
    for _ in range(max_iterations):
        cost = normals.cost
        while True:
            step = _solve(prob, normals, lam)
            if lam == 0.0:
                if step.min_pivot < _SINGULAR_PIVOT:
                    j = step.min_pivot_index
                    raise GeometryError(
                        "the reduced normal matrix is singular (relative pivot "
                        f"{step.min_pivot:.1e} at the {_PHOTO_PARAMETER_NAMES[j % 6]} of photo "
                        f"'{observations.photo_ids[j // 6]}'): the datum or that photo's "
                        "orientation is not determined"
                    )
                if step.min_pivot < _WEAK_PIVOT and not warned_weak:
                    warned_weak = True
                    warnings.warn(
                        f"nearly singular reduced normal matrix (relative pivot "
                        f"{step.min_pivot:.1e}); the solution is weakly determined",
                        StripAerotriWarning,
                        stacklevel=3,
                    )
            max_step = max(
                float(np.max(np.abs(step.d_photo[:, :3]), initial=0.0)) / depth,
                float(np.max(np.abs(step.d_point), initial=0.0)) / depth,
                float(np.max(np.abs(step.d_photo[:, 3:]), initial=0.0)),
            )
            if not np.isfinite(max_step):
                raise ConvergenceError(
                    f"bundle adjustment failed: non-finite correction after {iterations} step(s)"
                )
            trial = _apply(state, step)
            trial_cost = _cost(prob, trial)
            if trial_cost <= cost:
                break
            if max_step < tolerance or trial_cost - cost <= tolerance * cost:
                trial, trial_cost = state, cost  # at the noise floor: nothing to gain
                break
            lam = 1e-4 if lam == 0.0 else 10.0 * lam
            if lam > 1e8:
                raise ConvergenceError(
                    "bundle adjustment diverges: the objective could not be reduced after "
                    f"{iterations} step(s) (sigma0 {history[-1]:.3g}); check the initial "
                    "values and the observations for blunders"
                )
        if trial is not state:
            iterations += 1
            state = trial
            normals = _normals(prob, state)
            history.append(sigma0_of(normals.cost))
        # A damped step may be small or gain little without being at the minimum:
        # only an undamped (Gauss-Newton) step can end the iteration.
        if lam == 0.0 and (max_step < tolerance or (cost - trial_cost) <= tolerance * cost):
            return state, normals, history, iterations, True
        lam = 0.0 if lam <= 1e-3 else lam / 10.0
    return state, normals, history, iterations, False


class _Precision(NamedTuple):
    point_std: FloatArray  # (P, 3) m
    centre_std: FloatArray  # (M, 3) m
    rotation_std: FloatArray  # (M, 3) rad
    imu_residuals: FloatArray  # (M, 3) rad, log(R_imu.T R)
    gnss_cofactor: FloatArray  # (M, 3, 3)
    imu_cofactor: FloatArray  # (M, 3, 3)
    camera: CameraEstimate | None


def _precision_products(
    prob: _Problem,
    state: _State,
    normals: _Normals,
    sigma0: float,
    compute_precision: bool,
) -> _Precision:
    """Standard deviations of points and photos and the cofactors of the GNSS
    and IMU residuals (NaN without ``compute_precision``)."""
    m, p = prob.n_photos, prob.n_points
    nan_p, nan_m = np.full((p, 3), np.nan), np.full((m, 3), np.nan)
    point_std, centre_std, rotation_std = nan_p, nan_m, nan_m.copy()
    e_imu = _imu_residual(state.rotations, prob.imu_rot)
    gnss_cofactor = np.full((m, 3, 3), np.nan)
    imu_cofactor = np.full((m, 3, 3), np.nan)
    camera = None
    if prob.camera is not None:
        final = _solve(prob, normals, 0.0)
        if final.border is not None:
            camera = CameraEstimate(
                model=prob.camera,
                values=state.camera,
                cofactor=final.border.c_inv,
                sigma0=sigma0,
                information=final.border.g_diag,
                conditional_information=final.border.c_diag,
            )
    if compute_precision:
        final = _solve(prob, normals, 0.0)
        q_blocks, q_point = _precision(prob, final)
        if final.border is not None and normals.border is not None:
            add_photo, add_point = border_precision(
                final.border, final.v_inv, normals.border.t_point, normals.w, prob.photo,
                prob.point_sum,
            )
            q_blocks = q_blocks + add_photo
            q_point = q_point + add_point
        q_photo = np.diagonal(q_blocks, axis1=1, axis2=2)
        point_std = sigma0 * np.sqrt(q_point)
        centre_std = sigma0 * np.sqrt(q_photo[:, :3])
        rotation_std = sigma0 * np.sqrt(q_photo[:, 3:])
        # Residual cofactors of the direct photo observations: exact from the
        # photo blocks of N^-1 already at hand (no further solves).
        if (prob.gnss_weight > 0).any():
            gnss_cofactor = _residual_cofactor(prob.gnss_weight, q_blocks[:, :3, :3])
        if (prob.imu_weight > 0).any():
            j_imu = _right_jacobian_inv(e_imu)
            q_imu = j_imu @ q_blocks[:, 3:, 3:] @ np.swapaxes(j_imu, 1, 2)
            imu_cofactor = _residual_cofactor(prob.imu_weight, q_imu)
    return _Precision(
        point_std, centre_std, rotation_std, e_imu, gnss_cofactor, imu_cofactor, camera
    )
