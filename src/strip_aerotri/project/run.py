"""Adjust a loaded project: :func:`run_project`, the pipeline's call with the
project's own observations and options."""

from __future__ import annotations

from ..options import BlunderOptions, Construction, GroundOptions, StripOptions
from ..pipeline import Progress, triangulate, triangulate_block
from ..results import BlockResult, StripResult
from .model import Project

__all__ = ["project_options", "run_project"]


def project_options(project: Project) -> tuple[StripOptions, GroundOptions]:
    """The strip formation's and the ground stage's options of a loaded project."""
    return project.adjustment.strip_options(), project.adjustment.ground_options()


def run_project(
    project: Project, *, progress: Progress | None = None, blunders: BlunderOptions | None = None
) -> StripResult | BlockResult:
    """Adjust a loaded project (:func:`strip_aerotri.project.load_project`).

    ``blunders`` overrides the project's own blunder options.  The project's
    GNSS centres and IMU attitudes (``[gnss]``, ``[imu]``), if any, are
    observations of the bundle refinement.
    """
    adj = project.adjustment
    if project.is_block:
        return triangulate_block(
            project.observations,
            project.control,
            project.crs,
            project.strips,
            strip_options=adj.strip_options(),
            construction=adj.block,
            route=adj.route,
            blunders=project.blunders if blunders is None else blunders,
            max_iterations=adj.max_iterations,
            refine=adj.refine,
            gnss=project.gnss,
            imu=project.imu,
            progress=progress,
            warnings=project.warnings,
            polynomial=int(adj.polynomial) if adj.block is Construction.STRIPS else 0,
        )
    return triangulate(
        project.observations,
        project.control,
        project.crs,
        lines=project.straight_lines,
        strip_options=adj.strip_options(),
        ground_options=adj.ground_options(),
        blunders=project.blunders if blunders is None else blunders,
        photo_step=adj.photo_step,
        min_base_to_height=adj.min_base_to_height,
        refine=adj.refine,
        gnss=project.gnss,
        imu=project.imu,
        progress=progress,
        warnings=project.warnings,
        control_name=str(project.control_file),
    )
