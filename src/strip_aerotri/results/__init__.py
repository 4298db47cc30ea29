"""The result types of every stage, typed, importing no stage.

Each stage returns one of these; the pipeline bundles them in a
:class:`StripResult`.  They depend only on the layers below the stages
(options, observations, geometry, geodesy), so any stage and the report can
import them without importing each other.
"""

from .block import BlockResult, StripJoin
from .bundle import (
    BundleResult,
    CameraEstimate,
    FrameRefinement,
    GnssResiduals,
    ImuResiduals,
    ParameterOutcome,
    RefinedResult,
    ResidualCells,
    SelfCalibrationOutcome,
    ShutterEstimate,
    VarianceComponents,
    VarianceGroup,
)
from .common import AccuracyStatistics, PointWarning, Rejection
from .ground import GroundResult, ModelAdjustment
from .run import StripResult
from .strip import RelativeOrientation, StripModel

__all__ = [
    "AccuracyStatistics",
    "BlockResult",
    "BundleResult",
    "CameraEstimate",
    "FrameRefinement",
    "GnssResiduals",
    "GroundResult",
    "ImuResiduals",
    "ModelAdjustment",
    "ParameterOutcome",
    "PointWarning",
    "RefinedResult",
    "ResidualCells",
    "SelfCalibrationOutcome",
    "ShutterEstimate",
    "Rejection",
    "RelativeOrientation",
    "StripJoin",
    "StripModel",
    "StripResult",
    "VarianceComponents",
    "VarianceGroup",
]
