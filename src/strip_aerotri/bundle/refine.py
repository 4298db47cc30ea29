"""Rigorous refinement of a strip-method result by bundle adjustment.

The strip method (partially dependent models, then similarity and
polynomials on the control) delivers every photo's exterior orientation and
every point's ground coordinates.  :func:`refine_bundle` takes them as
initial values of the simultaneous least-squares adjustment of all image
coordinates by the collinearity equations (:func:`strip_aerotri.bundle.bundle_adjust`),
with the ground control and, optionally, GNSS projection centres and IMU
attitudes as weighted observations; gross errors are searched for by data
snooping on the image, control, GNSS and IMU residuals, one rejection (or a
few well-separated image rays) at a time.

Frame
-----
The adjustment runs in a Cartesian frame in metres in which the collinearity
equations hold exactly:

* geocentric route: the ground stage's own local tangent frame
  (``result.ground.frame``, B(142)-(144), X along the strip); its
  work-frame arrays are the initial values;
* projected route with a real CRS: a local tangent frame built the same way,
  at the geocentric centroid of the control, X along the strip (the strip
  method's CRS results are converted to it through ECEF);
* ``crs = "local"``: the site system itself (X, Y, H taken as Cartesian, no
  earth curvature, as in the ground stage).

Plan-only and height-only control have no full position in the frame; their
missing components are taken from the adjusted points and the adjustment is
repeated (warm start, a pass or two) until the frame coordinates of the
control no longer change by more than 1 µm.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Sequence

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..blunders import robust_variance_factor
from ..errors import GeometryError, StripAerotriWarning
from ..frames import LocalTangentFrame, TangentWorkFrame, enu_residuals
from ..geometry.collinearity import image_jacobian, image_vectors
from ..geometry.rotation import matrix_from_opk, opk_from_matrix, rotvec_from_matrix
from ..observations import ControlPoints, GnssCentres, ImageObservations, ImuAttitudes
from ..options import DEFAULT_MAX_ITERATIONS, BlunderOptions
from ..results import (
    AccuracyStatistics,
    FrameRefinement,
    GnssResiduals,
    ImuResiduals,
    RefinedResult,
    Rejection,
    StripResult,
)
from .adjust import bundle_adjust, observed_with_sigma

__all__ = [
    "FrameRefinement",
    "GnssCentres",
    "GnssResiduals",
    "ImuAttitudes",
    "ImuResiduals",
    "RefinedResult",
    "refine_bundle",
    "refine_frame",
]

#: Stage name of the image-coordinate tests in :class:`Rejection` records.
IMAGE_STAGE = "bundle"
#: Stage name of the control tests (shared with the ground stage's options).
CONTROL_STAGE = "control"
#: Stage names of the GNSS centre and IMU attitude tests.
GNSS_STAGE = "gnss"
IMU_STAGE = "imu"
#: Passes for plan / height control in a curved frame stop below this change (m).
_PASS_TOLERANCE_M = 1e-6
_MAX_PASSES = 4
#: Smallest value the photo-unknowns factor of the redundancy numbers may take.
_MIN_PHOTO_FACTOR = 0.05


# --------------------------------------------------------------------------- frame


def _frame_for(
    result: StripResult, control_rows: IntArray, point_index: IntArray
) -> TangentWorkFrame:
    ground = result.ground
    crs = ground.crs
    if ground.frame is not None:
        return TangentWorkFrame(crs, ground.frame, "local tangent frame of the geocentric route")
    if crs.is_local:
        return TangentWorkFrame(crs, None, 'the site system of crs = "local" (X, Y, H Cartesian)')
    # Projected route with a real CRS: a tangent frame at the control centroid.
    pts = result.points[point_index[control_rows]]
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    ecef = crs.to_ecef(pts)
    frame0 = LocalTangentFrame.from_ecef_centroid(ecef, 0.0, crs=crs)
    ends = frame0.ecef2local(crs.to_ecef(result.photo_centres[[0, -1]]))
    azimuth = float(frame0.azimuth_of(ends[1] - ends[0]))
    return TangentWorkFrame(
        crs,
        frame0.with_azimuth(azimuth),
        "local tangent frame at the control centroid, X along the strip",
    )


# --------------------------------------------------------------------------- tests


def _point_leverage(
    obs: ImageObservations,
    centres: FloatArray,
    rotations: FloatArray,
    points: FloatArray,
    control_weight: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Leverage of each image coordinate on its own point, photos held fixed.

    Returns ``h`` (K, 2), the diagonal of ``B V^-1 B.T`` per observation with
    the whitened point Jacobian ``B`` and the point's normal block ``V``
    (image rays plus control weights), and ``V^-1`` diagonals (P, 3).
    """
    photo, point = obs.photo, obs.point
    rot = rotations[photo]
    d_v = image_jacobian(image_vectors(centres[photo], rot, points[point]), obs.principal_distance)
    b = np.einsum("kab,kcb->kac", d_v, rot) / np.asarray(obs.sigma)[:, None, None]
    p = points.shape[0]
    normal = np.zeros((p, 3, 3))
    np.add.at(normal, point, np.swapaxes(b, 1, 2) @ b)
    i3 = np.arange(3)
    normal[:, i3, i3] += control_weight
    v_inv = np.linalg.inv(normal)
    h = np.einsum("kai,kij,kaj->ka", b, v_inv[point], b)
    return h, np.diagonal(v_inv, axis1=1, axis2=2)


def _compact(
    obs: ImageObservations, keep_obs: BoolArray, point_used: BoolArray
) -> tuple[ImageObservations, IntArray, IntArray]:
    """Observations of the used points only, points renumbered.

    Returns the sub-observations, the rows of ``obs`` they came from and the
    original point index of each new point.
    """
    rows = np.flatnonzero(keep_obs & point_used[obs.point])
    points = np.flatnonzero(point_used)
    new_index = np.full(point_used.shape[0], -1, dtype=np.intp)
    new_index[points] = np.arange(points.size)
    sub = ImageObservations(
        photo_ids=obs.photo_ids,
        point_ids=tuple(obs.point_ids[i] for i in points),
        photo=obs.photo[rows],
        point=new_index[obs.point[rows]],
        xy=obs.xy[rows],
        sigma=np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), obs.photo.shape)[rows],
        principal_distance=obs.principal_distance,
    )
    return sub, rows, points


def _separated(candidates: list[tuple[float, int]], photo: IntArray, window: int) -> list[int]:
    """Greedy pick of failing observations, largest first, pairwise more than
    ``window`` photos apart (so that no two share a point)."""
    chosen: list[int] = []
    taken: list[int] = []
    for _, k in sorted(candidates, reverse=True):
        j = int(photo[k])
        if all(abs(j - t) > window for t in taken):
            chosen.append(k)
            taken.append(j)
    return chosen


def refine_frame(
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
    blunders: BlunderOptions | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    compute_precision: bool = True,
    observation_used: ArrayLike | None = None,
    control_used: ArrayLike | None = None,
    gnss_axes: ArrayLike | None = None,
    gnss_used: ArrayLike | None = None,
    imu_used: ArrayLike | None = None,
) -> FrameRefinement:
    """Bundle adjustment in a Cartesian frame with data snooping.

    Parameters
    ----------
    observations : ImageObservations
        K image observations (mm) of P points on M photos.
    centres0 : array_like, shape (M, 3)
        Initial projection centres, metres.
    rotations0 : array_like, shape (M, 3, 3)
        Initial rotations, image -> frame.
    points0 : array_like, shape (P, 3)
        Initial points, metres; rows with NaN are left out (no initial value).
    control_xyz, control_sigma : array_like, shapes (P, 3), optional
        Control coordinates in the frame, NaN where not given, and their
        standard deviations (m).
    gnss_centres, gnss_sigma : array_like, shapes (M, 3), optional
        Observed centres in the frame (NaN where none) and sigmas (m).
    imu_rotations : array_like, shape (M, 3, 3), optional
        Observed rotations image -> frame (NaN matrices where none).
    imu_sigma : float or array_like, shape (M, 3), optional
        Their standard deviations, radians.
    blunders : BlunderOptions, optional
        ``action``, ``alpha``, critical values (stages ``"bundle"`` for the
        image coordinates, ``"control"`` for the control, ``"gnss"`` and
        ``"imu"`` for the GNSS centres and IMU attitudes), ``max_fraction``,
        excluded points and observations.
    max_iterations : int
        Per adjustment.
    compute_precision : bool
        Standard deviations of points and photos (and exact control tests).
    observation_used : array_like of bool, shape (K,), optional
        Observations to start with (default all but the excluded ones).
    control_used : array_like of bool, shape (P, 3), optional
        Control components to start with (default all given).
    gnss_axes : array_like, shape (M, 3, 3), optional
        Directions along which the GNSS centres are tested, as the columns
        of a rotation east-north-up -> frame at each centre (the components
        are named ``"E"``, ``"N"``, ``"U"`` in the rejections); default the
        frame axes.
    gnss_used, imu_used : array_like of bool, shape (M,), optional
        GNSS centres / IMU attitudes to start with (default all given).

    Returns
    -------
    FrameRefinement

    Raises
    ------
    GeometryError
        As :func:`~strip_aerotri.bundle.bundle_adjust`, or more than
        ``max_fraction`` of the image observations, of the control, of the
        GNSS centres or of the IMU attitudes fail.

    Notes
    -----
    Test values are Baarda's ``w = v / (sigma sqrt(r))`` with the a priori
    sigma; the image tests are divided by the square root of their robust
    variance factor (:func:`~strip_aerotri.blunders.robust_variance_factor`),
    the control tests are not (the control's stated accuracy is what is
    tested, and over a few dozen control components with small redundancy
    numbers one blunder spreads to its neighbours and would inflate the
    factor).

    *Control*: ``r = 1 - q / sigma_c**2`` with the cofactor ``q`` of the
    adjusted coordinate (exact; with ``compute_precision=False`` ``q`` is
    approximated by the point's own 3 x 3 block, photos held fixed).

    *Image coordinates*: exact redundancy numbers need the photo-by-photo
    blocks of the inverse normal matrix for every observation; they are
    approximated by ``r = (1 - h) rho``, where ``h`` is the exact leverage of
    the coordinate on its own point with the photos held fixed and
    ``rho = 1 - 6 M / sum(1 - h)`` spreads the photos' unknowns evenly over
    the image coordinates (so that the numbers add up to the image share of
    the redundancy).  On the 12-photo film strip the approximation is within
    0.1 of the exact numbers (tests/test_refine.py).

    *GNSS centres and IMU attitudes* (with ``compute_precision`` only): the
    exact directional tests of :func:`_directional_tests` from the residual
    cofactors of the bundle (``BundleResult.gnss_residual_cofactor``,
    ``imu_residual_cofactor``), at the a priori sigmas, along ``gnss_axes``
    for GNSS and about the image axes for IMU; critical values of stages
    ``"gnss"`` and ``"imu"`` (Bonferroni over three components per used
    photo).  A photo's test value is its largest ``|w|``.

    Rejection: the largest ``|w| / critical`` over all four kinds is taken.
    A control component is rejected alone (a plan point loses X and Y
    together), a GNSS centre or an IMU attitude as a whole (its three
    components).  Image
    observations (both coordinates of a ray) are rejected several per round:
    the failing ones, largest first, as long as their photos are more than
    ``n`` photos apart, ``n`` the largest number of photos that see one point
    (so no two rejections of a round share a point or a photo).  A point
    left with one ray (and no full control) is dropped.  The adjustment is
    then solved again from the last solution, until nothing fails.
    """
    blunders = blunders or BlunderOptions()
    obs = observations
    k_all = obs.photo.shape[0]
    m = len(obs.photo_ids)
    p = len(obs.point_ids)
    centres = np.array(centres0, dtype=np.float64)
    rotations = np.array(rotations0, dtype=np.float64)
    points = np.array(points0, dtype=np.float64)
    if points.shape != (p, 3):
        raise ValueError(f"Expected `points0` to have shape {(p, 3)}, got {points.shape}")
    if centres.shape != (m, 3) or rotations.shape != (m, 3, 3):
        raise ValueError(
            f"Expected `centres0` (M, 3) and `rotations0` (M, 3, 3) with M = {m}, got "
            f"{centres.shape}, {rotations.shape}"
        )
    sigma_img = np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), (k_all,))

    # Control in the frame and its weights.
    if control_xyz is None:
        c_xyz = np.full((p, 3), np.nan)
        c_sig = np.full((p, 3), np.inf)
    else:
        c_xyz, c_sig = observed_with_sigma(
            control_xyz, control_sigma, (p, 3), "control_xyz", "control_sigma"
        )
    given = np.isfinite(c_xyz) & np.isfinite(c_sig)
    if np.any(c_sig[given] <= 0):
        raise ValueError("Expected positive standard deviations for `control_xyz`")

    # Starting sets.
    keep = np.ones(k_all, bool) if observation_used is None else np.array(observation_used, bool)
    if keep.shape != (k_all,):
        raise ValueError(f"Expected `observation_used` to have shape {(k_all,)}")
    ctrl_on = given.copy() if control_used is None else np.array(control_used, bool) & given
    excluded_points, excluded_obs = blunders.excluded(obs)
    rejected_before = ~keep & ~excluded_obs  # by an earlier pass's tests
    keep &= ~excluded_obs
    ctrl_on[excluded_points] = False
    has_start = np.all(np.isfinite(points), axis=1)
    obs_rejected = np.zeros(k_all, bool)
    ctrl_rejected = np.zeros((p, 3), bool)

    # GNSS centres and IMU attitudes: given, in use, test directions.
    g_xyz = i_rot = None
    g_sig = i_sig = np.full((m, 3), np.inf)
    g_given = np.zeros(m, bool)
    i_given = np.zeros(m, bool)
    if gnss_centres is not None:
        g_xyz, g_sig = observed_with_sigma(
            gnss_centres, gnss_sigma, (m, 3), "gnss_centres", "gnss_sigma"
        )
        g_given = np.any(np.isfinite(g_xyz) & np.isfinite(g_sig), axis=1)
    if imu_rotations is not None:
        i_rot, i_sig = observed_with_sigma(
            imu_rotations, imu_sigma, (m, 3, 3), "imu_rotations", "imu_sigma"
        )
        i_given = np.all(np.isfinite(i_rot), axis=(1, 2)) & np.any(np.isfinite(i_sig), axis=1)
    g_on = g_given & _photo_flags(gnss_used, m, "gnss_used")
    i_on = i_given & _photo_flags(imu_used, m, "imu_used")
    g_rejected = g_given & ~g_on
    i_rejected = i_given & ~i_on
    if gnss_axes is None:
        g_axes = np.broadcast_to(np.eye(3), (m, 3, 3))
    else:
        g_axes = np.asarray(gnss_axes, dtype=np.float64)
        if g_axes.shape != (m, 3, 3):
            raise ValueError(f"Expected `gnss_axes` to have shape {(m, 3, 3)}, got {g_axes.shape}")

    def used_points() -> BoolArray:
        rays = np.bincount(obs.point[keep], minlength=p)
        full = np.all(ctrl_on, axis=1)
        # A point that lost a ray to a rejection keeps a check on the rest only
        # with three rays left: with two, the ray rejected may have been the
        # good one (a wrong ray pulls the point towards itself, and a good
        # neighbour can show the larger w) and nothing would show it.
        lost = np.bincount(obs.point[obs_rejected | rejected_before], minlength=p) > 0
        need = np.where(lost, 3, 2)
        return has_start & ((rays >= need) | ((rays >= need - 1) & full))

    rejections: list[Rejection] = []
    rounds = 0
    iterations = 0
    n_img_start = int(keep.sum())
    n_ctrl_start = int(ctrl_on.sum())
    window = int(np.max(np.bincount(obs.point, minlength=p), initial=1))
    previous_effect: int | None = None
    state = (centres, rotations, points)
    while True:
        pt_used = used_points()
        sub, rows, pts = _compact(obs, keep, pt_used)
        c_sub = np.where(ctrl_on[pts], c_xyz[pts], np.nan)
        res = bundle_adjust(
            sub,
            state[0],
            state[1],
            state[2][pts],
            control_xyz=c_sub,
            control_sigma=np.where(ctrl_on[pts], c_sig[pts], np.inf),
            gnss_centres=None if g_xyz is None else np.where(g_on[:, None], g_xyz, np.nan),
            gnss_sigma=None if g_xyz is None else g_sig,
            imu_rotations=None if i_rot is None else np.where(i_on[:, None, None], i_rot, np.nan),
            imu_sigma=None if i_rot is None else i_sig,
            max_iterations=max_iterations,
            compute_precision=compute_precision,
        )
        rounds += 1
        iterations += res.iterations
        new_points = np.full((p, 3), np.nan)
        new_points[pts] = res.points
        # keep initial values of dropped points for a possible later round
        state = (res.centres, res.rotations, np.where(pt_used[:, None], new_points, points))
        if previous_effect is not None:
            r = rejections[previous_effect]
            rejections[previous_effect] = dataclasses.replace(
                r, effect=f"{r.effect}, sigma0 {res.sigma0:.4g} after"
            )
            for j in range(previous_effect + 1, len(rejections)):
                rejections[j] = dataclasses.replace(
                    rejections[j], effect=f"{rejections[j].effect}, sigma0 {res.sigma0:.4g} after"
                )

        # Residuals of every observation of a used point (rejected ones included).
        tested = pt_used[obs.point]
        v_all = np.full((k_all, 2), np.nan)
        rows_t = np.flatnonzero(tested)
        vv = np.einsum(
            "kji,kj->ki",
            res.rotations[obs.photo[rows_t]],
            new_points[obs.point[rows_t]] - res.centres[obs.photo[rows_t]],
        )
        v_all[rows_t] = -obs.principal_distance * vv[:, :2] / vv[:, 2:3] - obs.xy[rows_t]

        weight_sub = np.where(ctrl_on[pts], 1.0 / np.where(ctrl_on[pts], c_sig[pts], 1.0) ** 2, 0)
        h_sub, vinv_diag = _point_leverage(sub, res.centres, res.rotations, res.points, weight_sub)
        free = float(np.sum(1.0 - h_sub))
        rho = max(_MIN_PHOTO_FACTOR, 1.0 - 6.0 * m / free) if free > 0 else _MIN_PHOTO_FACTOR
        r_img = np.full((k_all, 2), np.nan)
        r_img[rows] = np.clip((1.0 - h_sub) * rho, 1e-12, 1.0)
        w_img = np.full((k_all, 2), np.nan)
        w_img[rows] = v_all[rows] / (sigma_img[rows, None] * np.sqrt(r_img[rows]))
        factor_img = robust_variance_factor(w_img[rows].ravel())
        w_img /= np.sqrt(factor_img)

        ctrl_res = np.full((p, 3), np.nan)
        ctrl_res[given] = np.where(pt_used[:, None], new_points, np.nan)[given] - c_xyz[given]
        if compute_precision and np.isfinite(res.sigma0) and res.sigma0 > 0:
            q = np.full((p, 3), np.nan)
            q[pts] = (res.point_std / res.sigma0) ** 2
        else:
            q = np.full((p, 3), np.nan)
            q[pts] = vinv_diag
        r_ctrl = np.where(ctrl_on, 1.0 - q / np.where(given, c_sig, 1.0) ** 2, np.nan)
        r_ctrl = np.where(ctrl_on, np.clip(r_ctrl, 1e-12, 1.0), np.nan)
        w_ctrl = np.where(ctrl_on, ctrl_res / (c_sig * np.sqrt(r_ctrl)), np.nan)
        # Control is tested at its stated sigmas: with a few dozen control
        # components and small redundancy numbers a single blunder spreads to its
        # neighbours and would inflate a robust variance factor.

        result = FrameRefinement(
            centres=res.centres,
            rotations=res.rotations,
            points=new_points,
            point_used=pt_used,
            observation_used=keep & tested,
            control_used=ctrl_on & pt_used[:, None],
            observation_rejected=obs_rejected.copy(),
            control_rejected=ctrl_rejected.copy(),
            image_residuals_mm=v_all,
            image_w=w_img,
            image_redundancy=r_img,
            control_residuals=ctrl_res,
            control_w=w_ctrl,
            point_std=_expand(res.point_std, pts, p),
            centre_std=res.centre_std,
            rotation_std=res.rotation_std,
            sigma0=res.sigma0,
            redundancy=res.redundancy,
            iterations=iterations,
            rounds=rounds,
            converged=res.converged,
            rejections=tuple(rejections),
            bundle=res,
            gnss_used=g_on.copy(),
            gnss_rejected=g_rejected.copy(),
            imu_used=i_on.copy(),
            imu_rejected=i_rejected.copy(),
        )
        if not blunders.testing:
            return result

        # Image tests: per ray, the larger of |w_x|, |w_y| among used observations.
        crit_img = blunders.critical(IMAGE_STAGE, int(np.count_nonzero(keep & tested)) * 2)
        ray_w = np.fmax(np.abs(w_img[:, 0]), np.abs(w_img[:, 1]))
        ray_w = np.where(keep & tested, ray_w, np.nan)
        fail_img = np.flatnonzero(ray_w > crit_img)
        # Control tests: plan (max of X, Y) and height.
        crit_ctrl = blunders.critical(CONTROL_STAGE, int(np.count_nonzero(ctrl_on)))
        plan_on = ctrl_on[:, 0] & ctrl_on[:, 1]
        plan_w = np.where(plan_on, np.fmax(np.abs(w_ctrl[:, 0]), np.abs(w_ctrl[:, 1])), np.nan)
        h_w = np.where(ctrl_on[:, 2], np.abs(w_ctrl[:, 2]), np.nan)
        found: list[tuple[float, str, int]] = [
            (float(ray_w[k]) / crit_img, "image", int(k)) for k in fail_img
        ]
        found += [
            (float(plan_w[i]) / crit_ctrl, "plan", int(i))
            for i in np.flatnonzero(plan_w > crit_ctrl)
        ]
        found += [
            (float(h_w[i]) / crit_ctrl, "height", int(i)) for i in np.flatnonzero(h_w > crit_ctrl)
        ]
        # GNSS centres (along gnss_axes, m) and IMU attitudes (about the image
        # axes, reported in degrees): kind -> stage, w, residuals along the
        # axes, critical value, component names, unit, residual factor.
        photo_stages = {
            "gnss": (
                GNSS_STAGE,
                *_photo_tests(
                    -res.gnss_residuals, res.gnss_residual_cofactor, g_sig, g_axes, g_on
                ),
                blunders.critical(GNSS_STAGE, 3 * int(np.count_nonzero(g_on))),
                ("E", "N", "U"),
                "m",
                1.0,
            ),
            "imu": (
                IMU_STAGE,
                *_photo_tests(
                    -res.imu_residuals, res.imu_residual_cofactor, i_sig, np.eye(3), i_on
                ),
                blunders.critical(IMU_STAGE, 3 * int(np.count_nonzero(i_on))),
                ("about x", "about y", "about z"),
                "deg",
                float(np.degrees(1.0)),
            ),
        }
        for kind, (_, w_k, _, crit_k, *_) in photo_stages.items():
            photo_w = np.max(np.where(np.isfinite(w_k), np.abs(w_k), -1.0), axis=1)
            found += [
                (float(photo_w[j]) / crit_k, kind, int(j))
                for j in np.flatnonzero(photo_w > crit_k)
            ]
        if not found:
            return result
        effect = f"sigma0 {res.sigma0:.4g} before"
        new_rejections: list[Rejection] = []
        worst = max(found)
        if worst[1] == "image":
            picks = _separated([(f[0], f[2]) for f in found if f[1] == "image"], obs.photo, window)
        else:
            picks = [worst[2]]
        if not blunders.rejecting:
            picks_all = [(f[1], f[2]) for f in sorted(found, reverse=True)]
        else:
            picks_all = [(worst[1], k) for k in picks]
        for kind, k in picks_all:
            if kind in photo_stages:
                stage, w_k, v_k, crit_k, names, unit, factor = photo_stages[kind]
                comp = int(np.nanargmax(np.abs(w_k[k])))
                new_rejections.append(
                    Rejection(
                        stage=stage,
                        point="",
                        photos=(obs.photo_ids[k],),
                        component=names[comp],
                        residual=factor * float(v_k[k, comp]),
                        unit=unit,
                        w=float(abs(w_k[k, comp])),
                        critical=crit_k,
                        applied=blunders.rejecting,
                        effect=f"bundle adjustment, {effect}",
                    )
                )
            elif kind == "image":
                comp = 0 if abs(w_img[k, 0]) >= abs(w_img[k, 1]) else 1
                new_rejections.append(
                    Rejection(
                        stage=IMAGE_STAGE,
                        point=obs.point_ids[obs.point[k]],
                        photos=(obs.photo_ids[obs.photo[k]],),
                        component="xy"[comp],
                        residual=float(v_all[k, comp] * 1000.0),
                        unit="µm",
                        w=float(abs(w_img[k, comp])),
                        critical=crit_img,
                        applied=blunders.rejecting,
                        effect=effect,
                    )
                )
            else:
                if kind == "plan":
                    resid = float(np.hypot(ctrl_res[k, 0], ctrl_res[k, 1]))
                    wv = float(plan_w[k])
                else:
                    resid = float(-ctrl_res[k, 2])
                    wv = float(h_w[k])
                new_rejections.append(
                    Rejection(
                        stage=CONTROL_STAGE,
                        point=obs.point_ids[k],
                        photos=(),
                        component=kind,
                        residual=resid,
                        unit="m",
                        w=wv,
                        critical=crit_ctrl,
                        applied=blunders.rejecting,
                        effect=f"bundle adjustment, {effect}",
                    )
                )
        if not blunders.rejecting:
            return dataclasses.replace(result, rejections=tuple(rejections + new_rejections))
        previous_effect = len(rejections)
        rejections.extend(new_rejections)
        for kind, k in picks_all:
            if kind == "image":
                keep[k] = False
                obs_rejected[k] = True
            elif kind == "plan":
                ctrl_on[k, :2] = False
                ctrl_rejected[k, :2] = True
            elif kind == "height":
                ctrl_on[k, 2] = False
                ctrl_rejected[k, 2] = True
            elif kind == "gnss":
                g_on[k] = False
                g_rejected[k] = True
            else:
                i_on[k] = False
                i_rejected[k] = True
        n_img_rej = n_img_start - int(keep.sum())
        if n_img_rej > blunders.max_fraction * max(n_img_start, 1):
            raise GeometryError(
                f"bundle adjustment: more than {blunders.max_fraction:.0%} of the image "
                f"observations fail the blunder test ({n_img_rej} of {n_img_start}); the "
                "observations cannot be trusted"
            )
        n_ctrl_rej = n_ctrl_start - int(ctrl_on.sum())
        if n_ctrl_rej > blunders.max_fraction * max(n_ctrl_start, 1):
            raise GeometryError(
                f"bundle adjustment: more than {blunders.max_fraction:.0%} of the control "
                "observations fail the blunder test; the control cannot be trusted"
            )
        for stage, what, given_k, rejected_k in (
            (GNSS_STAGE, "GNSS centres", g_given, g_rejected),
            (IMU_STAGE, "IMU attitudes", i_given, i_rejected),
        ):
            n_given_k = int(np.count_nonzero(given_k))
            n_rej_k = int(np.count_nonzero(rejected_k))
            if n_rej_k > blunders.max_fraction * max(n_given_k, 1):
                raise GeometryError(
                    f"bundle adjustment, stage {stage!r}: more than {blunders.max_fraction:.0%} "
                    f"of the {what} fail the blunder test ({n_rej_k} of {n_given_k} photos); "
                    f"the {what} cannot be trusted"
                )


def _photo_flags(values: ArrayLike | None, m: int, name: str) -> BoolArray:
    """Per-photo booleans (M,), all True when not given."""
    if values is None:
        return np.ones(m, bool)
    flags = np.array(values, dtype=bool)
    if flags.shape != (m,):
        raise ValueError(f"Expected `{name}` to have shape {(m,)}, got {flags.shape}")
    return flags


def _photo_tests(
    v: FloatArray, q_vv: FloatArray, sigma: FloatArray, axes: FloatArray, on: BoolArray
) -> tuple[FloatArray, FloatArray]:
    """w-tests and residuals along ``axes`` of the direct photo observations in use.

    ``v`` (M, 3) observed minus adjusted in the frame, ``q_vv`` (M, 3, 3)
    residual cofactors, ``sigma`` (M, 3), ``axes`` (M, 3, 3) or (3, 3)
    (columns: test directions in the frame), ``on`` (M,) the photos whose
    observation is in the adjustment.  Returns ``w`` and the residuals along
    the axes, both (M, 3), NaN for photos not in use.
    """
    m = v.shape[0]
    w = np.full((m, 3), np.nan)
    v_axes = np.full((m, 3), np.nan)
    rows = np.flatnonzero(on)
    if rows.size:
        a = np.broadcast_to(axes, (m, 3, 3))[rows]
        # unobserved components (weight 0) carry NaN: they take no part
        v_rows = np.nan_to_num(v[rows], nan=0.0)
        q_rows = np.nan_to_num(q_vv[rows], nan=0.0)  # all NaN without precision: w NaN
        _, w[rows] = _directional_tests(v_rows, q_rows, 1.0 / sigma[rows] ** 2, a)
        v_axes[rows] = np.einsum("gia,gi->ga", a, v_rows)
    return w, v_axes


def _expand(values: FloatArray, index: IntArray, n: int) -> FloatArray:
    out = np.full((n, *values.shape[1:]), np.nan)
    out[index] = values
    return out


# --------------------------------------------------------------------------- GNSS / IMU


def _directional_tests(
    v: FloatArray, q_vv: FloatArray, weight: FloatArray, axes: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Redundancy numbers and w-tests of direct observations along given axes.

    Parameters
    ----------
    v : ndarray, shape (G, 3)
        Observed minus adjusted, frame axes.
    q_vv : ndarray, shape (G, 3, 3)
        Cofactor matrices of the residuals, frame axes.
    weight : ndarray, shape (G, 3)
        Diagonal weights ``1 / sigma**2`` along the frame axes.
    axes : ndarray, shape (G, 3, 3)
        Columns: the test directions as unit vectors in the frame.

    Returns
    -------
    redundancy, w : ndarray, shape (G, 3)
        ``diag(Aᵀ Q_vv P A)`` and ``dᵀ P v / sqrt(dᵀ P Q_vv P d)`` per column
        ``d`` of ``A``; w is NaN where the component has no redundancy.
    """
    pa = weight[:, :, None] * axes  # P A
    redundancy = np.einsum("gia,gij,gja->ga", axes, q_vv, pa)
    denominator = np.einsum("gia,gij,gja->ga", pa, q_vv, pa)
    numerator = np.einsum("gia,gi->ga", pa, v)
    ok = denominator > 1e-12 * np.einsum("gia,gia->ga", pa, axes)
    w = np.where(ok, numerator / np.sqrt(np.where(ok, denominator, 1.0)), np.nan)
    return redundancy, w


def _gnss_residuals(
    gnss: GnssCentres,
    lookup: IntArray,
    observed_frame: FloatArray,
    sigma: FloatArray,
    fr: FrameRefinement,
    enu2frame: FloatArray,
    strip_ids: Sequence[str],
    options: BlunderOptions,
) -> GnssResiduals:
    """Residuals and tests of the GNSS centres in the final adjustment.

    ``lookup`` (given rows -> strip photo or -1), ``observed_frame`` (M, 3)
    and ``sigma`` (M, 3) as passed to the bundle, ``enu2frame`` (M, 3, 3)
    at the adjusted centres.  Rejected centres (``fr.gnss_rejected``) keep
    their residual, observed minus adjusted; their redundancy and w are NaN
    (the bundle has no cofactor for them).
    """
    index = np.flatnonzero(np.all(np.isfinite(observed_frame), axis=1))
    v_frame = observed_frame[index] - fr.centres[index]  # observed - adjusted
    axes = enu2frame[index]
    weight = 1.0 / sigma[index] ** 2
    q_vv = fr.bundle.gnss_residual_cofactor[index]  # NaN for rejected centres
    redundancy, w = _directional_tests(v_frame, q_vv, weight, axes)
    rejected = fr.gnss_rejected[index] if fr.gnss_rejected.size else np.zeros(index.size, bool)
    return GnssResiduals(
        photo_ids=tuple(strip_ids[j] for j in index),
        photo_index=index,
        n_given=len(gnss.photo_ids),
        unmatched=tuple(pid for pid, j in zip(gnss.photo_ids, lookup, strict=True) if j < 0),
        sigma_xy=sigma[index, 0],
        sigma_z=sigma[index, 2],
        residuals=np.einsum("gia,gi->ga", axes, v_frame),
        redundancy=redundancy,
        w=w,
        critical=options.critical(GNSS_STAGE, 3 * int(np.count_nonzero(~rejected))),
        rejected=rejected,
    )


def _imu_residuals(
    imu: ImuAttitudes,
    lookup: IntArray,
    observed_frame: FloatArray,
    sigma: FloatArray,
    fr: FrameRefinement,
    opk_adjusted: FloatArray,
    strip_ids: Sequence[str],
    options: BlunderOptions,
) -> ImuResiduals:
    """Residuals and tests of the IMU attitudes in the final adjustment.

    ``lookup`` (given rows -> strip photo or -1), ``observed_frame``
    (M, 3, 3) and ``sigma`` (M, 3) as passed to the bundle;
    ``opk_adjusted`` (M, 3) the adjusted omega, phi, kappa (image -> ENU).
    Rejected attitudes as in :func:`_gnss_residuals`.
    """
    m = observed_frame.shape[0]
    index = np.flatnonzero(np.all(np.isfinite(observed_frame), axis=(1, 2)))
    # log(R_adj.T R_imu): observed - adjusted, about the adjusted photo's axes
    v = rotvec_from_matrix(np.swapaxes(fr.rotations[index], 1, 2) @ observed_frame[index])
    ok = lookup >= 0
    opk_observed = np.full((m, 3), np.nan)
    opk_observed[lookup[ok]] = imu.opk[ok]
    d_opk = opk_observed[index] - opk_adjusted[index]
    d_opk = (d_opk + np.pi) % (2.0 * np.pi) - np.pi
    weight = 1.0 / sigma[index] ** 2
    axes = np.broadcast_to(np.eye(3), (index.size, 3, 3))
    q_vv = fr.bundle.imu_residual_cofactor[index]  # NaN for rejected attitudes
    redundancy, w = _directional_tests(v, q_vv, weight, axes)
    rejected = fr.imu_rejected[index] if fr.imu_rejected.size else np.zeros(index.size, bool)
    return ImuResiduals(
        photo_ids=tuple(strip_ids[j] for j in index),
        photo_index=index,
        n_given=len(imu.photo_ids),
        unmatched=tuple(pid for pid, j in zip(imu.photo_ids, lookup, strict=True) if j < 0),
        sigma=sigma[index, 0],
        residuals=v,
        opk_differences=d_opk,
        redundancy=redundancy,
        w=w,
        critical=options.critical(IMU_STAGE, 3 * int(np.count_nonzero(~rejected))),
        rejected=rejected,
    )


# --------------------------------------------------------------------------- driver


def _photo_lookup(ids: Sequence[str], strip_ids: Sequence[str], what: str) -> IntArray:
    lookup = {pid: j for j, pid in enumerate(strip_ids)}
    index = np.array([lookup.get(pid, -1) for pid in ids], dtype=np.intp)
    unknown = [pid for pid, j in zip(ids, index, strict=True) if j < 0]
    if unknown:
        more = f" and {len(unknown) - 5} more" if len(unknown) > 5 else ""
        warnings.warn(
            f"{what}: photo(s) {', '.join(map(repr, unknown[:5]))}{more} are not in the strip; "
            "ignored",
            StripAerotriWarning,
            stacklevel=3,
        )
    return index


def refine_bundle(
    result: StripResult,
    *,
    control: ControlPoints | None = None,
    gnss: GnssCentres | None = None,
    imu: ImuAttitudes | None = None,
    blunders: BlunderOptions | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    compute_precision: bool = True,
) -> RefinedResult:
    """Refine a strip-method result by a rigorous bundle adjustment.

    Parameters
    ----------
    result : StripResult
        From :func:`~strip_aerotri.pipeline.triangulate`; its photos and
        points are the initial values, its control the ground control
        (check points are compared, never used).
    control : ControlPoints, optional
        Control and check points (same CRS) to use instead of
        ``result.control``: e.g. fewer ground points once GNSS centres carry
        the datum; the strip result then only supplies initial values.
    gnss : GnssCentres, optional
        Observed projection centres in the control CRS.
    imu : ImuAttitudes, optional
        Observed attitudes (omega, phi, kappa, image -> local ENU).
    blunders : BlunderOptions, optional
        Data snooping of the image coordinates (stage ``"bundle"``), the
        control (stage ``"control"``), the GNSS centres (stage ``"gnss"``)
        and the IMU attitudes (stage ``"imu"``); default: test and reject.
        A rejected GNSS centre or IMU attitude leaves the adjustment as a
        whole (its three components); it stays listed in ``gnss`` / ``imu``
        with ``rejected`` True.
    max_iterations : int
        Largest number of bundle steps per adjustment.
    compute_precision : bool
        Standard deviations of points and centres (costs ``6 M`` sparse
        solves; see :func:`~strip_aerotri.bundle.bundle_adjust`).

    Returns
    -------
    RefinedResult

    Raises
    ------
    GeometryError
        The datum is not defined, a point or photo is not determined, or
        too many observations fail the blunder tests.
    ConvergenceError
        The adjustment diverges.

    Notes
    -----
    The frame is described in the module docstring.  Control rows enter as
    observations of their point's frame coordinates with the control's
    ``sigma_xy`` (X, Y) and ``sigma_h`` (Z); plan-only and height-only
    components are completed from the adjusted point and iterated (passes)
    in a curved frame.  Photo centres and attitudes observed by GNSS and IMU
    are converted into the frame (attitudes through east-north-up at the
    centre).  Points the strip method did not triangulate have no initial
    value and are left out (NaN).

    Examples
    --------
    >>> from strip_aerotri.simulate import simulate_strip
    >>> from strip_aerotri.pipeline import triangulate
    >>> from strip_aerotri.options import GroundOptions
    >>> sim = simulate_strip(12, seed=1, crs="local")
    >>> strip = triangulate(sim.observations, sim.control, sim.crs,
    ...                     ground_options=GroundOptions(route="projected"))
    >>> refined = refine_bundle(strip)
    >>> bool(refined.converged), len(refined.rejections)
    (True, 0)
    >>> bool(refined.check_statistics.rmse_plan < strip.check_statistics.rmse_plan)
    True
    """
    t_start = time.perf_counter()
    obs = result.strip.observations
    control = result.control if control is None else control
    m, p = obs.n_photos, obs.n_points
    ground = result.ground

    point_lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    row_point = np.array([point_lookup.get(pid, -1) for pid in control.point_ids], dtype=np.intp)
    seen = row_point >= 0
    has_point = np.zeros(len(control.point_ids), bool)
    has_point[seen] = np.all(np.isfinite(result.points[row_point[seen]]), axis=1)
    frame = _frame_for(result, np.flatnonzero(has_point), row_point)

    # Initial values in the frame.
    if ground.frame is not None or frame.frame is None:
        if ground.frame is not None:
            points0 = np.array(ground.points_work)
            centres0 = np.array(ground.photo_centres_work)
            rotations0 = np.array(ground.photo_rotations_work)
        else:
            points0 = np.array(result.points)
            centres0 = np.array(result.photo_centres)
            rotations0 = np.array(ground.photo_rotations_enu)
    else:
        ok = np.all(np.isfinite(result.points), axis=1)
        points0 = np.full((p, 3), np.nan)
        points0[ok] = frame.to_work(result.points[ok])
        centres0 = frame.to_work(result.photo_centres)
        rotations0 = frame.work_from_enu(result.photo_centres) @ ground.photo_rotations_enu

    # Control rows -> per-point observations (check points never used).
    rows = np.flatnonzero(has_point)
    idx = row_point[rows]
    if np.unique(idx).size != idx.size:
        raise ValueError("a point occurs twice in the control")
    use_xy = control.uses_xy[rows]
    use_h = control.uses_h[rows]
    check = control.is_check[rows]
    given_crs = control.xyz[rows]
    sig = np.full((p, 3), np.inf)
    sig[idx, 0] = sig[idx, 1] = np.where(use_xy, control.sigma_xy[rows], np.inf)
    sig[idx, 2] = np.where(use_h, control.sigma_h[rows], np.inf)
    mask = np.zeros((p, 3), bool)
    mask[idx, 0] = mask[idx, 1] = use_xy
    mask[idx, 2] = use_h

    # GNSS and IMU in the frame.
    gnss_xyz = gnss_sig = imu_rot = imu_sig = None
    gnss_lookup = imu_lookup = np.zeros(0, dtype=np.intp)
    if gnss is not None:
        j = gnss_lookup = _photo_lookup(gnss.photo_ids, obs.photo_ids, "GNSS centres")
        ok = j >= 0
        gnss_xyz = np.full((m, 3), np.nan)
        gnss_xyz[j[ok]] = frame.to_work(gnss.xyz[ok])
        gnss_sig = np.full((m, 3), np.inf)
        gnss_sig[j[ok], 0] = gnss_sig[j[ok], 1] = gnss.sigma_xy[ok]
        gnss_sig[j[ok], 2] = gnss.sigma_z[ok]
    if imu is not None:
        j = imu_lookup = _photo_lookup(imu.photo_ids, obs.photo_ids, "IMU attitudes")
        ok = j >= 0
        imu_rot = np.full((m, 3, 3), np.nan)
        centres_for = result.photo_centres[j[ok]]
        imu_rot[j[ok]] = frame.work_from_enu(centres_for) @ matrix_from_opk(imu.opk[ok])
        imu_sig = np.full((m, 3), np.inf)
        imu_sig[j[ok]] = imu.sigma[ok, None]
    # GNSS test directions: east, north, up at the strip method's centres.
    gnss_axes = None if gnss is None else frame.work_from_enu(result.photo_centres)
    t_frame = time.perf_counter() - t_start

    # Passes: complete missing components from the adjusted points, in the frame.
    t_bundle = 0.0
    adjusted_crs = np.array(result.points)
    state = (centres0, rotations0, points0)
    obs_used: BoolArray | None = None
    ctrl_used: BoolArray | None = None
    gnss_used: BoolArray | None = None
    imu_used: BoolArray | None = None
    rejections: list[Rejection] = []
    reported: tuple[Rejection, ...] = ()
    iterations = 0
    control_frame_prev: FloatArray | None = None
    notes: list[str] = []
    for _ in range(_MAX_PASSES):
        t0 = time.perf_counter()
        filled = np.where(np.isnan(given_crs), adjusted_crs[idx], given_crs)
        control_frame = np.full((p, 3), np.nan)
        control_frame[idx] = frame.to_work(filled)
        control_xyz = np.where(mask, control_frame, np.nan)
        t_frame += time.perf_counter() - t0
        if control_frame_prev is not None:
            change = float(np.nanmax(np.abs(control_xyz - control_frame_prev), initial=0.0))
            if change < _PASS_TOLERANCE_M:
                break
        control_frame_prev = control_xyz
        t0 = time.perf_counter()
        fr = refine_frame(
            obs,
            state[0],
            state[1],
            state[2],
            control_xyz=control_xyz,
            control_sigma=sig,
            gnss_centres=gnss_xyz,
            gnss_sigma=gnss_sig,
            imu_rotations=imu_rot,
            imu_sigma=imu_sig,
            blunders=blunders,
            max_iterations=max_iterations,
            compute_precision=compute_precision,
            observation_used=obs_used,
            control_used=ctrl_used,
            gnss_axes=gnss_axes,
            gnss_used=gnss_used,
            imu_used=imu_used,
        )
        t_bundle += time.perf_counter() - t0
        iterations += fr.iterations
        rejections.extend(r for r in fr.rejections if r.applied)
        # what would be rejected ("report"): as found in the last pass only
        reported = tuple(r for r in fr.rejections if not r.applied)
        # rejections of this pass stay rejected in the next
        obs_used = ~fr.observation_rejected
        ctrl_used = ~fr.control_rejected
        gnss_used = ~fr.gnss_rejected
        imu_used = ~fr.imu_rejected
        state = (fr.centres, fr.rotations, np.where(fr.point_used[:, None], fr.points, points0))
        t0 = time.perf_counter()
        adjusted_crs = np.full((p, 3), np.nan)
        adjusted_crs[fr.point_used] = frame.from_work(fr.points[fr.point_used])
        t_frame += time.perf_counter() - t0
        if not frame.curved:
            break
    else:
        notes.append(
            f"plan/height control passes did not settle below {_PASS_TOLERANCE_M * 1e6:.0f} µm "
            f"in {_MAX_PASSES} passes"
        )

    t0 = time.perf_counter()
    centres_crs = frame.from_work(fr.centres)
    enu2frame = frame.work_from_enu(centres_crs)
    rot_enu = np.swapaxes(enu2frame, 1, 2) @ fr.rotations
    opk = opk_from_matrix(rot_enu)

    # What the GNSS centres and IMU attitudes did (rejected ones included).
    rejections.extend(reported)
    options = blunders or BlunderOptions()
    gnss_out = imu_out = None
    if gnss_xyz is not None and gnss_sig is not None and gnss is not None:
        gnss_out = _gnss_residuals(
            gnss, gnss_lookup, gnss_xyz, gnss_sig, fr, enu2frame, obs.photo_ids, options
        )
    if imu_rot is not None and imu_sig is not None and imu is not None:
        imu_out = _imu_residuals(
            imu, imu_lookup, imu_rot, imu_sig, fr, opk, obs.photo_ids, options
        )

    # Residuals at the control, given minus adjusted along E, N, H.
    adj_rows = adjusted_crs[idx]
    filled = np.where(np.isnan(given_crs), adj_rows, given_crs)
    resid = enu_residuals(frame.crs, filled, adj_rows)
    used_xy_final = use_xy & fr.control_used[idx, 0] & fr.point_used[idx]
    used_h_final = use_h & fr.control_used[idx, 2] & fr.point_used[idx]
    keep_rows = fr.point_used[idx]
    resid[~(use_xy | check), :2] = np.nan
    resid[~(use_h | check), 2] = np.nan
    resid[np.isnan(given_crs)] = np.nan
    t_frame += time.perf_counter() - t0
    ctrl_stat_resid = resid.copy()
    ctrl_stat_resid[~used_xy_final, :2] = np.nan
    ctrl_stat_resid[~used_h_final, 2] = np.nan
    out_rows = rows[keep_rows]
    if np.any(~keep_rows & ~check):
        dropped = [control.point_ids[r] for r in rows[~keep_rows & ~check]]
        notes.append(f"control point(s) {', '.join(map(repr, dropped[:5]))} left out")
    notes += [r.describe() for r in rejections]
    return RefinedResult(
        photo_ids=obs.photo_ids,
        point_ids=obs.point_ids,
        points=adjusted_crs,
        photo_centres=centres_crs,
        photo_opk=opk,
        frame=frame.frame,
        frame_description=frame.description,
        points_frame=fr.points,
        photo_centres_frame=fr.centres,
        photo_rotations_frame=fr.rotations,
        sigma0=fr.sigma0,
        redundancy=fr.redundancy,
        iterations=iterations,
        converged=fr.converged,
        image_residuals_um=fr.image_residuals_mm * 1000.0,
        image_used=fr.observation_used,
        control_index=out_rows,
        control_residuals=resid[keep_rows],
        is_check=check[keep_rows],
        used_xy=used_xy_final[keep_rows],
        used_h=used_h_final[keep_rows],
        control_statistics=AccuracyStatistics.from_residuals(ctrl_stat_resid[keep_rows & ~check]),
        check_statistics=AccuracyStatistics.from_residuals(resid[keep_rows & check]),
        point_std=fr.point_std,
        centre_std=fr.centre_std,
        rejections=tuple(rejections),
        warnings=tuple(notes),
        timings={"frame": t_frame, "bundle": t_bundle, "total": time.perf_counter() - t_start},
        n_observations=fr.bundle.n_observations,
        gnss=gnss_out,
        imu=imu_out,
    )
