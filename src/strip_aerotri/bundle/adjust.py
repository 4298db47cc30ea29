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
the axes of the photo's own image system; three per point.

Each iteration forms the normal blocks ``U`` (6 x 6 per photo), ``V`` (3 x 3
per point) and ``W`` (6 x 3 per observation) as whole arrays and reduces
to the photos, ``S = U - W V^-1 W.T``, with the structured engine
:mod:`strip_aerotri.geometry.normals` (method.md 6B): the photos along the
strip (in a block along the main axis of the centres, or by reverse
Cuthill-McKee where narrower), ``S`` a block band scaled to unit diagonal
and factorised by LAPACK's banded Cholesky; the points follow by
back-substitution.
Levenberg-Marquardt damping (diagonals times ``1 + lambda``) is used only
when a Gauss-Newton step fails to reduce the objective.

The datum must come from the observations: before iterating, the seven
similarity motions of the net are tested against the control, GNSS and
IMU observations; a pivot of the scaled reduced matrix below 1e-11
likewise means a singular system.

Precision: ``Q = N^-1`` at the solution (undamped), on its pattern only:
the band of ``S^-1`` by Takahashi's recursion on the banded factor, the
3 x 3 point blocks ``Q_pp = V^-1 + V^-1 W.T S^-1 W V^-1`` and every image
coordinate's redundancy number ``1 - (A Q A.T P)_ii``
(``BundleResult.image_redundancy``), about the cost of one more
iteration.  Standard deviations are
``sigma0 * sqrt(diag(Q))``.  The cofactors of the GNSS and IMU residuals
follow from the photos' own 6 x 6 blocks of ``Q`` at no further cost:
``Q_vv = P^-1 - A Q A.T`` with ``A`` the identity (GNSS) or ``Jr^-1``
(IMU).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .._threads import compute_workers, limit_blas_threads
from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import ConvergenceError, GeometryError, StripAerotriWarning
from ..geometry.camera_model import CameraModel, ShutterMotion
from ..geometry.collinearity import collinearity_jacobians, project
from ..geometry.normals import (
    FormedNormals,
    NormalSolution,
    NormalStructure,
    PointRows,
    SingularNormalsError,
    UnitPointRows,
    UnitRows,
)
from ..geometry.rotation import matrix_from_rotvec
from ..observations import ImageObservations
from ..options import DEFAULT_MAX_ITERATIONS
from ..results import BundleResult, CameraEstimate, ShutterEstimate
from ._datum import free_motions
from ._given import along_axis_order, check_rotations, given_weights, observed_with_sigma
from ._observation_space import (
    ObservationSpace,
    moving_space,
    observation_space,
    premultiply,
    readout_at,
)
from ._so3 import imu_residual as _imu_residual
from ._so3 import right_jacobian_inv as _right_jacobian_inv
from ._structures import structure_for

__all__ = ["NOT_CONVERGED", "BundleResult", "CameraUndetermined", "bundle_adjust"]


class CameraUndetermined(GeometryError):
    """A camera parameter of a self-calibration (``name``) is not determined."""

    def __init__(self, message: str, name: str) -> None:
        super().__init__(message)
        self.name = name

#: Relative pivot (of the Jacobi-scaled reduced matrix, whose diagonal is 1)
#: below which the reduced normal matrix is taken as singular.
_SINGULAR_PIVOT = 1e-11
#: Relative pivot below which a near-singular reduced matrix is warned about.
_WEAK_PIVOT = 1e-8
#: How the warning of an adjustment out of iterations begins (callers that run
#: trial adjustments filter it by this text).
NOT_CONVERGED = "bundle adjustment did not converge"
#: Ratio of smallest to largest eigenvalue of a point's 3 x 3 normal block
#: below which the point counts as undetermined (e.g. seen on one photo only).
_POINT_RANK_TOL = 1e-10

_PHOTO_PARAMETER_NAMES = (
    "X0",
    "Y0",
    "Z0",
    "rotation about x",
    "rotation about y",
    "rotation about z",
)


# --- Problem data ------------------------------------------------------------


@dataclass(frozen=True)
class _Problem:
    photo_ids: tuple[str, ...]
    rows: IntArray  # (K,) the observation of each row (the rows in the structure's pairs' order)
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
    structure: NormalStructure  # photos (6 unknowns each) and points, banded
    control_points: IntArray  # points with control
    gnss_photos: IntArray  # photos with a GNSS centre
    imu_photos: IntArray  # photos with an IMU attitude
    camera: CameraModel | None = None  # self-calibration: the border's parameters
    motion: ShutterMotion | None = None  # rolling shutter: the border's last columns

    @property
    def n_camera(self) -> int:
        return 0 if self.camera is None else len(self.camera.estimated)

    @property
    def n_motion(self) -> int:
        return 0 if self.motion is None else self.motion.n_unknowns

    @property
    def n_observations(self) -> int:
        return int(
            2 * self.photo.size
            + np.count_nonzero(self.control_weight)
            + np.count_nonzero(self.gnss_weight)
            + np.count_nonzero(self.imu_weight)
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
    camera: CameraModel | None = None,
    motion: ShutterMotion | None = None,
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
    cxyz, cw = given_weights(control_xyz, control_sigma, (p, 3), "control_xyz", "control_sigma")
    gxyz, gw = given_weights(gnss_centres, gnss_sigma, (m, 3), "gnss_centres", "gnss_sigma")
    if imu_rotations is None:
        imu = np.broadcast_to(np.eye(3), (m, 3, 3)).copy()
        iw = np.zeros((m, 3))
    else:
        imu, sig = observed_with_sigma(
            imu_rotations, imu_sigma, (m, 3, 3), "imu_rotations", "imu_sigma"
        )
        present = np.all(np.isfinite(imu), axis=(1, 2))
        imu = np.where(present[:, None, None], imu, np.eye(3))
        check_rotations(imu, "imu_rotations")
        used = present[:, None] & np.isfinite(sig)
        if np.any(sig[used] <= 0.0):
            raise ValueError("Expected positive standard deviations for `imu_rotations`")
        iw = np.zeros((m, 3))
        iw[used] = 1.0 / sig[used] ** 2
    along = along_axis_order(centres)
    n_border = (0 if camera is None else len(camera.estimated)) + (
        0 if motion is None else motion.n_unknowns
    )
    structure = structure_for(  # one for every border: "auto"'s trials share it
        (m, p, photo, point, along, obs.photo_ids, obs.point_ids),
        lambda: NormalStructure.from_indices(
            m, 6, p, photo, point, candidates=[along], unit_names=tuple(obs.photo_ids),
            point_names=tuple(obs.point_ids), parameter_names=_PHOTO_PARAMETER_NAMES,
        ),
    )
    # the rows in the pairs' order, so that the normal blocks read them in place;
    # ordered before the border is added, so that the shared structure keeps it
    ordered = structure.in_pair_order()
    rows = np.arange(k, dtype=np.intp)
    if ordered is not None:
        structure, rows = ordered
    structure = structure.with_border(n_border)
    return _Problem(
        photo_ids=tuple(obs.photo_ids),
        rows=rows,
        photo=photo[rows],
        point=point[rows],
        xy=xy[rows],
        sigma=sigma[rows],
        c=c,
        n_photos=m,
        n_points=p,
        control_xyz=cxyz,
        control_weight=cw,
        gnss_xyz=gxyz,
        gnss_weight=gw,
        imu_rot=imu,
        imu_weight=iw,
        structure=structure,
        control_points=np.flatnonzero(np.any(cw > 0, axis=1)),
        gnss_photos=np.flatnonzero(np.any(gw > 0, axis=1)),
        imu_photos=np.flatnonzero(np.any(iw > 0, axis=1)),
        camera=camera,
        motion=motion,
    )


# --- Normal equations --------------------------------------------------------


@dataclass(frozen=True)
class _State:
    centres: FloatArray
    rotations: FloatArray
    points: FloatArray
    camera: FloatArray = field(default_factory=lambda: np.zeros(0))  # (k,) increments
    motion: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))  # (G, 3) m


@dataclass(frozen=True)
class _Normals:
    """The observation rows at one linearisation and their normal blocks."""

    image: UnitPointRows  # whitened image rows (K, 2)
    control: PointRows
    photo_rows: tuple[UnitRows, ...]  # GNSS centres, IMU attitudes
    formed: FormedNormals
    cost: float
    residuals_mm: FloatArray  # (K, 2) per row (prob.rows), computed - observed


@dataclass(frozen=True)
class _Reduced:
    d_photo: FloatArray  # (M, 6)
    d_point: FloatArray  # (P, 3)
    solution: NormalSolution
    min_pivot: float
    min_pivot_index: int  # 6 * photo + parameter


def _normals(prob: _Problem, state: _State) -> _Normals | None:
    """Linearise all observation equations at ``state`` and form the normal
    blocks; None when a point lies behind a photo.

    Rows (residual computed minus observed): image ``x - x_obs`` whitened by
    its sigma, with a camera model ``x̂ - x_obs`` (``x̂ + Δ(x̂) = x``, the
    design premultiplied per ray by ``(I + ∂Δ/∂x)⁻¹``), with a rolling
    shutter each ray read at ``x̂``'s row (``x̂ + Δ(x̂) = x(S + s(x̂) d)``,
    ``(I + ∂Δ/∂x - u aᵀ)⁻¹``; :mod:`._observation_space`); control ``X -
    X_c`` (m, design identity); GNSS ``S - S_g`` (m, design identity on the
    centre); IMU ``log(R_imu.T R)`` (rad, design ``Jr^-1(e)`` on the
    rotation)."""
    inv_s = 1.0 / prob.sigma
    at = None if prob.motion is None else _rows_read(prob, state)
    if prob.motion is not None and at is None:
        return None  # no first solution of the rows read: the cost is infinite
    motion = prob.motion
    shutter = None if at is None or motion is None else (motion, motion.fractions(at))
    xy, v, jac_photo, jac_point = _collinearity(prob, state, inv_s, shutter)
    if not (np.all(v[:, 2] < 0.0) and np.all(np.isfinite(xy))):
        return None  # a point behind a photo: no linearisation (the cost is infinite)
    if prob.camera is None and shutter is None:
        res, space = xy - prob.xy, None
    else:
        readout = None
        if shutter is not None and at is not None:
            rays = (state.rotations, prob.photo, v, prob.c)
            readout = readout_at(shutter[0], state.motion, rays, at)
        space = observation_space(prob.camera, state.camera, xy, prob.xy, readout)
        if not space.converged:
            return None  # no true positions for this camera: the cost is infinite
        res = space.residuals
        premultiply(space.mapping, jac_photo)  # before the shutter's columns copy the centre's
        premultiply(space.mapping, jac_point)
        if shutter is not None:  # the motion's columns at the row x̂ is read at
            shutter = (shutter[0], shutter[0].fractions(space.true_xy))
    border = _border(prob, state, jac_photo, inv_s, shutter, space)
    image = UnitPointRows(
        prob.photo, prob.point, jac_photo, jac_point, res * inv_s[:, None],
        border_jacobian=border, unit_shift=True,
    )  # fmt: skip
    cp = prob.control_points
    control = PointRows(
        cp,
        np.broadcast_to(np.eye(3), (cp.size, 3, 3)),
        state.points[cp] - prob.control_xyz[cp],
        prob.control_weight[cp],
    )
    gp, ip = prob.gnss_photos, prob.imu_photos
    gnss_jac = np.zeros((gp.size, 3, 1, 6))
    gnss_jac[:, :, 0, :3] = np.eye(3)
    e_imu = _imu_residual(state.rotations[ip], prob.imu_rot[ip])
    imu_jac = np.zeros((ip.size, 3, 1, 6))
    imu_jac[:, :, 0, 3:] = _right_jacobian_inv(e_imu)
    photo_rows = (
        UnitRows(gp[:, None], gnss_jac, state.centres[gp] - prob.gnss_xyz[gp], prob.gnss_weight[gp]),
        UnitRows(ip[:, None], imu_jac, e_imu, prob.imu_weight[ip]),
    )
    formed = prob.structure.form([image], photo_rows, [control])
    return _Normals(image, control, photo_rows, formed, formed.cost, res)


def _collinearity(
    prob: _Problem,
    state: _State,
    inv_s: FloatArray,
    shutter: tuple[ShutterMotion, FloatArray] | None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The collinearity equations and their Jacobians whitened by ``inv_s``
    (K,) = 1/σ; with a rolling shutter (its motion and the rows' fractions
    ``s`` (K,)) each ray from its centre moved by ``s d_g`` (the point moved
    by the opposite, which is the same ray)."""
    if shutter is None:
        return collinearity_jacobians(
            state.centres, state.rotations, state.points, prob.photo, prob.point, prob.c, inv_s
        )
    motion, s = shutter
    ray_points = state.points[prob.point] - motion.centre_shift(state.motion, prob.photo, s)
    rays = np.arange(prob.photo.size, dtype=np.intp)
    return collinearity_jacobians(
        state.centres, state.rotations, ray_points, prob.photo, rays, prob.c, inv_s
    )


def _rows_read(prob: _Problem, state: _State) -> FloatArray | None:
    """Coordinates (K, 2) at whose fractions the rays are projected: the true
    positions ``x̂`` of one pass of :func:`._observation_space.moving_space`
    (the observations' rows), so that the linearisation's projections are
    those of ``x̂``'s rows to 1e-14 mm; the observations themselves when no
    centre moves (the fraction moves nothing); None when no first solution
    exists."""
    assert prob.motion is not None
    if not np.any(state.motion):
        return prob.xy
    rays = (state.centres, state.rotations, state.points[prob.point], prob.photo, prob.c)
    first = moving_space(
        prob.motion, state.motion, rays, prob.camera, state.camera, prob.xy, passes=1
    )
    return None if first is None or not first.converged else first.true_xy


def _border(
    prob: _Problem,
    state: _State,
    jac_photo: FloatArray,
    inv_s: FloatArray,
    shutter: tuple[ShutterMotion, FloatArray] | None,
    space: ObservationSpace | None,
) -> FloatArray | None:
    """The border's whitened design columns (K, 2, k): the camera's
    ``dv/dθ = -M dΔ/dθ(x̂)`` (``space``) times ``inv_s`` (K,) = 1/σ, then the
    motions' ``s dv/dS`` from the centre columns of ``jac_photo``, which are
    whitened (and premultiplied by M) already."""
    parts = []
    if prob.camera is not None and space is not None:
        theta = prob.camera.partials(space.true_xy, state.camera) * -inv_s[:, None, None]
        premultiply(space.mapping, theta)
        parts.append(theta)
    if shutter is not None:
        motion, s = shutter
        parts.append(motion.border(jac_photo[:, :, :3], prob.photo, s))
    return np.concatenate(parts, axis=2) if parts else None


def _check_points(prob: _Problem, normals: _Normals, point_ids: tuple[str, ...]) -> None:
    """Raise GeometryError for points whose 3 x 3 normal block is (near) singular."""
    idx = normals.formed.undetermined_points(_POINT_RANK_TOL)
    if idx.size:
        n_rays = np.bincount(prob.point, minlength=prob.n_points)
        listed = ", ".join(f"'{point_ids[i]}' ({n_rays[i]} photo(s))" for i in idx[:5])
        more = f" and {idx.size - 5} more" if idx.size > 5 else ""
        raise GeometryError(
            f"{idx.size} point(s) cannot be determined: {listed}{more}; a point needs "
            "rays from two photos, or one ray and control that fixes it"
        )


def _solve(prob: _Problem, normals: _Normals, lam: float, step: bool = True) -> _Reduced:
    """Reduce to the photos (Schur complement on the point blocks), solve, back-substitute.

    ``lam`` is the Levenberg-Marquardt factor: the diagonals of U and V are
    multiplied by ``1 + lam``; without ``step`` the factor alone (steps NaN).
    """
    try:
        solution = normals.formed.solve(lam, step=step)
    except SingularNormalsError as exc:
        if exc.kind == "border" and exc.index >= prob.n_camera:
            g, axis = divmod(exc.index - prob.n_camera, 3)
            assert prob.motion is not None
            raise GeometryError(
                f"the rolling shutter's motion along {'XYZ'[axis]} of "
                f"'{prob.motion.group_names[g]}' is not determined by the observations: its "
                "photos' image points must spread over the rows read (leave the motion out)"
            ) from None
        if exc.kind == "border" and prob.camera is not None:
            name = prob.camera.estimated[exc.index]
            raise CameraUndetermined(
                f"the camera parameter {name} is not determined: the exterior orientation "
                "absorbs it (e.g. c with the flying height over flat ground, x0 and y0 with "
                'the centres), or other parameters do; leave it out of self_calibration or '
                'use "auto"',
                name,
            ) from None
        if exc.kind != "unit":
            raise
        raise GeometryError(
            "the reduced normal matrix is singular at the "
            f"{_PHOTO_PARAMETER_NAMES[exc.parameter or 0]} of photo "
            f"'{prob.photo_ids[exc.index]}': the datum or that photo's orientation is not "
            "determined by the observations"
        ) from None
    j = 6 * solution.min_pivot_unit + solution.min_pivot_parameter
    return _Reduced(solution.unit_step, solution.point_step, solution, solution.min_pivot, j)


#: A chord step (:func:`_chord`) follows a full Gauss-Newton step that moved the
#: unknowns by less than this (relative, as the tolerance's test measures them).
_CHORD_BELOW_MOVE = 1e-4


def _chord(normals: _Normals, full: _Reduced) -> _Reduced:
    """The step of ``normals``' gradients with the factor of the last full
    step `full` (no new forming of the reduced system nor factoring): where
    that step moved the unknowns by less than :data:`_CHORD_BELOW_MOVE`, the normal
    matrix changed by about as little, and the chord step differs from the
    full one by that share of its own size (a 1e-6 m step by 1e-10 m)."""
    unit, point = normals.formed.chord_step(full.solution)
    return dataclasses.replace(full, d_photo=unit, d_point=point)


def _apply(state: _State, step: _Reduced) -> _State:
    k = state.camera.size
    border = step.solution.border_step
    return _State(
        centres=state.centres + step.d_photo[:, :3],
        rotations=state.rotations @ matrix_from_rotvec(step.d_photo[:, 3:]),
        points=state.points + step.d_point,
        camera=state.camera + border[:k] if k else state.camera,
        motion=state.motion + border[k:].reshape(-1, 3) if state.motion.size else state.motion,
    )


# --- Precision ---------------------------------------------------------------


def _residual_cofactor(weight: FloatArray, q_hat: FloatArray) -> FloatArray:
    """``P^-1 - Q_hat`` (M, 3, 3) for direct observations with diagonal weights (M, 3).

    Rows and columns of unobserved components (weight 0) are NaN.
    """
    used = weight > 0.0
    i3 = np.arange(3)
    out = -np.array(q_hat, dtype=np.float64)
    out[:, i3, i3] += 1.0 / np.where(used, weight, 1.0)
    return np.where(used[:, :, None] & used[:, None, :], out, np.nan)


# --- Driver ------------------------------------------------------------------


@limit_blas_threads
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
    motion: ShutterMotion | None = None,
) -> BundleResult:
    """Least-squares bundle adjustment of a strip by the collinearity equations.

    Length: the documentation of its fifteen parameters, what it raises and
    warns, and a worked example; the code is about fifty lines of steps.

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
        Largest number of accepted steps; 0: the start values evaluated, not
        converged (the camera's values one Gauss-Newton step's from them).
    tolerance : float
        Stop when the objective changes by less than ``tolerance`` relative,
        or when the largest correction is below ``tolerance`` (radians, and
        metres relative to the mean point depth below the photos).
    compute_precision : bool
        Compute ``point_std``, ``centre_std`` and ``rotation_std`` (else NaN).
    camera : CameraModel, optional
        Self-calibration: the camera parameters estimated with the block, the
        dense border of the normal equations (method.md 6B, 6C); with the
        correction ``Δ(x; θ)`` (:mod:`strip_aerotri.geometry.camera_model`)
        the measured point's true position ``x̂`` satisfies ``x̂ + Δ(x̂; θ) =
        x(S, R, X)`` and the observation equation is ``x̂ - x_obs``, in the
        observations' space with their sigmas
        (:mod:`strip_aerotri.bundle._observation_space`).
    camera0 : array_like, shape (k,), optional
        Start values of the camera parameters (default 0: the start camera).
    motion : ShutterMotion, optional
        A rolling shutter: one motion of the centre over the readout per
        group of photos, each ray read at its true position's row,
        estimated in the border after the camera's
        (:class:`strip_aerotri.geometry.camera_model.ShutterMotion`; start 0).

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

    How each iteration is solved, the datum test and the precision: the
    module notes.

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
    with compute_workers(int(np.asarray(observations.photo).size)):
        m, p = centres.shape[0], points.shape[0]
        prob = _make_problem(
            observations, centres, rotations, points, control_xyz, control_sigma,
            gnss_centres, gnss_sigma, imu_rotations, imu_sigma, camera, motion,
        )
        state = _start_state(prob, centres, rotations, points, camera0)
        depth = _check_datum_and_sides(prob, state, observations)
        redundancy = prob.n_observations - 6 * m - 3 * p - prob.n_camera - prob.n_motion

        def sigma0_of(cost: float) -> float:
            return float(np.sqrt(cost / redundancy)) if redundancy > 0 else float("nan")

        normals = _normals(prob, state)
        if normals is None:  # _check_datum_and_sides found every point in front
            raise GeometryError("the collinearity equations are not defined at the initial values")
        _check_points(prob, normals, observations.point_ids)
        state, normals, history, iterations, converged = _iterate(
            prob, state, normals, depth, int(max_iterations), tolerance, observations, sigma0_of
        )
        if not converged:
            warnings.warn(
                f"{NOT_CONVERGED} in {max_iterations} iterations "
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
        at_start = int(max_iterations) == 0  # asked for no step: the camera's values are one step's
        precision = _precision_products(prob, state, normals, sigma0, compute_precision, at_start)
        control_used = prob.control_weight > 0
        return BundleResult(
            centres=state.centres,
            rotations=state.rotations,
            points=state.points,
            sigma0=sigma0,
            redundancy=int(redundancy),
            iterations=iterations,
            converged=converged,
            residuals_mm=_as_given(prob, normals.residuals_mm),
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
            image_redundancy=_as_given(prob, precision.image_redundancy),
            camera=precision.camera,
            motion=precision.motion,
        )


def _as_given(prob: _Problem, per_row: FloatArray) -> FloatArray:
    """Values of the rows (K, ...) in the observations' order."""
    out = np.empty_like(per_row)
    out[prob.rows] = per_row
    return out


def _start_state(
    prob: _Problem,
    centres: FloatArray,
    rotations: FloatArray,
    points: FloatArray,
    camera0: ArrayLike | None,
) -> _State:
    """The first state: the given orientations and points, the camera at
    ``camera0`` (default 0), no motion."""
    start_camera = np.zeros(prob.n_camera) if camera0 is None else np.asarray(camera0, float)
    if start_camera.shape != (prob.n_camera,):
        raise ValueError(f"Expected `camera0` of shape ({prob.n_camera},), got {start_camera.shape}")
    return _State(
        centres.copy(),
        rotations.copy(),
        points.copy(),
        start_camera.copy(),
        np.zeros((prob.n_motion // 3, 3)),
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
    check_rotations(rotations, "rotations0")
    if int(max_iterations) < 0:
        raise ValueError(f"Expected `max_iterations` >= 0, got {max_iterations}")
    if not tolerance > 0.0:
        raise ValueError(f"Expected a positive `tolerance`, got {tolerance}")
    return centres, rotations, points


def _check_datum_and_sides(
    prob: _Problem, state: _State, observations: ImageObservations
) -> float:
    """GeometryError when the control, GNSS and IMU leave the datum free or a
    point lies behind a photo at the start values; returns the median depth
    of the points below their photos (the scale of the steps' test)."""
    free = free_motions(
        state.points, state.centres, state.rotations, prob.control_weight, prob.gnss_weight,
        prob.imu_weight,
    )
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
        kk = int(np.argmin(np.where(behind, prob.rows, prob.rows.size)))  # the first observation
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
    chord_from: _Reduced | None = None  # a small full step's factor (_chord)
    for _ in range(max_iterations):
        cost = normals.cost
        while True:
            chord = lam == 0.0 and chord_from is not None
            if chord and chord_from is not None:  # (the second test narrows the type)
                step = _chord(normals, chord_from)
            else:
                step = _solve(prob, normals, lam)
            if lam == 0.0 and not chord:
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
            # the trial's normal equations at once: its cost decides, and an
            # accepted step (the rule) needs them next
            trial_normals = _normals(prob, trial)
            trial_cost = float("inf") if trial_normals is None else trial_normals.cost
            if trial_cost <= cost:
                break
            if chord:  # a chord that does not lower the cost gives way to a full step
                chord_from = None
                continue
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
        if trial is not state and trial_normals is not None:
            iterations += 1
            state, normals = trial, trial_normals
            history.append(sigma0_of(normals.cost))
        # A damped step may be small or gain little without being at the minimum:
        # only an undamped (Gauss-Newton) step can end the iteration.
        if lam == 0.0 and (max_step < tolerance or (cost - trial_cost) <= tolerance * cost):
            return state, normals, history, iterations, True
        small = lam == 0.0 and not chord and max_step < _CHORD_BELOW_MOVE
        chord_from = step if small and prob.n_camera + prob.n_motion == 0 else None
        lam = 0.0 if lam <= 1e-3 else lam / 10.0
    return state, normals, history, iterations, False


class _Precision(NamedTuple):
    point_std: FloatArray  # (P, 3) m
    centre_std: FloatArray  # (M, 3) m
    rotation_std: FloatArray  # (M, 3) rad
    imu_residuals: FloatArray  # (M, 3) rad, log(R_imu.T R)
    gnss_cofactor: FloatArray  # (M, 3, 3)
    imu_cofactor: FloatArray  # (M, 3, 3)
    image_redundancy: FloatArray  # (K, 2)
    camera: CameraEstimate | None = None
    motion: ShutterEstimate | None = None


#: Share of a camera parameter's information left once photos and points are
#: estimated (``C_ii / G_ii``) below which it counts as not determined.
_CAMERA_RANK_TOL = 1e-10


def _check_camera(camera: CameraEstimate) -> None:
    """CameraUndetermined when the orientation absorbs a camera parameter."""
    share = camera.conditional_information / np.maximum(camera.information, 1e-300)
    weak = ~(share > _CAMERA_RANK_TOL)
    if np.any(weak):
        name = camera.names[int(np.flatnonzero(weak)[0])]
        raise CameraUndetermined(
            f"the camera parameter {name} is not determined: the exterior orientation "
            "absorbs it (e.g. c with the flying height over flat ground, x0 and y0 with "
            'the centres); leave it out of self_calibration or use "auto"',
            name,
        )


def _precision_products(
    prob: _Problem,
    state: _State,
    normals: _Normals,
    sigma0: float,
    compute_precision: bool,
    linearised: bool = False,
) -> _Precision:
    """Standard deviations of points and photos and the cofactors of the GNSS and IMU
    residuals (NaN without ``compute_precision``); ``linearised``: the camera's values
    are those of one Gauss-Newton step from ``state``."""
    m, p = prob.n_photos, prob.n_points
    nan_p, nan_m = np.full((p, 3), np.nan), np.full((m, 3), np.nan)
    point_std, centre_std, rotation_std = nan_p, nan_m, nan_m.copy()
    e_imu = _imu_residual(state.rotations, prob.imu_rot)
    gnss_cofactor = np.full((m, 3, 3), np.nan)
    imu_cofactor = np.full((m, 3, 3), np.nan)
    image_redundancy = np.full((prob.photo.size, 2), np.nan)
    camera, motion = None, None
    border_q = np.zeros((0, 0))
    if compute_precision or normals.image.border_jacobian is not None:
        solution = _solve(prob, normals, 0.0, step=linearised).solution  # the factor alone
        border_q = solution.border_cofactor  # without the selected inverse of the band
    k = prob.n_camera
    if prob.camera is not None:
        border = normals.image.border_jacobian
        assert border is not None
        camera = CameraEstimate(
            model=prob.camera,
            values=state.camera + (solution.border_step[:k] if linearised else 0.0),
            cofactor=border_q[:k, :k],
            sigma0=sigma0,
            information=np.einsum("kri,kri->i", border[:, :, :k], border[:, :, :k]),
            conditional_information=np.diag(np.linalg.inv(border_q[:k, :k])),
        )
        _check_camera(camera)
    if prob.motion is not None:
        motion = ShutterEstimate(prob.motion, state.motion, border_q[k:, k:], sigma0)
    if compute_precision:
        cof = solution.cofactors()
        q_blocks = cof.unit
        q_point = np.diagonal(cof.point, axis1=1, axis2=2)
        image_redundancy = cof.redundancy(normals.image)
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
        point_std,
        centre_std,
        rotation_std,
        e_imu,
        gnss_cofactor,
        imu_cofactor,
        image_redundancy,
        camera,
        motion,
    )
