"""Adjust a loaded project: :func:`run_project`, the pipeline's call with the
project's own observations and options."""

from __future__ import annotations

from .._threads import limit_blas_threads
from .._typing import IntArray
from ..errors import FlightAxisError, GeometryError, PhotoOrderError
from ..options import BlunderOptions, GroundOptions, StripOptions
from ..pipeline import Progress, triangulate, triangulate_block
from ..plausibility import flight_axis_message, photo_order_hint, photo_order_message
from ..results import BlockResult, StripResult
from ..strip.densify import first_model_step, model_photo_index
from ..strip.relative import MIN_POINTS_PER_PAIR
from .model import Project

__all__ = ["explain", "project_options", "run_project"]


def explain(project: Project, exc: GeometryError, strip: str | None = None) -> GeometryError:
    """``exc`` with the hint that fits the project: the opposite of its own
    ``[images] flight_direction``, a block's ``[[strips]]`` entry.

    ``strip`` names the strip of a block when ``exc`` does not; other errors
    are returned as they are.
    """
    direction = project.images.flight_direction
    if isinstance(exc, PhotoOrderError):
        strip = exc.strip or strip
        message = photo_order_message(
            exc.n_wrong, exc.n_pairs, flight_direction=direction, strip=strip
        )
        return PhotoOrderError(
            message if strip is None else f"strip '{strip}': {message}",
            n_wrong=exc.n_wrong,
            n_pairs=exc.n_pairs,
            strip=strip,
        )
    if isinstance(exc, FlightAxisError):
        strip = exc.strip or strip
        message = flight_axis_message(exc.pair, exc.along, flight_direction=direction)
        return FlightAxisError(
            message if strip is None else f"strip '{strip}': {message}",
            pair=exc.pair,
            along=exc.along,
            strip=strip,
        )
    return exc


def project_options(project: Project) -> tuple[StripOptions, GroundOptions]:
    """The strip formation's and the ground stage's options of a loaded project."""
    return project.adjustment.strip_options(), project.adjustment.ground_options()


@limit_blas_threads
def run_project(
    project: Project, *, progress: Progress | None = None, blunders: BlunderOptions | None = None
) -> StripResult | BlockResult:
    """Adjust a loaded project (:func:`strip_aerotri.project.load_project`).

    ``blunders`` overrides the project's own blunder options.  The project's
    GNSS centres and IMU attitudes (``[gnss]``, ``[imu]``), if any, are
    observations of the bundle refinement.
    """
    order = _photo_order_problem(project)
    if order:
        raise GeometryError(order)
    try:
        return _run(project, progress, blunders)
    except (PhotoOrderError, FlightAxisError) as exc:
        raise explain(project, exc) from exc


def model_photos(n_photos: int, photo_step: int | str) -> IntArray:
    """The photos (positions in a strip's listed order) whose consecutive
    pairs the run orients first: every k-th with ``photo_step = k``
    (:func:`strip_aerotri.strip.densify.model_photo_index`), every photo
    with ``"auto"`` (its first relative orientation is of all consecutive
    pairs, :func:`~strip_aerotri.strip.densify.choose_photo_step`)."""
    return model_photo_index(n_photos, first_model_step(photo_step))


def _photo_order_problem(project: Project) -> str:
    """Consecutive model photos of a strip (:func:`model_photos`) without
    enough common points for their relative orientation, because the photos
    are listed out of flight order
    (:func:`strip_aerotri.plausibility.photo_order_hint`, as ``check`` runs
    it): the pair's failure, with its cause.  Empty when the order is not to
    blame."""
    obs = project.observations
    index = {pid: i for i, pid in enumerate(obs.photo_ids)}
    for spec in project.strips or (None,):
        listed = obs.photo_ids if spec is None else spec.photo_ids
        ids = [listed[i] for i in model_photos(len(listed), project.adjustment.photo_step)]
        m, hint = photo_order_hint(obs, [index[p] for p in ids], None, MIN_POINTS_PER_PAIR)
        if hint:
            where = "" if spec is None else f"strip '{spec.name}': "
            return (
                f"{project.images_file}: {where}pair {ids[m]}-{ids[m + 1]}: fewer than "
                f"{MIN_POINTS_PER_PAIR} points measured on both photos (a relative "
                f"orientation needs {MIN_POINTS_PER_PAIR}); {hint}"
            )
    return ""


def _run(
    project: Project, progress: Progress | None, blunders: BlunderOptions | None
) -> StripResult | BlockResult:
    adj = project.adjustment
    calibration = adj.calibration(project.images.flight_direction)
    blunders = project.blunders if blunders is None else blunders
    if project.is_block:
        return triangulate_block(
            project.observations,
            project.control,
            project.crs,
            project.strips,
            options=adj,
            blunders=blunders,
            gnss=project.gnss,
            imu=project.imu,
            progress=progress,
            warnings=project.warnings,
            control_name=str(project.control_file),
            self_calibration=calibration,
        )
    return triangulate(
        project.observations,
        project.control,
        project.crs,
        lines=project.straight_lines,
        options=adj,
        blunders=blunders,
        gnss=project.gnss,
        imu=project.imu,
        progress=progress,
        warnings=project.warnings,
        control_name=str(project.control_file),
        self_calibration=calibration,
    )
