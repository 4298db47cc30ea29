"""The loaded project: :class:`Camera` and :class:`Project`, frozen, in
library units (image millimetres, ground metres, radians).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._typing import FloatArray
from ..interior import (
    BrownDistortion,
    FiducialFit,
)
from ..observations import (
    ControlPoints,
    GnssCentres,
    ImageObservations,
    ImuAttitudes,
    LineSpec,
    StripSpec,
)
from ..options import (
    AdjustmentOptions,
    BlunderOptions,
    ImageOptions,
    ReportOptions,
)


def readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Camera:
    """Interior orientation.

    Attributes
    ----------
    principal_distance_mm : float
        c in millimetres.
    principal_point_mm : ndarray, shape (2,)
        x0, y0 in millimetres (already subtracted from the observations).
    """

    principal_distance_mm: float
    principal_point_mm: FloatArray


@dataclass(frozen=True)
class Project:
    """A validated project: everything a run needs, in library units.

    Attributes
    ----------
    path : Path
        The project file, as given.
    name : str
    photo_ids : tuple of str
        Photos in strip (flight) order.
    camera : Camera
    observations : ImageObservations
        Image x, y in mm in the method's axes (x along the flight, y to its
        left), from pixels if so given, through the fiducial transformation,
        reduced by the principal point, corrected for distortion; sigma in mm.
    control : ControlPoints
        Control and check points observed on at least one photo.
    crs : str
        ``[control] crs`` as given (``"local"`` in lower case).
    straight_lines : tuple of LineSpec
    adjustment : AdjustmentOptions
    output_directory : Path or None
        ``[output] directory`` joined to the project folder.
    warnings : tuple of str
        Valid but doubtful things found while loading (each names its point or
        file); they are not emitted as Python warnings.
    images_file, control_file : Path
        The input CSVs, joined to the project folder.
    report : ReportOptions
    images : ImageOptions
    distortion : BrownDistortion or None
        ``[distortion]`` (None without the table).
    fiducials : tuple of FiducialFit
        Per-photo interior orientation from ``[interior_orientation]`` (empty
        without it), with the residuals at the marks and R4 §1.7.7.1's check.
    fiducials_file : Path or None
    blunders : BlunderOptions
    gnss : GnssCentres or None
        ``[gnss]``: observed projection centres in the control CRS (None
        without the table); rows of photos not in the strip are left out.
    imu : ImuAttitudes or None
        ``[imu]``: observed attitudes in radians (None without the table).
    gnss_file, imu_file : Path or None
    strips : tuple of StripSpec
        The strips of a block (``[[strips]]``), empty for one ``[strip]``;
        ``photo_ids`` is then their photos, strip after strip.
        Their CSVs, joined to the project folder.
    """

    path: Path
    name: str
    photo_ids: tuple[str, ...]
    camera: Camera
    observations: ImageObservations
    control: ControlPoints
    crs: str
    straight_lines: tuple[LineSpec, ...]
    adjustment: AdjustmentOptions
    output_directory: Path | None
    warnings: tuple[str, ...]
    images_file: Path
    control_file: Path
    report: ReportOptions = field(default_factory=ReportOptions)
    images: ImageOptions = field(default_factory=ImageOptions)
    distortion: BrownDistortion | None = None
    fiducials: tuple[FiducialFit, ...] = ()
    fiducials_file: Path | None = None
    blunders: BlunderOptions = field(default_factory=BlunderOptions)
    gnss: GnssCentres | None = None
    imu: ImuAttitudes | None = None
    gnss_file: Path | None = None
    imu_file: Path | None = None
    strips: tuple[StripSpec, ...] = ()

    @property
    def is_block(self) -> bool:
        """True for a block of two or more ``[[strips]]``."""
        return len(self.strips) >= 2

    @property
    def input_files(self) -> tuple[Path, ...]:
        """The project file and the CSVs it names."""
        extra = tuple(
            f for f in (self.fiducials_file, self.gnss_file, self.imu_file) if f is not None
        )
        return (self.path, self.images_file, self.control_file, *extra)

    @property
    def is_local(self) -> bool:
        """True for ``crs = "local"`` (no geodesy)."""
        return self.crs == "local"
