"""Bundle adjustment in a Cartesian frame with data snooping (method.md §7).

:func:`refine_frame` solves the bundle (:func:`strip_aerotri.bundle.adjust.bundle_adjust`),
tests every image coordinate, control component, GNSS centre and IMU
attitude by Baarda's w, rejects the worst (or a few well-separated image
rays) and solves again from the last solution, until nothing fails.  A round
is: the adjustment (:func:`refine_frame`'s loop), the test values
(:func:`_round_statistics`), the failures (:func:`_failures`), their
records (:func:`describe`) and the rejection itself (`_Sets.reject`, in
``_snoop_sets.py``); the self-calibration's camera and choice are in
``_snoop_camera.py``.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from .._stats import leading_failures
from .._threads import compute_workers
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..blunders import robust_variance_factor
from ..geometry.camera_model import ShutterMotion
from ..geometry.collinearity import image_jacobian, image_vectors, project
from ..ground.systematic import kept_control, kept_if_alike, rejected_components
from ..observations import ImageObservations
from ..options import DEFAULT_MAX_ITERATIONS, BlunderOptions, SelfCalibration
from ..results import BundleResult, FrameRefinement, Rejection
from ._observation_space import moving_space, observation_space
from ._snoop_camera import _adjust, _Camera
from ._snoop_sets import (
    CONTROL_STAGE,
    GNSS_STAGE,
    IMAGE_STAGE,
    IMU_STAGE,
    _compact,
    _Inputs,
    _inputs,
    _Sets,
)
from ._structures import reusing_structures
from .photo_tests import _photo_tests

__all__ = ["CONTROL_STAGE", "GNSS_STAGE", "IMAGE_STAGE", "IMU_STAGE", "refine_frame"]

#: Smallest value the photo-unknowns factor of the redundancy numbers may take.
_MIN_PHOTO_FACTOR = 0.05


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
    self_calibration: SelfCalibration | None = None,
    control_tested: bool = True,
    motion: ShutterMotion | None = None,
) -> FrameRefinement:
    """Bundle adjustment in a Cartesian frame with data snooping.

    Length: the documentation of its many parameters (the bundle's own and
    the snooping's); the rounds themselves are a short loop over named steps.

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
    self_calibration : SelfCalibration, optional
        Estimate the camera with the block (:mod:`strip_aerotri.bundle.selfcal`);
        ``"auto"`` chooses the parameters before the blunder tests, which
        then run with the chosen camera, and once more on the image
        observations and control they kept (:meth:`_Camera.checked_again`):
        with another set the tests start over.
    control_tested : bool
        False: the control is not tested (an earlier call kept it for
        failing alike).
    motion : ShutterMotion, optional
        A rolling shutter's motion per group of photos, estimated in every
        adjustment (``bundle_adjust``'s ``motion``); the image residuals
        tested are those of the moved centres.

    Returns
    -------
    FrameRefinement

    Raises
    ------
    GeometryError
        As :func:`~strip_aerotri.bundle.bundle_adjust`, or more than
        ``max_fraction`` of the image observations, of the control (unless
        the first adjustment's control fails at many points alike: then it
        is all kept, untested, with a warning), of the GNSS centres or of
        the IMU attitudes fail.

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

    *Image coordinates*: with ``compute_precision`` the exact redundancy
    numbers ``r = 1 - (A Q Aᵀ P)ᵢᵢ`` from the selected inverse of the normal
    matrix (:mod:`strip_aerotri.geometry.normals`, no further solves).
    Without it they are approximated by ``r = (1 - h) rho``, where ``h`` is
    the exact leverage of the coordinate on its own point with the photos
    held fixed and ``rho = 1 - 6 M / sum(1 - h)`` spreads the photos'
    unknowns evenly over the image coordinates (so that the numbers add up
    to the image share of the redundancy); on the 12-photo film strip the
    approximation is within 0.1 of the exact numbers (tests/test_refine.py).

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
    observations (both coordinates of a ray) are rejected several per round
    (method.md 6B): every failing one whose test value is the largest of its
    point's and of its photo's, so that no rejection of a round is the echo
    of another through their shared point or photo.  A point
    left with one ray (and no full control) is dropped.  The adjustment is
    then solved again from the last solution, until nothing fails.
    """
    # one normal-equation structure for the choice's trials and every round
    with compute_workers(int(np.asarray(observations.photo).size)), reusing_structures():
        blunders = blunders or BlunderOptions()
        obs = observations
        inp = _inputs(
            obs, centres0, rotations0, points0, control_xyz, control_sigma,
            gnss_centres, gnss_sigma, imu_rotations, imu_sigma, gnss_axes,
        )._replace(motion=motion)  # fmt: skip
        sets = _Sets.start(inp, blunders, observation_used, control_used, gnss_used, imu_used)
        sets.control_tested = control_tested
        initial = sets.copy()
        rejections: list[Rejection] = []
        rounds = iterations = 0
        previous_effect: int | None = None
        state = (inp.centres0, inp.rotations0, inp.points0)
        camera = _Camera.start(inp, sets, self_calibration, max_iterations)
        state = camera.state or state  # from where the choice's adjustments ended
        first_control: tuple[IntArray, FloatArray, float] | None = None
        while True:
            res, stats, new_points, pt_used, state = _round(
                inp, sets, state, camera, max_iterations, compute_precision
            )
            rounds += 1
            iterations += res.iterations
            camera = camera.moved(res)
            _sigma0_after(rejections, previous_effect, res.sigma0)
            outcome = _RoundOutcome(res, stats, new_points, pt_used, iterations, rounds)
            result = _refinement(outcome, sets, camera, obs, rejections)
            if not blunders.testing:
                return result
            failures = _failures(inp, sets, res, stats, blunders)
            if first_control is None:
                first_control = (*_control_w(sets, stats), failures.crit_ctrl)
            if not failures.found:
                again = camera.checked_again(inp, initial, sets, max_iterations, state)
                if again is None or again.estimated == camera.estimated:
                    return result if again is None else again.told(result, sets, obs)
                # another set: the tests start over with it, from this solution
                camera, state = again, again.state or state
                sets, rejections = initial.copy(), []
                previous_effect, first_control = None, None
                continue
            picks = _picks(failures, blunders, obs)
            new_rejections = describe(obs, picks, failures, stats, res.sigma0, blunders)
            if not blunders.rejecting:
                return dataclasses.replace(result, rejections=tuple(rejections + new_rejections))
            previous_effect = len(rejections)
            rejections.extend(new_rejections)
            sets.reject(picks)
            if sets.control_over_limit(blunders) and _keep_systematic(
                first_control, stats, rejections, obs, camera.model is not None
            ):
                rejections = kept_control(rejections)
                sets.keep_control()
                previous_effect = None
            sets.check_fractions(inp, blunders)


def _round(
    inp: _Inputs,
    sets: _Sets,
    state: tuple[FloatArray, FloatArray, FloatArray],
    camera: _Camera,
    max_iterations: int,
    compute_precision: bool,
) -> tuple[
    BundleResult,
    _RoundStatistics,
    FloatArray,
    BoolArray,
    tuple[FloatArray, FloatArray, FloatArray],
]:
    """One adjustment of the data in use from ``state``: the adjustment, its
    test statistics, the points (P, 3; NaN where not used), the points used
    and the next round's start (dropped points keep their initial values)."""
    pt_used = sets.used_points(inp)
    sub, rows, pts = _compact(inp.obs, sets.keep, pt_used)
    res = _adjust(
        inp, sets, sub, pts, state, max_iterations=max_iterations,
        compute_precision=compute_precision, camera=camera.model, camera0=camera.values,
    )  # fmt: skip
    new_points = np.full((inp.n_points, 3), np.nan)
    new_points[pts] = res.points
    kept = np.where(pt_used[:, None], new_points, inp.points0)
    stats = _round_statistics(
        inp, sets, res, new_points, pt_used, sub, rows, pts, compute_precision
    )
    return res, stats, new_points, pt_used, (res.centres, res.rotations, kept)


def _sigma0_after(rejections: list[Rejection], since: int | None, sigma0: float) -> None:
    """The last round's rejections (from ``since``) told the sigma0 they led to."""
    if since is not None:
        rejections[since:] = [
            dataclasses.replace(r, effect=f"{r.effect}, sigma0 {sigma0:.4g} after")
            for r in rejections[since:]
        ]


class _RoundOutcome(NamedTuple):
    """One round's adjustment and statistics, and the counts so far."""

    res: BundleResult
    stats: _RoundStatistics
    points: FloatArray  # (P, 3), NaN where not used
    point_used: BoolArray
    iterations: int
    rounds: int


def _refinement(
    rnd: _RoundOutcome,
    sets: _Sets,
    camera: _Camera,
    obs: ImageObservations,
    rejections: list[Rejection],
) -> FrameRefinement:
    """The result of a round, as :func:`refine_frame` returns it."""
    res, stats, n_points = rnd.res, rnd.stats, rnd.point_used.shape[0]
    return FrameRefinement(
        centres=res.centres,
        rotations=res.rotations,
        points=rnd.points,
        point_used=rnd.point_used,
        observation_used=sets.keep & stats.tested,
        control_used=sets.ctrl_on & rnd.point_used[:, None],
        observation_rejected=sets.obs_rejected.copy(),
        control_rejected=sets.ctrl_rejected.copy(),
        image_residuals_mm=stats.v_img,
        image_w=stats.w_img,
        image_redundancy=stats.r_img,
        control_residuals=stats.ctrl_res,
        control_w=stats.w_ctrl,
        point_std=_expand(res.point_std, np.flatnonzero(rnd.point_used), n_points),
        centre_std=res.centre_std,
        rotation_std=res.rotation_std,
        sigma0=res.sigma0,
        redundancy=res.redundancy,
        iterations=rnd.iterations,
        rounds=rnd.rounds,
        converged=res.converged,
        rejections=tuple(rejections),
        bundle=res,
        gnss_used=sets.g_on.copy(),
        gnss_rejected=sets.g_rejected.copy(),
        imu_used=sets.i_on.copy(),
        imu_rejected=sets.i_rejected.copy(),
        self_calibration=camera.outcome(
            res, obs.xy, np.where(sets.keep[:, None], stats.v_img, np.nan)
        ),
        control_tested=sets.control_tested,
    )


def _picks(
    failures: _Failures, blunders: BlunderOptions, obs: ImageObservations
) -> list[tuple[str, int]]:
    """What a round rejects: every failing ray that leads its point and its
    photo (none is the echo of another rejection of the round), else the
    worst control component, GNSS centre or IMU attitude; every failure when
    the tests only flag."""
    if not blunders.rejecting:
        return [(f[1], f[2]) for f in sorted(failures.found, reverse=True)]
    worst = max(failures.found)
    if worst[1] == "image":
        leaders = leading_failures(failures.ray_w, failures.crit_img, obs.point, obs.photo)
        return [("image", int(k)) for k in leaders]
    return [(worst[1], worst[2])]


def _control_w(sets: _Sets, stats: _RoundStatistics) -> tuple[IntArray, FloatArray]:
    """The points with control and their test values (components; NaN where
    not tested)."""
    rows = np.flatnonzero(np.any(sets.ctrl_on, axis=1))
    return rows, np.where(sets.ctrl_on[rows], stats.w_ctrl[rows], np.nan)


def _keep_systematic(
    first: tuple[IntArray, FloatArray, float],
    stats: _RoundStatistics,
    rejections: list[Rejection],
    obs: ImageObservations,
    self_calibrating: bool,
) -> bool:
    """True (and a warning) when the control fails at many points alike
    (:func:`strip_aerotri.ground.systematic.fails_alike`): camera errors, not
    blunders, so the control is kept.  Judged on the first adjustment's test
    values and on every one met so far (this round's, each rejected
    component at the value it was rejected with)."""
    rows, w, critical = first
    position = {obs.point_ids[k]: j for j, k in enumerate(rows.tolist())}
    rejected = rejected_components(rejections, position)
    return kept_if_alike(
        "bundle adjustment",
        w,
        critical,
        last=stats.w_ctrl[rows],
        rejected=rejected,
        self_calibrating=self_calibrating,
    )


class _RoundStatistics(NamedTuple):
    tested: BoolArray  # (K,) observations of used points (rejected ones included)
    v_img: FloatArray  # (K, 2) computed minus observed, mm
    r_img: FloatArray  # (K, 2) redundancy numbers (approximate)
    w_img: FloatArray  # (K, 2) w, scaled by the robust variance factor
    ctrl_res: FloatArray  # (P, 3) adjusted minus given, m
    w_ctrl: FloatArray  # (P, 3)


def _round_statistics(
    inp: _Inputs,
    sets: _Sets,
    res: BundleResult,
    new_points: FloatArray,
    pt_used: BoolArray,
    sub: ImageObservations,
    rows: IntArray,
    pts: IntArray,
    compute_precision: bool,
) -> _RoundStatistics:
    """Residuals, redundancy numbers and w of the image coordinates and the
    control after one adjustment (see :func:`refine_frame`'s notes)."""
    obs, m, p = inp.obs, inp.n_photos, inp.n_points
    k_all = obs.photo.shape[0]
    tested = pt_used[obs.point]
    v_all = np.full((k_all, 2), np.nan)
    sel = _every_or(rows, k_all)
    v_all[sel] = res.residuals_mm  # the adjusted rays' own, x̂ - x_obs with a camera
    left_out = tested.copy()
    left_out[rows] = False
    rows_t = np.flatnonzero(left_out)  # rays of used points out of the adjustment
    ray_points = new_points[obs.point[rows_t]]
    cam = res.camera
    if res.motion is not None:  # a rolling shutter: each ray read at its x̂'s row
        moved = moving_space(
            res.motion.model, res.motion.values,
            (res.centres, res.rotations, ray_points, obs.photo[rows_t], obs.principal_distance),
            None if cam is None else cam.model, np.zeros(0) if cam is None else cam.values,
            obs.xy[rows_t],
        )  # fmt: skip
        v_all[rows_t] = np.nan if moved is None else moved.residuals
    else:
        computed = project(
            res.centres, res.rotations, ray_points, obs.photo[rows_t], np.arange(rows_t.size),
            obs.principal_distance,
        )[0]  # fmt: skip
        if cam is None:
            v_all[rows_t] = computed - obs.xy[rows_t]
        else:  # x̂ - x_obs with x̂ + Δ(x̂) = x, as the adjustment's own rays
            space = observation_space(cam.model, cam.values, computed, obs.xy[rows_t])
            v_all[rows_t] = space.residuals

    ctrl_on, c_sig, given = sets.ctrl_on, inp.c_sig, inp.c_given
    r_img = np.full((k_all, 2), np.nan)
    exact = res.image_redundancy
    precise = compute_precision and np.isfinite(res.sigma0) and res.sigma0 > 0
    if precise and exact.shape == (rows.size, 2) and np.all(np.isfinite(exact)):
        r_img[sel] = np.clip(exact, 1e-12, 1.0)
        vinv_diag = np.full((pts.size, 3), np.nan)  # not needed: the cofactors are exact
    else:
        weight_sub = np.where(ctrl_on[pts], 1.0 / np.where(ctrl_on[pts], c_sig[pts], 1.0) ** 2, 0)
        h_sub, vinv_diag = _point_leverage(
            sub, res.centres, res.rotations, res.points, weight_sub
        )
        free = float(np.sum(1.0 - h_sub))
        n_photo = 6.0 * m + (0 if res.camera is None else len(res.camera.names))
        n_photo += 0 if res.motion is None else res.motion.values.size
        rho = max(_MIN_PHOTO_FACTOR, 1.0 - n_photo / free) if free > 0 else _MIN_PHOTO_FACTOR
        r_img[sel] = np.clip((1.0 - h_sub) * rho, 1e-12, 1.0)
    w_img = np.full((k_all, 2), np.nan)
    w_img[sel] = v_all[sel] / (inp.sigma_img[sel, None] * np.sqrt(r_img[sel]))
    w_img /= np.sqrt(robust_variance_factor(w_img[sel].ravel()))

    ctrl_res = np.full((p, 3), np.nan)
    ctrl_res[given] = np.where(pt_used[:, None], new_points, np.nan)[given] - inp.c_xyz[given]
    q = np.full((p, 3), np.nan)
    if precise:
        q[pts] = (res.point_std / res.sigma0) ** 2
    else:
        q[pts] = vinv_diag
    r_ctrl = np.where(ctrl_on, 1.0 - q / np.where(given, c_sig, 1.0) ** 2, np.nan)
    r_ctrl = np.where(ctrl_on, np.clip(r_ctrl, 1e-12, 1.0), np.nan)
    # Control is tested at its stated sigmas: with a few dozen control
    # components and small redundancy numbers a single blunder spreads to its
    # neighbours and would inflate a robust variance factor.
    w_ctrl = np.where(ctrl_on, ctrl_res / (c_sig * np.sqrt(r_ctrl)), np.nan)
    return _RoundStatistics(tested, v_all, r_img, w_img, ctrl_res, w_ctrl)


class _Failures(NamedTuple):
    #: (|w| / critical, kind, index) of every failing test; kind "image"
    #: (observation index), "plan" / "height" (point index), "gnss" / "imu"
    #: (photo index)
    found: list[tuple[float, str, int]]
    ray_w: FloatArray  # (K,) the larger of |w_x|, |w_y| of each observation in use
    crit_img: float
    crit_ctrl: float
    plan_w: FloatArray
    height_w: FloatArray
    #: kind -> (stage, w (M, 3), residuals along the axes (M, 3), critical,
    #: component names, unit, factor of the residual)
    photo_stages: dict[str, tuple[str, FloatArray, FloatArray, float, tuple[str, ...], str, float]]


def _failures(
    inp: _Inputs,
    sets: _Sets,
    res: BundleResult,
    stats: _RoundStatistics,
    blunders: BlunderOptions,
) -> _Failures:
    """Every test above its critical value: image rays (the larger of |w_x|,
    |w_y|), control in plan (the larger of X, Y) and height, GNSS centres
    along ``gnss_axes`` and IMU attitudes about the image axes (a photo's
    largest |w|)."""
    used = sets.keep & stats.tested
    crit_img = blunders.critical(IMAGE_STAGE, int(np.count_nonzero(used)) * 2)
    ray_w = np.fmax(np.abs(stats.w_img[:, 0]), np.abs(stats.w_img[:, 1]))
    ray_w = np.where(used, ray_w, np.nan)
    ctrl_on, w_ctrl = sets.ctrl_on & sets.control_tested, stats.w_ctrl
    crit_ctrl = blunders.critical(CONTROL_STAGE, int(np.count_nonzero(sets.ctrl_on)))
    plan_on = ctrl_on[:, 0] & ctrl_on[:, 1]
    plan_w = np.where(plan_on, np.fmax(np.abs(w_ctrl[:, 0]), np.abs(w_ctrl[:, 1])), np.nan)
    h_w = np.where(ctrl_on[:, 2], np.abs(w_ctrl[:, 2]), np.nan)
    found = [
        (float(ray_w[k]) / crit_img, "image", int(k)) for k in np.flatnonzero(ray_w > crit_img)
    ]
    found += [
        (float(plan_w[i]) / crit_ctrl, "plan", int(i)) for i in np.flatnonzero(plan_w > crit_ctrl)
    ]
    found += [
        (float(h_w[i]) / crit_ctrl, "height", int(i)) for i in np.flatnonzero(h_w > crit_ctrl)
    ]
    photo_stages = {
        "gnss": (
            GNSS_STAGE,
            *_photo_tests(
                -res.gnss_residuals, res.gnss_residual_cofactor, inp.g_sig, inp.g_axes, sets.g_on
            ),
            blunders.critical(GNSS_STAGE, 3 * int(np.count_nonzero(sets.g_on))),
            ("E", "N", "U"),
            "m",
            1.0,
        ),
        "imu": (
            IMU_STAGE,
            *_photo_tests(
                -res.imu_residuals, res.imu_residual_cofactor, inp.i_sig, np.eye(3), sets.i_on
            ),
            blunders.critical(IMU_STAGE, 3 * int(np.count_nonzero(sets.i_on))),
            ("about x", "about y", "about z"),
            "deg",
            float(np.degrees(1.0)),
        ),
    }
    for kind, (_, w_k, _, crit_k, *_) in photo_stages.items():
        photo_w = np.max(np.where(np.isfinite(w_k), np.abs(w_k), -1.0), axis=1)
        found += [
            (float(photo_w[j]) / crit_k, kind, int(j)) for j in np.flatnonzero(photo_w > crit_k)
        ]
    return _Failures(found, ray_w, crit_img, crit_ctrl, plan_w, h_w, photo_stages)  # type: ignore[arg-type]


def describe(
    obs: ImageObservations,
    picks: list[tuple[str, int]],
    failures: _Failures,
    stats: _RoundStatistics,
    sigma0: float,
    blunders: BlunderOptions,
) -> list[Rejection]:
    """The rejection records of the picked failures."""
    effect = f"sigma0 {sigma0:.4g} before"
    out: list[Rejection] = []
    for kind, k in picks:
        if kind in failures.photo_stages:
            stage, w_k, v_k, crit_k, names, unit, factor = failures.photo_stages[kind]
            comp = int(np.nanargmax(np.abs(w_k[k])))
            out.append(
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
            w_img = stats.w_img
            comp = 0 if abs(w_img[k, 0]) >= abs(w_img[k, 1]) else 1
            out.append(
                Rejection(
                    stage=IMAGE_STAGE,
                    point=obs.point_ids[obs.point[k]],
                    photos=(obs.photo_ids[obs.photo[k]],),
                    component="xy"[comp],
                    residual=float(stats.v_img[k, comp] * 1000.0),
                    unit="µm",
                    w=float(abs(w_img[k, comp])),
                    critical=failures.crit_img,
                    applied=blunders.rejecting,
                    effect=effect,
                )
            )
        else:
            ctrl_res = stats.ctrl_res
            if kind == "plan":
                resid = float(np.hypot(ctrl_res[k, 0], ctrl_res[k, 1]))
                wv = float(failures.plan_w[k])
            else:
                resid = float(-ctrl_res[k, 2])
                wv = float(failures.height_w[k])
            out.append(
                Rejection(
                    stage=CONTROL_STAGE,
                    point=obs.point_ids[k],
                    photos=(),
                    component=kind,
                    residual=resid,
                    unit="m",
                    w=wv,
                    critical=failures.crit_ctrl,
                    applied=blunders.rejecting,
                    effect=f"bundle adjustment, {effect}",
                )
            )
    return out


def _every_or(index: IntArray, n: int) -> IntArray | slice:
    """`index` (ascending, distinct places in ``range(n)``), or the slice of
    every place when it holds them all (the same values, read without a copy)."""
    return slice(None) if index.size == n else index


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


def _expand(values: FloatArray, index: IntArray, n: int) -> FloatArray:
    out = np.full((n, *values.shape[1:]), np.nan)
    out[index] = values
    return out
