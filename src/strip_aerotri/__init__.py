"""strip_aerotri: analytical strip aerotriangulation by partially dependent models.

From image coordinates measured on one strip of overlapping photos and a few
ground control points, compute the ground coordinates of every measured point
and the exterior orientation of every photo (docs/method.md):

>>> import strip_aerotri as sa
>>> sim = sa.simulate_strip(8, seed=1)
>>> result = sa.triangulate(sim.observations, sim.control, sim.crs)
>>> bool(result.check_statistics.rmse_plan < 0.2)
True

Every public name is here, imported from its module when it is first used;
scipy, pyproj and matplotlib are imported inside the functions that need
them.  So ``import strip_aerotri`` loads nothing heavy, and a command of
``stripaero`` only the modules it uses.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

if TYPE_CHECKING:  # the public names, for type checkers; at run time see __getattr__
    from .blunders import critical_value
    from .bundle.adjust import bundle_adjust
    from .bundle.refine import refine_bundle
    from .errors import (
        ConfigError,
        ConvergenceError,
        GeometryError,
        StripAerotriError,
        StripAerotriWarning,
    )
    from .frames import LocalTangentFrame
    from .geodesy import (
        GroundCRS,
        azimuth_from_local_enu,
        earth_curvature_correction,
        enu_rotation,
        gaussian_mean_radius,
    )
    from .geometry.deformation import (
        DeformationResult,
        StraightLine,
        fit_deformation,
        polynomial_terms,
    )
    from .geometry.camera_model import CameraModel, ShutterMotion
    from .geometry.deformation_auto import KindSelection, select_kind_auto
    from .geometry.intersection import intersect, intersect_midpoint, intersect_normal
    from .geometry.normals import (
        BorderRows,
        Cofactors,
        FormedNormals,
        NormalSolution,
        NormalStructure,
        PointRows,
        SingularNormalsError,
        UnitPointRows,
        UnitRows,
    )
    from .geometry.rotation import (
        cardan_from_matrix,
        cardan_from_opk,
        cardan_from_schut,
        check_matrix,
        matrix_from_cardan,
        matrix_from_opk,
        matrix_from_rotvec,
        matrix_from_schut,
        opk_from_cardan,
        opk_from_matrix,
        opk_from_schut,
        rotvec_from_matrix,
        schut_from_cardan,
        schut_from_matrix,
        schut_from_opk,
        skew,
    )
    from .geometry.similarity import (
        SimilarityResult,
        SimilarityTransform,
        fit_similarity,
        similarity_from_points,
    )
    from .ground.polynomials import adjust_to_ground
    from .interior import (
        BrownDistortion,
        FiducialFit,
        correct_distortion,
        fit_fiducial_transform,
        flight_from_sensor,
        mm_from_pixel,
        reduce_image_coordinates,
    )
    from .observations import (
        ControlPoints,
        ControlType,
        GnssCentres,
        ImageObservations,
        ImuAttitudes,
        LineSpec,
    )
    from .options import (
        BlunderOptions,
        FlightDirection,
        GroundOptions,
        IntersectionMethod,
        RelativeOrientationMethod,
        Route,
        ScaleTransfer,
        StripOptions,
        SelfCalibration,
        Weights,
    )
    from .pipeline import triangulate
    from .project import Project, load_project, run_project
    from .report.files import OutputError, ResultFolder, write_result_folder
    from .report.outputs import build_outputs, build_report
    from .report.summary import (
        EstimatedWeights,
        RunOutputs,
        RunSummary,
        build_run,
        summarize,
    )
    from .report.tolerances import Criterion, chance_beyond, tolerance_verdicts
    from .report.verdict import Verdict, overall_verdict
    from .results import (
        AccuracyStatistics,
        BundleResult,
        GnssResiduals,
        GroundResult,
        ImuResiduals,
        PointWarning,
        RefinedResult,
        Rejection,
        RelativeOrientation,
        StripModel,
        StripResult,
        CameraEstimate,
        SelfCalibrationOutcome,
        ShutterEstimate,
        VarianceComponents,
        VarianceGroup,
    )
    from .simulate import (
        PRESETS,
        BlockStrip,
        SimulatedBlock,
        SimulatedStrip,
        SimulationTruth,
        StripPreset,
        simulate_block,
        simulate_strip,
    )
    from .strip.chaining import form_strip
    from .strip.densify import (
        choose_photo_step,
        complete_strip,
        form_strip_stepped,
        intersect_rays,
        model_photo_index,
        resect,
    )
    from .strip.relative import chain_rotations, essential_start, relative_orientation
    from .strip.scaling import scale_ratios, scale_ratios_distance, scale_ratios_z

#: The module of every public name: imported when the name is first used (PEP
#: 562), so that ``import strip_aerotri`` and a command of ``stripaero`` load
#: only the modules they use (tests/test_package.py holds it to the imports above).
_MODULES: dict[str, tuple[str, ...]] = {
    ".blunders": ("critical_value",),
    ".bundle.adjust": ("bundle_adjust",),
    ".bundle.refine": ("refine_bundle",),
    ".errors": (
        "ConfigError",
        "ConvergenceError",
        "GeometryError",
        "StripAerotriError",
        "StripAerotriWarning",
    ),
    ".frames": ("LocalTangentFrame",),
    ".geodesy": (
        "GroundCRS",
        "azimuth_from_local_enu",
        "earth_curvature_correction",
        "enu_rotation",
        "gaussian_mean_radius",
    ),
    ".geometry.deformation": (
        "DeformationResult",
        "StraightLine",
        "fit_deformation",
        "polynomial_terms",
    ),
    ".geometry.camera_model": ("CameraModel", "ShutterMotion"),
    ".geometry.deformation_auto": ("KindSelection", "select_kind_auto"),
    ".geometry.intersection": ("intersect", "intersect_midpoint", "intersect_normal"),
    ".geometry.normals": (
        "BorderRows",
        "Cofactors",
        "FormedNormals",
        "NormalSolution",
        "NormalStructure",
        "PointRows",
        "SingularNormalsError",
        "UnitPointRows",
        "UnitRows",
    ),
    ".geometry.rotation": (
        "cardan_from_matrix",
        "cardan_from_opk",
        "cardan_from_schut",
        "check_matrix",
        "matrix_from_cardan",
        "matrix_from_opk",
        "matrix_from_rotvec",
        "matrix_from_schut",
        "opk_from_cardan",
        "opk_from_matrix",
        "opk_from_schut",
        "rotvec_from_matrix",
        "schut_from_cardan",
        "schut_from_matrix",
        "schut_from_opk",
        "skew",
    ),
    ".geometry.similarity": (
        "SimilarityResult",
        "SimilarityTransform",
        "fit_similarity",
        "similarity_from_points",
    ),
    ".ground.polynomials": ("adjust_to_ground",),
    ".interior": (
        "BrownDistortion",
        "FiducialFit",
        "correct_distortion",
        "fit_fiducial_transform",
        "flight_from_sensor",
        "mm_from_pixel",
        "reduce_image_coordinates",
    ),
    ".observations": (
        "ControlPoints",
        "ControlType",
        "GnssCentres",
        "ImageObservations",
        "ImuAttitudes",
        "LineSpec",
    ),
    ".options": (
        "BlunderOptions",
        "FlightDirection",
        "GroundOptions",
        "IntersectionMethod",
        "RelativeOrientationMethod",
        "Route",
        "ScaleTransfer",
        "StripOptions",
        "SelfCalibration",
        "Weights",
    ),
    ".pipeline": ("triangulate",),
    ".project": ("Project", "load_project", "run_project"),
    ".report.files": ("OutputError", "ResultFolder", "write_result_folder"),
    ".report.outputs": ("build_outputs", "build_report"),
    ".report.summary": (
        "EstimatedWeights",
        "RunOutputs",
        "RunSummary",
        "build_run",
        "summarize",
    ),
    ".report.tolerances": ("Criterion", "chance_beyond", "tolerance_verdicts"),
    ".report.verdict": ("Verdict", "overall_verdict"),
    ".results": (
        "AccuracyStatistics",
        "BundleResult",
        "GnssResiduals",
        "GroundResult",
        "ImuResiduals",
        "PointWarning",
        "RefinedResult",
        "Rejection",
        "RelativeOrientation",
        "StripModel",
        "StripResult",
        "CameraEstimate",
        "SelfCalibrationOutcome",
        "ShutterEstimate",
        "VarianceComponents",
        "VarianceGroup",
    ),
    ".simulate": (
        "PRESETS",
        "BlockStrip",
        "SimulatedBlock",
        "SimulatedStrip",
        "SimulationTruth",
        "StripPreset",
        "simulate_block",
        "simulate_strip",
    ),
    ".strip.chaining": ("form_strip",),
    ".strip.densify": (
        "choose_photo_step",
        "complete_strip",
        "form_strip_stepped",
        "intersect_rays",
        "model_photo_index",
        "resect",
    ),
    ".strip.relative": ("chain_rotations", "essential_start", "relative_orientation"),
    ".strip.scaling": ("scale_ratios", "scale_ratios_distance", "scale_ratios_z"),
}
_WHERE = {name: module for module, names in _MODULES.items() for name in names}


def __getattr__(name: str) -> Any:
    """A public name, imported from its module on first use (PEP 562); a
    subpackage or module of the package by its name (``strip_aerotri.report``),
    as when every module was imported with the package."""
    module = _WHERE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
    elif not name.startswith("_"):
        try:
            value = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise  # a module of the package that imports something missing
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # later uses find it without this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_WHERE})


__all__ = [
    "PRESETS",
    "AccuracyStatistics",
    "BlockStrip",
    "BlunderOptions",
    "BorderRows",
    "BrownDistortion",
    "BundleResult",
    "CameraEstimate",
    "CameraModel",
    "SelfCalibration",
    "SelfCalibrationOutcome",
    "ShutterEstimate",
    "ShutterMotion",
    "VarianceComponents",
    "VarianceGroup",
    "Weights",
    "Cofactors",
    "ConfigError",
    "ControlPoints",
    "ControlType",
    "ConvergenceError",
    "Criterion",
    "DeformationResult",
    "FiducialFit",
    "FlightDirection",
    "FormedNormals",
    "GeometryError",
    "GnssCentres",
    "GnssResiduals",
    "GroundCRS",
    "GroundOptions",
    "GroundResult",
    "ImageObservations",
    "ImuAttitudes",
    "ImuResiduals",
    "IntersectionMethod",
    "KindSelection",
    "LineSpec",
    "LocalTangentFrame",
    "NormalSolution",
    "NormalStructure",
    "OutputError",
    "PointRows",
    "PointWarning",
    "Project",
    "RefinedResult",
    "Rejection",
    "RelativeOrientation",
    "RelativeOrientationMethod",
    "ResultFolder",
    "EstimatedWeights",
    "RunOutputs",
    "RunSummary",
    "Route",
    "ScaleTransfer",
    "SimilarityResult",
    "SimilarityTransform",
    "SimulatedBlock",
    "SimulatedStrip",
    "SimulationTruth",
    "SingularNormalsError",
    "StraightLine",
    "StripAerotriError",
    "StripAerotriWarning",
    "StripModel",
    "StripOptions",
    "StripPreset",
    "StripResult",
    "UnitPointRows",
    "UnitRows",
    "Verdict",
    "__version__",
    "adjust_to_ground",
    "azimuth_from_local_enu",
    "build_outputs",
    "build_run",
    "build_report",
    "bundle_adjust",
    "cardan_from_matrix",
    "cardan_from_opk",
    "cardan_from_schut",
    "chain_rotations",
    "chance_beyond",
    "check_matrix",
    "choose_photo_step",
    "complete_strip",
    "correct_distortion",
    "critical_value",
    "earth_curvature_correction",
    "enu_rotation",
    "essential_start",
    "fit_deformation",
    "fit_fiducial_transform",
    "fit_similarity",
    "flight_from_sensor",
    "form_strip",
    "form_strip_stepped",
    "gaussian_mean_radius",
    "intersect",
    "intersect_midpoint",
    "intersect_normal",
    "intersect_rays",
    "load_project",
    "matrix_from_cardan",
    "matrix_from_opk",
    "matrix_from_rotvec",
    "matrix_from_schut",
    "mm_from_pixel",
    "model_photo_index",
    "opk_from_cardan",
    "opk_from_matrix",
    "opk_from_schut",
    "overall_verdict",
    "polynomial_terms",
    "reduce_image_coordinates",
    "refine_bundle",
    "relative_orientation",
    "resect",
    "rotvec_from_matrix",
    "run_project",
    "scale_ratios",
    "scale_ratios_distance",
    "scale_ratios_z",
    "schut_from_cardan",
    "schut_from_matrix",
    "schut_from_opk",
    "select_kind_auto",
    "similarity_from_points",
    "simulate_block",
    "simulate_strip",
    "skew",
    "summarize",
    "tolerance_verdicts",
    "triangulate",
    "write_result_folder",
]
