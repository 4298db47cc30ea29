"""Bundle adjustment in a Cartesian frame with data snooping (method.md §7).

:func:`refine_frame` solves the bundle (:func:`strip_aerotri.bundle.adjust.bundle_adjust`),
tests every image coordinate, control component, GNSS centre and IMU
attitude by Baarda's w, rejects the worst (or a few well-separated image
rays) and solves again from the last solution, until nothing fails.  A round
is: the adjustment (:func:`refine_frame`'s loop), the test values
(:func:`_round_statistics`), the failures (:func:`_failures`), their
records (:func:`describe`) and the rejection itself (:meth:`_Sets.reject`).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._stats import leading_failures
from .._threads import compute_workers
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..blunders import robust_variance_factor
from ..errors import GeometryError, StripAerotriWarning
from ..geometry.camera_model import CameraModel, ShutterMotion
from ..geometry.collinearity import image_jacobian, image_vectors
from ..ground.systematic import kept_control, kept_if_alike, rejected_components
from ..observations import ImageObservations
from ..options import DEFAULT_MAX_ITERATIONS, BlunderOptions, SelfCalibration
from ..results import BundleResult, FrameRefinement, Rejection, SelfCalibrationOutcome
from ._given import observed_with_sigma
from .adjust import NOT_CONVERGED, bundle_adjust
from .photo_tests import _photo_flags, _photo_tests
from .selfcal import ebner_base_mm, final_outcome, residual_cells, start_model

__all__ = ["CONTROL_STAGE", "GNSS_STAGE", "IMAGE_STAGE", "IMU_STAGE", "refine_frame"]

#: Stage name of the image-coordinate tests in :class:`Rejection` records.
IMAGE_STAGE = "bundle"
#: Stage name of the control tests (shared with the ground stage's options).
CONTROL_STAGE = "control"
#: Stage names of the GNSS centre and IMU attitude tests.
GNSS_STAGE = "gnss"
IMU_STAGE = "imu"
#: Smallest value the photo-unknowns factor of the redundancy numbers may take.
_MIN_PHOTO_FACTOR = 0.05
#: Relative change of the sum of squares below which a trial adjustment of
#: ``"auto"``'s choice stops (the delivered one's is 1e-10).  Gauss-Newton
#: converges quadratically: the step that changes the sum of squares by less
#: than 1e-6 of itself leaves the t values within about 1e-3 of the converged
#: ones (tests/test_camera_subsets.py), and the first round of the data
#: snooping goes on from there.
_TRIAL_TOLERANCE = 1e-6


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
        observations they kept (:meth:`_Camera.checked_again`): with another
        set the tests start over.
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
    with compute_workers(int(np.asarray(observations.photo).size)):
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
            pt_used = sets.used_points(inp)
            sub, rows, pts = _compact(obs, sets.keep, pt_used)
            res = _adjust(
                inp, sets, sub, pts, state, max_iterations=max_iterations,
                compute_precision=compute_precision, camera=camera.model, camera0=camera.values,
            )  # fmt: skip
            rounds += 1
            iterations += res.iterations
            camera = camera.moved(res)
            new_points = np.full((inp.n_points, 3), np.nan)
            new_points[pts] = res.points
            # keep initial values of dropped points for a possible later round
            kept = np.where(pt_used[:, None], new_points, inp.points0)
            state = (res.centres, res.rotations, kept)
            _sigma0_after(rejections, previous_effect, res.sigma0)
            stats = _round_statistics(
                inp, sets, res, new_points, pt_used, sub, rows, pts, compute_precision
            )
            result = _refinement(
                _RoundOutcome(res, stats, new_points, pt_used, iterations, rounds),
                sets,
                camera,
                obs,
                rejections,
            )
            if not blunders.testing:
                return result
            failures = _failures(inp, sets, res, stats, blunders)
            if first_control is None:
                first_control = (*_control_w(sets, stats), failures.crit_ctrl)
            if not failures.found:
                again = camera.checked_again(
                    inp, initial.with_images_of(sets), max_iterations, state,
                    int(np.count_nonzero(sets.obs_rejected)),
                )  # fmt: skip
                if again is None:
                    return result
                if again.estimated == camera.estimated:
                    return dataclasses.replace(
                        result, self_calibration=again.outcome(
                            res, obs.xy, np.where(sets.keep[:, None], stats.v_img, np.nan)
                        )
                    )  # fmt: skip
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


def _adjust(
    inp: _Inputs,
    sets: _Sets,
    sub: ImageObservations,
    pts: IntArray,
    state: tuple[FloatArray, FloatArray, FloatArray],
    *,
    max_iterations: int,
    compute_precision: bool,
    camera: CameraModel | None,
    camera0: FloatArray | None,
    tolerance: float = 1e-10,
) -> BundleResult:
    """One bundle adjustment of the observations, control, GNSS and IMU in use
    (``tolerance`` :func:`bundle_adjust`'s)."""
    return bundle_adjust(
        sub,
        state[0],
        state[1],
        state[2][pts],
        camera=camera,
        camera0=camera0,
        motion=inp.motion,
        control_xyz=np.where(sets.ctrl_on[pts], inp.c_xyz[pts], np.nan),
        control_sigma=np.where(sets.ctrl_on[pts], inp.c_sig[pts], np.inf),
        gnss_centres=None
        if inp.g_xyz is None
        else np.where(sets.g_on[:, None], inp.g_xyz, np.nan),
        gnss_sigma=None if inp.g_xyz is None else inp.g_sig,
        imu_rotations=None
        if inp.i_rot is None
        else np.where(sets.i_on[:, None, None], inp.i_rot, np.nan),
        imu_sigma=None if inp.i_rot is None else inp.i_sig,
        max_iterations=max_iterations,
        compute_precision=compute_precision,
        tolerance=tolerance,
    )


@dataclass
class _Trials:
    """The adjustments of ``"auto"``'s choice (:class:`~strip_aerotri.bundle.selfcal.Trials`):
    on the data as given, without tests, each from the last one's photos and
    points; ``state`` the last one's (the start of the first round)."""

    inp: _Inputs
    sets: _Sets
    sub: ImageObservations
    pts: IntArray
    max_iterations: int
    state: tuple[FloatArray, FloatArray, FloatArray]

    def _run(self, model: CameraModel | None, start: FloatArray | None, iterations: int
             ) -> BundleResult:
        with warnings.catch_warnings():
            # a trial may estimate parameters the data cannot separate (the
            # choice then holds them), and a screening takes no step; only the
            # delivered adjustment's convergence is the user's concern
            warnings.filterwarnings("ignore", NOT_CONVERGED, category=StripAerotriWarning)
            return _adjust(
                self.inp, self.sets, self.sub, self.pts, self.state,
                max_iterations=iterations, compute_precision=False, camera=model,
                camera0=start, tolerance=_TRIAL_TOLERANCE,
            )  # fmt: skip

    def screen(self, model: CameraModel) -> BundleResult:
        return self._run(model, None, 0)

    def adjust(self, model: CameraModel | None, start: FloatArray | None) -> BundleResult:
        res = self._run(model, start, self.max_iterations)
        points = self.state[2].copy()
        points[self.pts] = res.points
        self.state = (res.centres, res.rotations, points)
        return res


@dataclass(frozen=True)
class _Camera:
    """The self-calibration of a refinement: its model, current values and choice;
    ``state`` the photos and points of the choice's adjustment of the kept set
    (None: none kept, or no choice)."""

    spec: SelfCalibration | None
    model: CameraModel | None
    values: FloatArray | None
    chosen: SelfCalibrationOutcome | None
    state: tuple[FloatArray, FloatArray, FloatArray] | None = None
    rechecked: bool = False  # "auto" chose again after the blunder tests

    @classmethod
    def start(
        cls,
        inp: _Inputs,
        sets: _Sets,
        spec: SelfCalibration | None,
        max_iterations: int,
        state: tuple[FloatArray, FloatArray, FloatArray] | None = None,
    ) -> _Camera:
        """The model to start with; ``"auto"`` chooses it on the data in use
        (``sets``), its adjustments from ``state`` (default the start values)."""
        if spec is None:
            return cls(None, None, None, None)
        obs = inp.obs
        pt_used = sets.used_points(inp)
        sub, _, pts = _compact(obs, sets.keep, pt_used)
        c_mm = float(obs.principal_distance)
        trials = _Trials(
            inp, sets, sub, pts, max_iterations,
            state or (inp.centres0, inp.rotations0, inp.points0),
        )  # fmt: skip
        base = ebner_base_mm(inp.centres0, inp.points0[pts], c_mm)
        model, values, chosen = start_model(spec, trials, c_mm, base)
        # a kept set starts where its own trial converged; none starts where the
        # refinement without self-calibration does (and ends as it does)
        return cls(spec, model, values, chosen, trials.state if model is not None else None)

    def checked_again(
        self,
        inp: _Inputs,
        sets: _Sets,
        max_iterations: int,
        state: tuple[FloatArray, FloatArray, FloatArray],
        rejected: int,
    ) -> _Camera | None:
        """``"auto"``'s choice made again, once, on ``sets``: the image
        observations the blunder tests kept (``rejected`` of them rejected),
        the control, GNSS and IMU as given (a control point the unmodelled
        camera bent may have failed); None when there is nothing to check
        (another choice, checked already, no image observation rejected).

        A blunder inflates sigma0 and so deflates every t value (or lends a
        parameter a t of its own): on simulated drone strips with 5-15
        blunders and a camera error the set chosen before the tests missed
        the affinity that the blunder-free data keep, and the check points
        lost half their plan accuracy (docs/bundle.md)."""
        if self.spec is None or self.spec.choice != "auto" or self.rechecked or not rejected:
            return None
        again = _Camera.start(inp, sets, self.spec, max_iterations, state)
        again = dataclasses.replace(again, rechecked=True)
        old = self.chosen.kept if self.chosen is not None else ()
        new = again.chosen.kept if again.chosen is not None else ()
        if set(old) == set(new) or again.chosen is None:
            # the same set: this round's adjustment stands, told the reasons
            # and values of the choice on the data kept
            return dataclasses.replace(self, chosen=again.chosen or self.chosen, rechecked=True)
        note = (
            f"self-calibration chosen again without the {rejected} image observation(s) the "
            f"blunder tests rejected: {', '.join(old) or 'none'} became "
            f"{', '.join(new) or 'none'}, and the tests started over with it"
        )
        chosen = dataclasses.replace(again.chosen, notes=(*again.chosen.notes, note))
        return dataclasses.replace(again, chosen=chosen)

    @property
    def estimated(self) -> tuple[str, ...]:
        """The parameters the next adjustment estimates."""
        return () if self.model is None else self.model.estimated

    def moved(self, res: BundleResult) -> _Camera:
        """The camera of the next round starts from this round's estimate."""
        if res.camera is None:
            return self
        return dataclasses.replace(self, values=res.camera.values)

    def outcome(
        self, res: BundleResult, xy: FloatArray, residuals_mm: FloatArray
    ) -> SelfCalibrationOutcome | None:
        """What was estimated, kept and held, with the residuals over the format."""
        if self.spec is None:
            return None
        out = final_outcome(self.spec, self.chosen, res.camera)
        if res.camera is None:
            return out
        return dataclasses.replace(out, cells=residual_cells(res.camera, xy, residuals_mm))


class _Inputs(NamedTuple):
    """The validated inputs of :func:`refine_frame` (frame units: m, rad)."""

    obs: ImageObservations
    n_photos: int
    n_points: int
    centres0: FloatArray
    rotations0: FloatArray
    points0: FloatArray
    sigma_img: FloatArray  # (K,) mm
    c_xyz: FloatArray  # (P, 3), NaN where not given
    c_sig: FloatArray  # (P, 3), inf where not given
    c_given: BoolArray  # (P, 3)
    g_xyz: FloatArray | None
    g_sig: FloatArray
    g_given: BoolArray
    g_axes: FloatArray
    i_rot: FloatArray | None
    i_sig: FloatArray
    i_given: BoolArray
    motion: ShutterMotion | None = None  # a rolling shutter's groups, if estimated


def _inputs(
    obs: ImageObservations,
    centres0: ArrayLike,
    rotations0: ArrayLike,
    points0: ArrayLike,
    control_xyz: ArrayLike | None,
    control_sigma: ArrayLike | None,
    gnss_centres: ArrayLike | None,
    gnss_sigma: ArrayLike | None,
    imu_rotations: ArrayLike | None,
    imu_sigma: ArrayLike | None,
    gnss_axes: ArrayLike | None,
) -> _Inputs:
    """Shapes checked, control, GNSS and IMU with their sigmas; ValueError naming
    the argument otherwise."""
    k_all, m, p = obs.photo.shape[0], len(obs.photo_ids), len(obs.point_ids)
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
    if control_xyz is None:
        c_xyz, c_sig = np.full((p, 3), np.nan), np.full((p, 3), np.inf)
    else:
        c_xyz, c_sig = observed_with_sigma(
            control_xyz, control_sigma, (p, 3), "control_xyz", "control_sigma"
        )
    c_given = np.isfinite(c_xyz) & np.isfinite(c_sig)
    if np.any(c_sig[c_given] <= 0):
        raise ValueError("Expected positive standard deviations for `control_xyz`")
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
    if gnss_axes is None:
        g_axes = np.broadcast_to(np.eye(3), (m, 3, 3))
    else:
        g_axes = np.asarray(gnss_axes, dtype=np.float64)
        if g_axes.shape != (m, 3, 3):
            raise ValueError(f"Expected `gnss_axes` to have shape {(m, 3, 3)}, got {g_axes.shape}")
    return _Inputs(
        obs,
        m,
        p,
        centres,
        rotations,
        points,
        np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), (k_all,)),
        c_xyz,
        c_sig,
        c_given,
        g_xyz,
        g_sig,
        g_given,
        g_axes,
        i_rot,
        i_sig,
        i_given,
    )


@dataclass
class _Sets:
    """What is in use and what was rejected; changed by each round's rejections."""

    keep: BoolArray  # (K,) image observations in use
    rejected_before: BoolArray  # (K,) rejected by an earlier call's tests
    obs_rejected: BoolArray  # (K,)
    ctrl_on: BoolArray  # (P, 3)
    ctrl_rejected: BoolArray  # (P, 3)
    g_on: BoolArray  # (M,)
    g_rejected: BoolArray
    i_on: BoolArray
    i_rejected: BoolArray
    n_img_start: int
    n_ctrl_start: int
    #: False once the control is kept for failing alike: no more control tests
    control_tested: bool = True

    @classmethod
    def start(
        cls,
        inp: _Inputs,
        blunders: BlunderOptions,
        observation_used: ArrayLike | None,
        control_used: ArrayLike | None,
        gnss_used: ArrayLike | None,
        imu_used: ArrayLike | None,
    ) -> _Sets:
        obs, m, p = inp.obs, inp.n_photos, inp.n_points
        k_all = obs.photo.shape[0]
        keep = (
            np.ones(k_all, bool) if observation_used is None else np.array(observation_used, bool)
        )
        if keep.shape != (k_all,):
            raise ValueError(f"Expected `observation_used` to have shape {(k_all,)}")
        ctrl_on = (
            inp.c_given.copy()
            if control_used is None
            else np.array(control_used, bool) & inp.c_given
        )
        excluded_points, excluded_obs = blunders.excluded(obs)
        rejected_before = ~keep & ~excluded_obs
        keep &= ~excluded_obs
        ctrl_on[excluded_points] = False
        g_on = inp.g_given & _photo_flags(gnss_used, m, "gnss_used")
        i_on = inp.i_given & _photo_flags(imu_used, m, "imu_used")
        return cls(
            keep=keep,
            rejected_before=rejected_before,
            obs_rejected=np.zeros(k_all, bool),
            ctrl_on=ctrl_on,
            ctrl_rejected=np.zeros((p, 3), bool),
            g_on=g_on,
            g_rejected=inp.g_given & ~g_on,
            i_on=i_on,
            i_rejected=inp.i_given & ~i_on,
            n_img_start=int(keep.sum()),
            n_ctrl_start=int(ctrl_on.sum()),
        )

    def copy(self) -> _Sets:
        """A copy that later rejections leave alone."""
        arrays = {
            f.name: getattr(self, f.name).copy()
            for f in dataclasses.fields(self)
            if isinstance(getattr(self, f.name), np.ndarray)
        }
        return dataclasses.replace(self, **arrays)

    def with_images_of(self, other: _Sets) -> _Sets:
        """A copy with ``other``'s image observations in use and rejected (and
        this one's control, GNSS and IMU)."""
        return dataclasses.replace(
            self.copy(), keep=other.keep.copy(), obs_rejected=other.obs_rejected.copy()
        )

    def used_points(self, inp: _Inputs) -> BoolArray:
        """Points with a start value and enough rays.

        A point that lost a ray to a rejection keeps a check on the rest only
        with three rays left: with two, the ray rejected may have been the
        good one (a wrong ray pulls the point towards itself, and a good
        neighbour can show the larger w) and nothing would show it."""
        obs, p = inp.obs, inp.n_points
        rays = np.bincount(obs.point[self.keep], minlength=p)
        full = np.all(self.ctrl_on, axis=1)
        lost = np.bincount(obs.point[self.obs_rejected | self.rejected_before], minlength=p) > 0
        need = np.where(lost, 3, 2)
        has_start = np.all(np.isfinite(inp.points0), axis=1)
        used: BoolArray = has_start & ((rays >= need) | ((rays >= need - 1) & full))
        return used

    def reject(self, picks: list[tuple[str, int]]) -> None:
        for kind, k in picks:
            if kind == "image":
                self.keep[k] = False
                self.obs_rejected[k] = True
            elif kind == "plan":
                self.ctrl_on[k, :2] = False
                self.ctrl_rejected[k, :2] = True
            elif kind == "height":
                self.ctrl_on[k, 2] = False
                self.ctrl_rejected[k, 2] = True
            elif kind == "gnss":
                self.g_on[k] = False
                self.g_rejected[k] = True
            else:
                self.i_on[k] = False
                self.i_rejected[k] = True

    def control_over_limit(self, blunders: BlunderOptions) -> bool:
        """More than ``max_fraction`` of the control components rejected."""
        n_ctrl_rej = self.n_ctrl_start - int(self.ctrl_on.sum())
        return n_ctrl_rej > blunders.max_fraction * max(self.n_ctrl_start, 1)

    def keep_control(self) -> None:
        """Every rejected control component back in use, and no more control tests."""
        self.ctrl_on |= self.ctrl_rejected
        self.ctrl_rejected[:] = False
        self.control_tested = False

    def check_fractions(self, inp: _Inputs, blunders: BlunderOptions) -> None:
        """GeometryError when a kind of observation lost more than
        ``max_fraction`` to the tests: the rest cannot be trusted either."""
        limit = blunders.max_fraction
        n_img_rej = self.n_img_start - int(self.keep.sum())
        if n_img_rej > limit * max(self.n_img_start, 1):
            raise GeometryError(
                f"bundle adjustment: more than {limit:.0%} of the image "
                f"observations fail the blunder test ({n_img_rej} of {self.n_img_start}); the "
                "observations cannot be trusted"
            )
        if self.control_over_limit(blunders):
            raise GeometryError(
                f"bundle adjustment: more than {limit:.0%} of the control "
                "observations fail the blunder test; the control cannot be trusted, or "
                "uncorrected camera errors bend the block (when many points fail together, "
                'add [adjustment] self_calibration = "auto")'
            )
        for stage, what, given_k, rejected_k in (
            (GNSS_STAGE, "GNSS centres", inp.g_given, self.g_rejected),
            (IMU_STAGE, "IMU attitudes", inp.i_given, self.i_rejected),
        ):
            n_given_k = int(np.count_nonzero(given_k))
            n_rej_k = int(np.count_nonzero(rejected_k))
            if n_rej_k > limit * max(n_given_k, 1):
                raise GeometryError(
                    f"bundle adjustment, stage {stage!r}: more than {limit:.0%} "
                    f"of the {what} fail the blunder test ({n_rej_k} of {n_given_k} photos); "
                    f"the {what} cannot be trusted"
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
    rows_t = _every_or(np.flatnonzero(tested), k_all)
    sel = _every_or(rows, k_all)
    ray_points = new_points[obs.point[rows_t]]
    if res.motion is not None:  # a rolling shutter: each ray from its moved centre
        shutter = res.motion.model
        ray_points = ray_points - shutter.centre_shift(
            res.motion.values, obs.photo[rows_t], shutter.fractions(obs.xy[rows_t])
        )
    vv = image_vectors(
        res.centres[obs.photo[rows_t]], res.rotations[obs.photo[rows_t]], ray_points
    )
    v_all[rows_t] = -obs.principal_distance * vv[:, :2] / vv[:, 2:3] - obs.xy[rows_t]
    if res.camera is not None:  # computed minus corrected observed
        v_all[rows_t] -= res.camera.model.correction(obs.xy[rows_t], res.camera.values)

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
        point_ids=tuple(obs.point_ids)
        if points.size == len(obs.point_ids)
        else tuple(obs.point_ids[i] for i in points),
        photo=obs.photo[rows],
        point=new_index[obs.point[rows]],
        xy=obs.xy[rows],
        sigma=np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), obs.photo.shape)[rows],
        principal_distance=obs.principal_distance,
    )
    return sub, rows, points


def _expand(values: FloatArray, index: IntArray, n: int) -> FloatArray:
    out = np.full((n, *values.shape[1:]), np.nan)
    out[index] = values
    return out
