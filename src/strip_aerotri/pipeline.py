"""One call from the observations to the adjusted strip.

:func:`triangulate` chains strip formation (:mod:`strip`), the ground stage
(:mod:`ground`) and, if asked, the bundle refinement (:mod:`bundle`);
:func:`strip_aerotri.project.run_project` calls it with a loaded project's
observations and options.  The result carries every stage's figures and
the check-point statistics of method.md §7-8.  No stage imports this module.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from ._threads import limit_blas_threads
from .errors import GeometryError
from .geodesy import GroundCRS
from .ground.common import image_scale
from .ground.polynomials import adjust_to_ground
from .ground.systematic import self_calibration_follows
from .observations import (
    ControlPoints,
    GnssCentres,
    ImageObservations,
    ImuAttitudes,
    LineSpec,
    StripSpec,
)
from .options import (
    DEFAULT_BLOCK_POLYNOMIAL,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_MIN_BASE_TO_HEIGHT,
    DEFAULT_PHOTO_STEP,
    AdjustmentOptions,
    BlunderOptions,
    Construction,
    GroundOptions,
    Refine,
    Route,
    SelfCalibration,
    StripOptions,
    Weights,
)
from .plausibility import control_coverage_problems, control_problems, image_sigma_problems
from .results import (
    AccuracyStatistics,
    BlockResult,
    GroundResult,
    PointWarning,
    StripModel,
    StripResult,
)
from .strip.densify import form_strip_stepped

if TYPE_CHECKING:
    from .ground.check_precision import WeakCheck

__all__ = [
    "AccuracyStatistics",
    "Progress",
    "StripResult",
    "form_strip_of",
    "triangulate",
    "triangulate_block",
]

Progress = Callable[[str], None]


@limit_blas_threads
def form_strip_of(
    observations: ImageObservations,
    options: AdjustmentOptions,
    *,
    strip_options: StripOptions | None = None,
    blunders: BlunderOptions | None = None,
) -> StripModel:
    """The strip formed as a run of ``options`` forms it: the photo step, and
    breaks allowed where every model is transformed on its own
    (:attr:`AdjustmentOptions.allow_breaks`); ``strip_options`` (default:
    ``options.strip_options()``) may set more (the first photo's pose).
    ``stripaero check`` forms the strip with it too."""
    strip_options = (
        options.strip_options()
        if strip_options is None
        else dataclasses.replace(strip_options, allow_breaks=options.allow_breaks)
    )
    return form_strip_stepped(
        observations,
        strip_options,
        photo_step=options.photo_step,
        min_base_to_height=options.min_base_to_height,
        blunders=blunders,
    )


@limit_blas_threads
def triangulate(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS | str,
    *,
    lines: Sequence[LineSpec] = (),
    options: AdjustmentOptions | None = None,
    strip_options: StripOptions | None = None,
    ground_options: GroundOptions | None = None,
    blunders: BlunderOptions | None = None,
    photo_step: int | Literal["auto"] = DEFAULT_PHOTO_STEP,
    min_base_to_height: float = DEFAULT_MIN_BASE_TO_HEIGHT,
    refine: Refine | str = Refine.NONE,
    gnss: Any = None,
    imu: Any = None,
    self_calibration: SelfCalibration | None = None,
    progress: Progress | None = None,
    warnings: Sequence[str] = (),
    control_name: str = "control",
) -> StripResult:
    """Strip formation and ground stage in one call.

    Parameters
    ----------
    observations : ImageObservations
        Image coordinates (mm, reduced to the principal point).
    control : ControlPoints
        Control and check points in `crs`.
    crs : GroundCRS or str
        Control CRS (any pyproj CRS text, or ``"local"``).
    lines : sequence of LineSpec
        Straight-line conditions, J(18).
    options : AdjustmentOptions, optional
        Every option of the run (a project's ``[adjustment]``); then
        ``ground_options``, ``photo_step``, ``min_base_to_height`` and
        ``refine`` are taken from it and must not be given, and
        ``strip_options``, if given, only adds what ``options`` does not hold
        (the first photo's pose).
    strip_options : StripOptions
    ground_options : GroundOptions
    blunders : BlunderOptions, optional
        Gross-error tests at every stage (default: test and reject; see
        :mod:`strip_aerotri.blunders`).
    photo_step : int or "auto"
        Form the models from every k-th photo and orient the others by
        resection (drone strips with 80-95 % overlap); "auto" chooses the
        smallest k reaching ``min_base_to_height`` (:mod:`strip_aerotri.strip.densify`).
    min_base_to_height : float
    refine : {"none", "bundle"}
        "bundle": a rigorous bundle adjustment from the strip solution
        (:func:`strip_aerotri.bundle.refine.refine_bundle`).
    gnss, imu : GnssCentres, ImuAttitudes, optional
        Observed projection centres and attitudes for the bundle refinement.
    self_calibration : SelfCalibration, optional
        Calibrate the camera in the bundle refinement (``refine = "bundle"``).
    progress : callable, optional
        Called with a short message at each stage (the CLI shows it).
    warnings : sequence of str
        Warnings found earlier (e.g. while loading), carried into the result.
    control_name : str
        How messages name the control (its file in a project).

    Returns
    -------
    StripResult
    """
    say = progress or (lambda message: None)
    timings: dict[str, float] = {}
    options, ground_options = _run_options(
        options, strip_options, ground_options, photo_step, min_base_to_height, refine
    )
    t0 = time.perf_counter()
    crs = GroundCRS.from_user_input(crs)  # once: pyproj's CRS and transformers are shared
    mirrored = control_problems(observations, control, crs, file=control_name)
    if mirrored:
        raise GeometryError(mirrored[0])
    warnings = [*warnings, *control_coverage_problems(observations, control, file=control_name)]
    say(
        f"forming the strip: {observations.n_photos} photos, "
        f"{len(observations.photo)} observations"
    )
    strip = form_strip_of(
        observations, options, strip_options=strip_options, blunders=blunders
    )
    timings["strip_formation"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    sigma_notes = image_sigma_problems(strip.relative.sigma0_um, observations.sigma)
    warnings = [*warnings, *sigma_notes]
    # the stages' warnings name self-calibration as under way when the bundle does it
    with self_calibration_follows(
        self_calibration is not None and options.refine is Refine.BUNDLE
    ), _likely_cause(sigma_notes):
        adjust, doing = adjust_to_ground, "orienting the strip on the control"
        if ground_options.construction is Construction.MODELS:
            from .ground.models import adjust_models_to_ground

            adjust, doing = adjust_models_to_ground, "transforming the models onto the control"
        say(doing)
        ground = adjust(
            strip, control, crs, lines=lines, options=ground_options, blunders=blunders,
            control_name=control_name,
        )  # fmt: skip
    timings["ground"] = time.perf_counter() - t1
    # the tie test's residuals, in model base lengths until now, in metres
    model_per_mm, _ = image_scale(strip)
    strip = strip.with_rejections_in_metres(ground.image_scale / model_per_mm)
    notes = _strip_warnings(observations, strip, ground, warnings)
    resid = ground.control_residuals
    used = resid[~ground.is_check].copy()
    # statistics at the control actually used: rejected coordinates left out
    used[~ground.used_xy[~ground.is_check], :2] = np.nan
    used[~ground.used_h[~ground.is_check], 2] = np.nan
    result = StripResult(
        strip=strip,
        ground=ground,
        control=control,
        control_statistics=AccuracyStatistics.from_residuals(used),
        check_statistics=AccuracyStatistics.from_residuals(resid[ground.is_check]),
        warnings=tuple(notes),
        timings=timings,
        # the options as run: the route taken, the photo step chosen
        options=dataclasses.replace(options, route=ground.route, photo_step=strip.photo_step),
    )
    if options.refine is Refine.BUNDLE:
        from .bundle.refine import refine_bundle  # refine imports this module

        say("bundle refinement")
        t2 = time.perf_counter()
        refined = refine_bundle(
            result,
            gnss=gnss,
            imu=imu,
            blunders=blunders,
            max_iterations=ground_options.max_iterations,
            self_calibration=self_calibration,
            variance_components=options.weights is Weights.ESTIMATED,
        )
        timings["bundle"] = time.perf_counter() - t2
        result = dataclasses.replace(
            result,
            refined=refined,
            warnings=result.warnings + tuple(refined.warnings),
        )
    return _without_weak_checks(result)


def _run_options(
    options: AdjustmentOptions | None,
    strip_options: StripOptions | None,
    ground_options: GroundOptions | None,
    photo_step: int | Literal["auto"],
    min_base_to_height: float,
    refine: Refine | str,
) -> tuple[AdjustmentOptions, GroundOptions]:
    """The options of a run of :func:`triangulate`: ``options``, or the
    stages' options and the keywords made into one (giving both is an
    error); and its ground stage's options."""
    if options is None:
        ground_options = ground_options or GroundOptions()
        options = AdjustmentOptions.of_stages(
            strip_options or StripOptions(),
            ground_options,
            route=ground_options.route or Route.GEOCENTRIC,
            photo_step=photo_step,
            min_base_to_height=min_base_to_height,
            refine=refine,
        )
        return options, ground_options
    if (
        ground_options is not None
        or photo_step != DEFAULT_PHOTO_STEP
        or min_base_to_height != DEFAULT_MIN_BASE_TO_HEIGHT
        or refine != Refine.NONE
    ):
        raise ValueError(
            "Expected either `options` or `ground_options`, `photo_step`, `min_base_to_height` "
            "and `refine`, not both"
        )
    return options, options.ground_options()


@contextmanager
def _likely_cause(notes: Sequence[str]) -> Iterator[None]:
    """A geometry error raised within names the first of ``notes`` (a doubt
    about the input found earlier) as its likely cause."""
    try:
        yield
    except GeometryError as exc:
        if not notes or type(exc) is not GeometryError:
            raise
        raise GeometryError(f"{exc}; likely cause: {notes[0]}") from exc


def _strip_warnings(
    observations: ImageObservations,
    strip: StripModel,
    ground: GroundResult,
    warnings: Sequence[str],
) -> list[str]:
    """The warnings of a strip's run: those given, the breaks, every
    rejection, the control points left out and the points not triangulated."""
    notes = list(warnings) + list(strip.break_warnings)
    notes += [r.describe() for r in strip.rejections + ground.rejections]
    why = strip.lost_to_blunder_tests()
    notes += [
        PointWarning.not_triangulated(p, why.get(p, "seen on fewer than two photos of a model"))
        for p in ground.left_out
    ]
    lost = np.flatnonzero(~np.isfinite(ground.points).all(axis=1))
    ids = [observations.point_ids[i] for i in lost]
    for cause in ("seen on fewer than two photos", "their observations failed the blunder tests"):
        group = [p for p in ids if (p in why) == cause.startswith("their")]
        if group:
            notes.append(PointWarning.points_not_triangulated(group, cause))
    return notes


@limit_blas_threads
def triangulate_block(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS | str,
    strips: Sequence[StripSpec],
    *,
    options: AdjustmentOptions | None = None,
    strip_options: StripOptions | None = None,
    construction: Construction | str = Construction.MODELS,
    route: Route | str | None = None,
    blunders: BlunderOptions | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    refine: Refine | str = Refine.NONE,
    gnss: GnssCentres | None = None,
    imu: ImuAttitudes | None = None,
    progress: Progress | None = None,
    warnings: Sequence[str] = (),
    polynomial: int | None = None,
    control_name: str = "control",
    self_calibration: SelfCalibration | None = None,
) -> BlockResult:
    """Form every strip of a block and transform them all at once
    (:func:`strip_aerotri.block.strips.adjust_block`); control given in
    degrees under a projected CRS, or mirrored against the photos, stops it
    first (:func:`strip_aerotri.plausibility.control_problems`, as for one strip).

    ``options`` (a project's ``[adjustment]``, checked by
    :func:`strip_aerotri.options.adjustment_options` with ``block=True``)
    gives every option at once; then ``construction``, ``route``,
    ``max_iterations``, ``refine`` and ``polynomial`` must not be given.
    The result carries the options it ran with.
    """
    from .block.strips import adjust_block

    if options is None:
        construction = Construction.create(construction)
        options = AdjustmentOptions.of_stages(
            strip_options or StripOptions(max_iterations=max_iterations),
            GroundOptions(construction=construction, max_iterations=max_iterations),
            route=Route.GEOCENTRIC if route is None else route,
            refine=refine,
        )
        block_polynomial = DEFAULT_BLOCK_POLYNOMIAL if polynomial is None else polynomial
        options = dataclasses.replace(
            options,
            polynomial=block_polynomial if construction is Construction.STRIPS else 0,
        )
    elif (
        construction != Construction.MODELS
        or route is not None
        or max_iterations != DEFAULT_MAX_ITERATIONS
        or refine != Refine.NONE
        or polynomial is not None
    ):
        raise ValueError(
            "Expected either `options` or `construction`, `route`, `max_iterations`, `refine` "
            "and `polynomial`, not both"
        )
    else:
        route = options.route
    # degrees under a projected CRS, or control mirrored against the photos
    # (X and Y swapped): a block's run stops on them as one strip's does
    crs = GroundCRS.from_user_input(crs)  # once: pyproj's CRS and transformers are shared
    implausible = control_problems(observations, control, crs, file=control_name)
    if implausible:
        raise GeometryError(implausible[0])
    if progress is not None:
        progress(
            f"forming {len(strips)} strips and transforming the block "
            f"({options.block.value})"
        )
    with self_calibration_follows(
        self_calibration is not None and options.refine is Refine.BUNDLE
    ):
        result = adjust_block(
            observations,
            control,
            crs,
            strips,
            strip_options=options.strip_options() if strip_options is None else strip_options,
            construction=options.block,
            route=route,
            blunders=blunders,
            max_iterations=options.max_iterations,
            refine=options.refine is Refine.BUNDLE,
            gnss=gnss,
            imu=imu,
            polynomial=int(options.polynomial),
            self_calibration=self_calibration,
            variance_components=options.weights is Weights.ESTIMATED,
            control_name=control_name,
        )
    sigma = image_sigma_problems(
        np.concatenate([strip.relative.sigma0_um for strip in result.strips]), observations.sigma
    )
    result = dataclasses.replace(
        result, warnings=(*warnings, *sigma, *result.warnings), options=options
    )
    return _block_without_weak_checks(result, crs)


def _weak_check_warnings(weak: Sequence[WeakCheck]) -> tuple[PointWarning, ...]:
    """A warning naming each weakly determined check point and why."""
    from .ground.check_precision import weak_check_message

    return tuple(PointWarning.weak_check(w.point, weak_check_message(w)) for w in weak)


def _without_weak_checks(result: StripResult) -> StripResult:
    """The check statistics without the weakly determined check points, and a
    warning naming each (:mod:`strip_aerotri.ground.check_precision`)."""
    from .ground.check_precision import check_statistics_without, weak_checks_of

    ground, refined = result.ground, result.refined
    final = ground if refined is None else refined  # the photos as delivered
    weak = weak_checks_of(result.strip.observations, result.control, ground.crs, ground, final)
    if not weak:
        return result
    if refined is not None:
        refined = dataclasses.replace(
            refined, check_statistics=check_statistics_without(refined, result.control, weak)
        )
    return dataclasses.replace(
        result,
        check_statistics=check_statistics_without(ground, result.control, weak),
        refined=refined,
        warnings=result.warnings + _weak_check_warnings(weak),
        weak_checks=tuple(w.point for w in weak),
    )


def _block_without_weak_checks(result: BlockResult, crs: GroundCRS | str) -> BlockResult:
    """:func:`_without_weak_checks` of a block."""
    from .ground.check_precision import check_statistics_without, weak_checks_of

    ground_crs = crs if isinstance(crs, GroundCRS) else GroundCRS.from_user_input(crs)
    weak = weak_checks_of(result.observations, result.control, ground_crs, result, result)
    if not weak:
        return result
    own = result.block_check_statistics
    if result.block_control_residuals is not None:  # refined: the block's own, alike
        before = dataclasses.replace(result, control_residuals=result.block_control_residuals)
        own = check_statistics_without(before, result.control, weak)
    return dataclasses.replace(
        result,
        check_statistics=check_statistics_without(result, result.control, weak),
        block_check_statistics=own,
        warnings=result.warnings + _weak_check_warnings(weak),
        weak_checks=tuple(w.point for w in weak),
    )
