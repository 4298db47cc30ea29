"""strip_aerotri: analytical strip aerotriangulation by partially dependent models.

From image coordinates measured on one strip of overlapping photos and a few
ground control points, compute the ground coordinates of every measured point
and the exterior orientation of every photo (method.md):

>>> import strip_aerotri as sa
>>> sim = sa.simulate_strip(8, seed=1)
>>> result = sa.triangulate(sim.observations, sim.control, sim.crs)
>>> bool(result.check_statistics.rmse_plan < 0.2)
True
"""

from __future__ import annotations

__version__ = "0.1.0"

from .chaining import StripModel, StripOptions, form_strip
from .deformation import (
    DeformationResult,
    KindSelection,
    StraightLine,
    fit_deformation,
    polynomial_terms,
    select_kind_auto,
)
from .errors import (
    ConfigError,
    ConvergenceError,
    GeometryError,
    StripAerotriError,
    StripAerotriWarning,
)
from .geodesy import (
    GroundCRS,
    LocalTangentFrame,
    azimuth_from_local_enu,
    earth_curvature_correction,
    enu_rotation,
    gaussian_mean_radius,
)
from .ground import GroundOptions, GroundResult, LineSpec, Route, adjust_to_ground
from .intersection import IntersectionMethod, intersect, intersect_midpoint, intersect_normal
from .observations import ControlPoints, ControlType, ImageObservations
from .pipeline import AccuracyStatistics, StripResult, run_project, triangulate
from .relative import (
    RelativeOrientation,
    RelativeOrientationMethod,
    chain_rotations,
    essential_start,
    relative_orientation,
)
from .rotation import (
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
from .scaling import ScaleTransfer, scale_ratios, scale_ratios_distance, scale_ratios_z
from .similarity import (
    SimilarityResult,
    SimilarityTransform,
    fit_similarity,
    similarity_from_points,
)
from .simulate import PRESETS, SimulatedStrip, SimulationTruth, StripPreset, simulate_strip

__all__ = [
    "PRESETS",
    "AccuracyStatistics",
    "ConfigError",
    "ControlPoints",
    "ControlType",
    "ConvergenceError",
    "DeformationResult",
    "GeometryError",
    "GroundCRS",
    "GroundOptions",
    "GroundResult",
    "ImageObservations",
    "IntersectionMethod",
    "KindSelection",
    "LineSpec",
    "LocalTangentFrame",
    "RelativeOrientation",
    "RelativeOrientationMethod",
    "Route",
    "ScaleTransfer",
    "SimilarityResult",
    "SimilarityTransform",
    "SimulatedStrip",
    "SimulationTruth",
    "StraightLine",
    "StripAerotriError",
    "StripAerotriWarning",
    "StripModel",
    "StripOptions",
    "StripPreset",
    "StripResult",
    "__version__",
    "adjust_to_ground",
    "azimuth_from_local_enu",
    "cardan_from_matrix",
    "cardan_from_opk",
    "cardan_from_schut",
    "chain_rotations",
    "check_matrix",
    "earth_curvature_correction",
    "enu_rotation",
    "essential_start",
    "fit_deformation",
    "fit_similarity",
    "form_strip",
    "gaussian_mean_radius",
    "intersect",
    "intersect_midpoint",
    "intersect_normal",
    "matrix_from_cardan",
    "matrix_from_opk",
    "matrix_from_rotvec",
    "matrix_from_schut",
    "opk_from_cardan",
    "opk_from_matrix",
    "opk_from_schut",
    "polynomial_terms",
    "relative_orientation",
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
    "simulate_strip",
    "skew",
    "triangulate",
]
