"""Results of the ground stage: the strip on the control, and the models'
simultaneous transformation."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._typing import FloatArray, IntArray
from ..frames import LocalTangentFrame
from ..geodesy import GroundCRS
from ..geometry.deformation import DeformationResult
from ..geometry.deformation_auto import KindSelection
from ..geometry.similarity import SimilarityResult
from ..geometry.simultaneous import SimultaneousResult
from ..options import Construction, Route
from .common import Rejection

__all__ = ["GroundResult", "ModelAdjustment"]


@dataclass(frozen=True)
class GroundResult:
    """The strip in the ground system.

    Work-frame arrays are in metres in the frame described in the module
    docstring; CRS arrays in the control CRS (X, Y in its axis order as
    pyproj's ``always_xy`` understands it, H ellipsoidal height in metres).
    Residuals are *given minus adjusted* in metres along local east, north
    and up (grid east and north on the projected route).

    Attributes
    ----------
    route : Route
    crs : GroundCRS
    azimuth : float
        A0, azimuth (clockwise from north, radians) of the work frame's X
        axis: geodetic on the geocentric route, grid azimuth on the projected.
    frame : LocalTangentFrame or None
        The intermediate system of the geocentric route.
    similarity : SimilarityResult
        Strip system -> work frame.
    deformation : DeformationResult or None
        None when the polynomial type is 0.
    kind_selection : KindSelection or None
        The table behind ``polynomial = "auto"``.
    points_work, points : ndarray, shape (P, 3)
        Every point of ``strip.observations.point_ids`` (NaN if not
        triangulated), work frame and CRS.
    photo_centres_work, photo_centres : ndarray, shape (M, 3)
        Photos of ``strip.photo_index``.
    photo_rotations_work : ndarray, shape (M, 3, 3)
        Image -> work frame.
    photo_rotations_enu : ndarray, shape (M, 3, 3)
        Image -> local east-north-up at the projection centre (image -> X, Y,
        H axes for ``crs = "local"``).
    photo_opk : ndarray, shape (M, 3)
        omega, phi, kappa (radians) of ``photo_rotations_enu = Rx Ry Rz``.
    control_index : ndarray of int, shape (C,)
        Rows of ``control`` used or checked (observed and triangulated).
    control_residuals : ndarray, shape (C, 3)
        Given minus adjusted (E, N, H), NaN for coordinates not given; check
        points included (their rows have ``is_check``).
    is_check : ndarray of bool, shape (C,)
    left_out : tuple of str
        Control points not triangulated (seen on fewer than two photos of a
        model), left out with a warning.
    passes : int
        Passes of the plan/height iteration.
    passes_converged : bool
    image_scale : float
        Metres on the ground per mm on the image (median over the model points).
    expected_sigma_plan, expected_sigma_height : float
        Random error of a photogrammetric point expected from the image sigma,
        metres: the weights of the ground stage combine them with the control
        sigmas.
    used_xy, used_h : ndarray of bool, shape (C,)
        Control coordinates that entered the final adjustment (False where a
        blunder was rejected or for check points).
    line_used : tuple of ndarray of bool
        Line points that entered the final fit.
    rejections : tuple of Rejection
        Control and line observations that failed the blunder tests (and,
        with ``applied`` False and an ``effect`` saying so, those kept
        because their rejection would leave the control unable to carry
        the strip).
    control_redundancy : ndarray, shape (C, 3)
        Redundancy numbers of the control components used (NaN elsewhere):
        the share of an error of the component that shows in its residual.
    control_mde : ndarray, shape (C, 3)
        Minimal detectable error of each used component, metres (Baarda:
        ``σ δ0 / sqrt(r)``, δ0 for the stage's critical value and 80 %
        power; inf where r is 0: an error there cannot be detected at all).
    models : ModelAdjustment or None
        The simultaneous transformation of the models (construction
        ``"models"``, :mod:`strip_aerotri.ground_models`).
    """

    route: Route
    crs: GroundCRS
    azimuth: float
    frame: LocalTangentFrame | None
    similarity: SimilarityResult
    deformation: DeformationResult | None
    kind_selection: KindSelection | None
    points_work: FloatArray
    points: FloatArray
    photo_centres_work: FloatArray
    photo_centres: FloatArray
    photo_rotations_work: FloatArray
    photo_rotations_enu: FloatArray
    photo_opk: FloatArray
    control_index: IntArray
    control_residuals: FloatArray
    is_check: np.ndarray
    line_names: tuple[str, ...]
    line_point_index: tuple[IntArray, ...]
    line_residuals: tuple[FloatArray, ...]
    left_out: tuple[str, ...]
    passes: int
    passes_converged: bool
    image_scale: float
    expected_sigma_plan: float
    expected_sigma_height: float
    used_xy: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    used_h: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    line_used: tuple[np.ndarray, ...] = ()
    rejections: tuple[Rejection, ...] = ()
    control_redundancy: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    control_mde: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    models: ModelAdjustment | None = None

    @property
    def construction(self) -> Construction:
        """How the strip went to the ground."""
        return Construction.STRIPS if self.models is None else Construction.MODELS

    @property
    def polynomial_kind(self) -> int:
        return 0 if self.deformation is None else self.deformation.kind


@dataclass(frozen=True)
class ModelAdjustment:
    """The simultaneous transformation of the models of a strip.

    Attributes
    ----------
    result : SimultaneousResult
        Units are the models (unit m is model m); points ``0 .. P − 1`` are
        the strip's points, ``P + j`` the projection centre of photo j.
    model : ndarray of int, shape (n,)
        Model of each determination (rows of the strip's ``model_points``
        that took part; rejected ones left out).
    point : ndarray of int, shape (n,)
        Its point.
    discrepancy : ndarray, shape (n, 3)
        Its residual, model point minus adjusted point, metres along the
        work frame (X along the strip, Y left, Z up): the "differences
        between determinations" of R4 §2.2, after the adjustment.
    model_rms : ndarray, shape (M, 3)
        RMS of the discrepancies of each model's points, metres.
    centre_discrepancy : ndarray, shape (M, 2, 3)
        Left and right projection centre of each model minus its adjusted
        position, metres.
    rejected : tuple of (str, str)
        (model label, point id) of determinations left out as gross errors.
    """

    result: SimultaneousResult
    model: IntArray
    point: IntArray
    discrepancy: FloatArray
    model_rms: FloatArray
    centre_discrepancy: FloatArray
    rejected: tuple[tuple[str, str], ...] = ()

    @property
    def sigma0(self) -> float:
        return self.result.sigma0
