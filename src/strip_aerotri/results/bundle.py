"""Results of the bundle adjustment and of the bundle refinement."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..frames import LocalTangentFrame
from ..geometry.camera_model import CameraModel, ShutterMotion
from .common import AccuracyStatistics, Rejection

__all__ = [
    "BundleResult",
    "CameraEstimate",
    "FrameRefinement",
    "GnssResiduals",
    "ImuResiduals",
    "ParameterOutcome",
    "RefinedResult",
    "ResidualCells",
    "SelfCalibrationOutcome",
    "ShutterEstimate",
    "VarianceComponents",
    "VarianceGroup",
]


@dataclass(frozen=True)
class CameraEstimate:
    """The self-calibrated camera of a bundle adjustment.

    Attributes
    ----------
    model : CameraModel
        The estimated parameters and how they act.
    values : ndarray, shape (k,)
        Their estimates (increments from the start camera; units in
        :data:`strip_aerotri.geometry.camera_model.PARAMETER_UNITS`).
    cofactor : ndarray, shape (k, k)
        Their cofactor matrix ``Q`` (the block of ``N^-1``).
    sigma0 : float
        The adjustment's sigma0.
    information : ndarray, shape (k,)
        Diagonal of the camera's own normal block ``G``.
    conditional_information : ndarray, shape (k,)
        Diagonal of the border's Schur complement ``C`` (the information
        left to each parameter once photos and points are estimated too).
    """

    model: CameraModel
    values: FloatArray
    cofactor: FloatArray
    sigma0: float
    information: FloatArray
    conditional_information: FloatArray

    @property
    def names(self) -> tuple[str, ...]:
        """The estimated parameters' names."""
        return self.model.estimated

    @property
    def std(self) -> FloatArray:
        """Standard deviations ``sigma0 sqrt(Q_ii)``."""
        out: FloatArray = self.sigma0 * np.sqrt(np.diag(self.cofactor))
        return out

    @property
    def t_values(self) -> FloatArray:
        """``value / std`` of each parameter."""
        out: FloatArray = self.values / self.std
        return out

    @property
    def correlations(self) -> FloatArray:
        """Correlation matrix (k, k) of the parameters."""
        d = 1.0 / np.sqrt(np.diag(self.cofactor))
        out: FloatArray = self.cofactor * d[:, None] * d[None, :]
        return out

    @property
    def orientation_correlation(self) -> FloatArray:
        """Multiple correlation (k,) of each parameter with the photos' orientation
        and the points: ``sqrt(1 - C_ii / G_ii)`` (0: independent of them; 1: they
        absorb it entirely, e.g. c with the flying height over flat ground)."""
        ratio = self.conditional_information / np.maximum(self.information, 1e-300)
        out: FloatArray = np.sqrt(np.clip(1.0 - ratio, 0.0, 1.0))
        return out


@dataclass(frozen=True)
class ParameterOutcome:
    """One camera parameter of a self-calibration.

    ``value``, ``std`` and ``t`` are those of the last adjustment that
    estimated it (NaN if none did); ``kept`` says whether the delivered
    adjustment estimates it, ``reason`` why not (empty when kept).
    ``orientation_correlation`` is its multiple correlation with the photos'
    orientation and the points.
    """

    name: str
    unit: str
    value: float
    std: float
    t: float
    kept: bool
    reason: str
    orientation_correlation: float


@dataclass(frozen=True)
class ResidualCells:
    """Image residuals averaged in cells over the format (sensor axes, x right, y up).

    Attributes
    ----------
    x_edges, y_edges : ndarray
        Cell edges in mm.
    after : ndarray, shape (ny, nx, 2)
        Mean residual ``x̂ - x_obs`` per cell, µm, with the
        self-calibration (``x̂ + Δ(x̂) = x`` the projection); NaN in empty cells.
    before : ndarray, shape (ny, nx, 2)
        The same with the camera's correction added back, ``x - x_obs``:
        what the orientation would have to absorb without it.
    count : ndarray of int, shape (ny, nx)
    """

    x_edges: FloatArray
    y_edges: FloatArray
    after: FloatArray
    before: FloatArray
    count: IntArray


@dataclass(frozen=True)
class SelfCalibrationOutcome:
    """What a self-calibration estimated, kept and held, and why.

    Attributes
    ----------
    choice : str or tuple of str
        ``[adjustment] self_calibration`` as given.
    family : {"brown", "ebner"}
    parameters : tuple of ParameterOutcome
        Every candidate parameter.
    correlations : tuple of (str, str, float)
        Pairs of estimated parameters correlated above 0.9 in magnitude
        (in the last adjustment that estimated both).
    estimate : CameraEstimate or None
        The delivered camera (None when every parameter was held).
    sigma0_without : float
        sigma0 of the same adjustment without self-calibration (NaN when not
        computed, i.e. for an explicit list).
    notes : tuple of str
        Warnings: the held parameters with their reasons, a fallback.
    cells : ResidualCells or None
        The image residuals averaged over the format, with and without the
        camera's correction.
    """

    choice: str | tuple[str, ...]
    family: str
    parameters: tuple[ParameterOutcome, ...]
    correlations: tuple[tuple[str, str, float], ...]
    estimate: CameraEstimate | None
    sigma0_without: float
    notes: tuple[str, ...]
    cells: ResidualCells | None = None

    @property
    def kept(self) -> tuple[str, ...]:
        """The parameters the delivered adjustment estimates."""
        return tuple(p.name for p in self.parameters if p.kept)


@dataclass(frozen=True)
class ShutterEstimate:
    """The rolling shutter's motion estimated with the block (geometry/camera_model.py, ``ShutterMotion``).

    Attributes
    ----------
    model : ShutterMotion
        The groups of photos (strips) sharing one motion, and how the rows
        are read.
    values : ndarray, shape (G, 3)
        The projection centre's displacement over the whole readout of a
        photo, metres along the adjustment frame's X, Y, Z.
    cofactor : ndarray, shape (3 G, 3 G)
        Their cofactor matrix (the block of ``N^-1``), group by group.
    sigma0 : float
        The adjustment's sigma0.
    """

    model: ShutterMotion
    values: FloatArray
    cofactor: FloatArray
    sigma0: float

    @property
    def group_names(self) -> tuple[str, ...]:
        """The groups' names."""
        return self.model.group_names

    @property
    def std(self) -> FloatArray:
        """Standard deviations (G, 3), metres."""
        out: FloatArray = self.sigma0 * np.sqrt(np.diag(self.cofactor)).reshape(-1, 3)
        return out


@dataclass(frozen=True)
class BundleResult:
    """Result of :func:`bundle_adjust`.

    Attributes
    ----------
    centres : ndarray, shape (M, 3)
        Adjusted projection centres in metres (local frame).
    rotations : ndarray, shape (M, 3, 3)
        Adjusted rotation matrices, image -> local frame (``l = R @ l_image``).
    points : ndarray, shape (P, 3)
        Adjusted point coordinates in metres, in ``observations.point_ids``
        order.
    sigma0 : float
        A posteriori standard deviation of unit weight,
        ``sqrt(v.T P v / redundancy)`` (NaN when the redundancy is 0).  It is
        close to 1 when the given standard deviations are right.
    redundancy : int
        Number of scalar observations minus number of unknowns.
    iterations : int
        Number of accepted Gauss-Newton / Levenberg-Marquardt steps.
    converged : bool
        False when ``max_iterations`` was reached first.
    residuals_mm : ndarray, shape (K, 2)
        Image residuals ``v = computed - observed`` in mm at the solution
        (observed + v = adjusted); with a camera model ``v = x̂ - x_obs``,
        ``x̂ + Δ(x̂) = x(S, R, X)``.
    control_residuals : ndarray, shape (P, 3)
        ``adjusted - given`` ground coordinates of the control in metres, NaN
        for components without control.
    point_std : ndarray, shape (P, 3)
        Standard deviations of the adjusted points in metres,
        ``sigma0 * sqrt(diag(N^-1))`` (NaN when not computed).
    centre_std : ndarray, shape (M, 3)
        Standard deviations of the adjusted centres in metres.
    rotation_std : ndarray, shape (M, 3)
        Standard deviations of the small rotations about the image x, y, z
        axes in radians.
    history : ndarray, shape (iterations + 1,)
        sigma0 at the initial values and after each accepted step.
    n_observations : int
        Number of scalar observations: ``2 K`` image coordinates plus the
        control, GNSS and IMU components used.
    gnss_residuals : ndarray, shape (M, 3)
        ``S - S_gnss``: adjusted minus observed projection centre in metres
        along the frame axes, NaN for components without a GNSS observation.
    imu_residuals : ndarray, shape (M, 3)
        ``log(R_imu.T @ R)`` in radians: the rotation vector about the
        photo's own image x, y, z axes that takes the observed attitude to the
        adjusted one (``R = R_imu @ exp([e]x)``; adjusted minus observed), NaN
        for photos without an IMU observation.
    gnss_residual_cofactor : ndarray, shape (M, 3, 3)
        Cofactor matrix of the GNSS residuals, ``Q_vv = P^-1 - Q_SS`` in m^2
        along the frame axes (``Q_SS`` the centre block of ``N^-1``); the
        redundancy numbers are ``Q_vv[i, i] / sigma_i**2``.  NaN in the rows
        and columns of components without GNSS, and everywhere when the
        precision is not computed.
    imu_residual_cofactor : ndarray, shape (M, 3, 3)
        Cofactor matrix of the IMU residuals, ``P^-1 - J Q_dd J.T`` in rad^2
        about the image axes (``J`` the inverse right Jacobian at the
        solution, ``Q_dd`` the rotation block of ``N^-1``); NaN as above.
    image_redundancy : ndarray, shape (K, 2)
        Redundancy numbers ``1 - (A Q Aᵀ P)ᵢᵢ`` of the image coordinates,
        exact (from the selected inverse of the normal matrix); NaN when the
        precision is not computed.
    camera : CameraEstimate or None
        The self-calibrated camera (None without self-calibration).
    motion : ShutterEstimate or None
        The rolling shutter's motion per group of photos (None without it).
    """

    centres: FloatArray
    rotations: FloatArray
    points: FloatArray
    sigma0: float
    redundancy: int
    iterations: int
    converged: bool
    residuals_mm: FloatArray
    control_residuals: FloatArray
    point_std: FloatArray
    centre_std: FloatArray
    rotation_std: FloatArray
    history: FloatArray
    n_observations: int
    gnss_residuals: FloatArray
    imu_residuals: FloatArray
    gnss_residual_cofactor: FloatArray
    imu_residual_cofactor: FloatArray
    image_redundancy: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    camera: CameraEstimate | None = None
    motion: ShutterEstimate | None = None


@dataclass(frozen=True)
class VarianceGroup:
    """One observation group's variance component (:mod:`strip_aerotri.bundle.variance`).

    Attributes
    ----------
    name : str
        ``"image, tie points"``, ``"image, control points"``, ``"control plan"``,
        ``"control height"``, ``"GNSS centres"`` or ``"IMU attitudes"``.
    unit : str
        Unit of the sigmas: ``"µm"`` (image), ``"m"`` (control, GNSS) or
        ``"deg"`` (IMU).
    n : int
        Scalar observations of the group in the final adjustment.
    sigma_apriori : float
        The group's median a-priori standard deviation, as given.
    sigma : float
        The estimated standard deviation, ``sigma_apriori`` times the
        product of the factors of all iterations (the a-priori value when not
        estimated).
    redundancy : float
        The group's share of the redundancy, the sum of its redundancy
        numbers in the final adjustment.
    factor : float
        ``sqrt(v'Pv / r)`` of the group in the final adjustment, at the
        weights it ran with: 1 once the estimate has settled.
    estimated : bool
        False when the group's redundancy is too small to estimate its
        variance (its sigma is kept as given).
    """

    name: str
    unit: str
    n: int
    sigma_apriori: float
    sigma: float
    redundancy: float
    factor: float
    estimated: bool


@dataclass(frozen=True)
class VarianceComponents:
    """The observation weights a bundle estimated from its own residuals.

    Attributes
    ----------
    groups : tuple of VarianceGroup
    iterations : int
        Adjustments run with re-estimated weights (after the first).
    converged : bool
        Every estimated group's factor within the tolerance at the end.
    sigma0_apriori : float
        sigma0 of the first adjustment, at the a-priori weights.
    applied : bool
        The estimated weights are those of the delivered adjustment (False:
        only estimated and reported, the adjustment ran at the a-priori
        weights).
    """

    groups: tuple[VarianceGroup, ...]
    iterations: int
    converged: bool
    sigma0_apriori: float
    applied: bool = True


@dataclass(frozen=True)
class FrameRefinement:
    """Result of :func:`refine_frame` (all arrays in the adjustment frame).

    Attributes
    ----------
    centres : ndarray, shape (M, 3)
        Adjusted projection centres, metres.
    rotations : ndarray, shape (M, 3, 3)
        Adjusted rotations, image -> frame.
    points : ndarray, shape (P, 3)
        Adjusted points, metres; NaN for points left out (no initial value,
        excluded, or dropped after a rejection left them on one photo).
    point_used : ndarray of bool, shape (P,)
    observation_used : ndarray of bool, shape (K,)
        Image observations that entered the final adjustment.
    control_used : ndarray of bool, shape (P, 3)
        Control components that entered the final adjustment.
    observation_rejected : ndarray of bool, shape (K,)
        Image observations rejected by the tests.
    control_rejected : ndarray of bool, shape (P, 3)
        Control components rejected by the tests.
    image_residuals_mm : ndarray, shape (K, 2)
        ``v = computed - observed`` at the solution for every observation of
        a used point (rejected ones included), NaN otherwise.
    image_w : ndarray, shape (K, 2)
        Test values of the image coordinates (NaN where not tested).
    image_redundancy : ndarray, shape (K, 2)
        Redundancy numbers used by the test: exact with the precision,
        approximate without (see Notes of :func:`refine_frame`).
    control_residuals : ndarray, shape (P, 3)
        ``adjusted - given`` in metres where control was given (rejected
        components included), NaN elsewhere.
    control_w : ndarray, shape (P, 3)
        Test values of the control components.
    point_std, centre_std : ndarray, shapes (P, 3), (M, 3)
        Standard deviations in metres along the frame axes.
    rotation_std : ndarray, shape (M, 3)
        Standard deviations of the small rotations about the image axes, rad.
    sigma0 : float
    redundancy : int
    iterations : int
        Accepted bundle steps over all rounds.
    rounds : int
        Adjustments solved (1 + rounds of rejections).
    converged : bool
        The final adjustment converged.
    rejections : tuple of Rejection
    bundle : BundleResult
        The final adjustment (on the used points and observations only).
    gnss_used, imu_used : ndarray of bool, shape (M,)
        Photos whose GNSS centre / IMU attitude entered the final adjustment.
    gnss_rejected, imu_rejected : ndarray of bool, shape (M,)
        Photos whose GNSS centre / IMU attitude was rejected by the tests
        (in this call or, through ``gnss_used`` / ``imu_used``, before).
    self_calibration : SelfCalibrationOutcome or None
        The camera's parameters estimated, kept and held (None without
        self-calibration).
    control_tested : bool
        False when the control failed at many points alike and was kept
        untested (:mod:`strip_aerotri.ground.systematic`).
    variance_components : VarianceComponents or None
        The groups' weights estimated from the residuals (None unless asked
        for, :mod:`strip_aerotri.bundle.variance`).
    """

    centres: FloatArray
    rotations: FloatArray
    points: FloatArray
    point_used: BoolArray
    observation_used: BoolArray
    control_used: BoolArray
    observation_rejected: BoolArray
    control_rejected: BoolArray
    image_residuals_mm: FloatArray
    image_w: FloatArray
    image_redundancy: FloatArray
    control_residuals: FloatArray
    control_w: FloatArray
    point_std: FloatArray
    centre_std: FloatArray
    rotation_std: FloatArray
    sigma0: float
    redundancy: int
    iterations: int
    rounds: int
    converged: bool
    rejections: tuple[Rejection, ...]
    bundle: BundleResult
    gnss_used: BoolArray = field(default_factory=lambda: np.zeros(0, bool))
    gnss_rejected: BoolArray = field(default_factory=lambda: np.zeros(0, bool))
    imu_used: BoolArray = field(default_factory=lambda: np.zeros(0, bool))
    imu_rejected: BoolArray = field(default_factory=lambda: np.zeros(0, bool))
    self_calibration: SelfCalibrationOutcome | None = None
    control_tested: bool = True
    variance_components: VarianceComponents | None = None


def _rms(values: FloatArray) -> FloatArray:
    """Root mean square over the rows (NaN for no rows)."""
    if values.shape[0] == 0:
        return np.full(values.shape[1:], np.nan)
    rms: FloatArray = np.sqrt(np.mean(values**2, axis=0))
    return rms


def _max_abs(values: FloatArray) -> FloatArray:
    """Largest absolute value over the rows (NaN for no rows)."""
    if values.shape[0] == 0:
        return np.full(values.shape[1:], np.nan)
    largest: FloatArray = np.max(np.abs(values), axis=0)
    return largest


class _PhotoTests:
    """Counts and test verdicts shared by :class:`GnssResiduals` and :class:`ImuResiduals`.

    The subclasses are frozen dataclasses with the fields ``photo_ids``,
    ``residuals`` (G, 3), ``w`` (G, 3), ``critical`` and ``rejected`` (G,).
    """

    photo_ids: tuple[str, ...]
    residuals: FloatArray
    w: FloatArray
    critical: float
    rejected: BoolArray

    def __post_init__(self) -> None:  # run by the subclasses' dataclass __init__
        g = len(self.photo_ids)
        rejected = np.zeros(g, bool) if self.rejected is None else np.array(self.rejected, bool)
        if rejected.shape != (g,):
            raise ValueError(f"Expected `rejected` to have shape {(g,)}, got {rejected.shape}")
        object.__setattr__(self, "rejected", rejected)

    @property
    def used(self) -> BoolArray:
        """(G,) the observation is in the final adjustment (``~rejected``)."""
        return ~self.rejected

    @property
    def n_used(self) -> int:
        """Number of observations in the final adjustment (G minus the rejected)."""
        return int(np.count_nonzero(~self.rejected))

    @property
    def n_rejected(self) -> int:
        """Number of observations rejected by the data snooping."""
        return int(np.count_nonzero(self.rejected))

    @property
    def failed(self) -> BoolArray:
        """(G,) some component's ``|w|`` exceeds ``critical`` (NaN w never fails)."""
        failed: BoolArray = np.any(np.abs(self.w) > self.critical, axis=1)
        return failed

    @property
    def _used_residuals(self) -> FloatArray:
        return self.residuals[~self.rejected]


@dataclass(frozen=True)
class GnssResiduals(_PhotoTests):
    """What the GNSS projection centres did in the bundle refinement.

    Residuals are **observed minus adjusted** projection centres in ground
    metres along local **east, north, up at the adjusted centre** (true
    north; the site X, Y, H axes for ``crs = "local"``).

    Rejected observations (data snooping stages ``"gnss"`` / ``"imu"`` of
    :func:`refine_bundle`) stay listed with ``rejected`` True: their
    residuals are still observed minus adjusted (how far the final solution
    is from them), their ``redundancy`` and ``w`` are NaN (an observation
    outside the adjustment has no redundancy number; its test value at the
    time of rejection is in the :class:`~strip_aerotri.blunders.Rejection`
    record).  The summary statistics (``rms``, ``max_*``) are over the used
    observations only.

    Attributes
    ----------
    photo_ids : tuple of str, length G
        Photos of the strip with a GNSS centre (used or rejected), in strip
        order.
    photo_index : ndarray of int, shape (G,)
        Their positions in the strip.
    n_given : int
        Rows of the :class:`GnssCentres` given.
    unmatched : tuple of str
        Given photo ids that are not in the strip (ignored with a warning).
    sigma_xy, sigma_z : ndarray, shape (G,)
        A priori standard deviations, metres (horizontal, vertical).
    residuals : ndarray, shape (G, 3)
        Observed minus adjusted centre, m, along E, N, U.
    redundancy : ndarray, shape (G, 3)
        Redundancy numbers of the E, N, U components (``diag(Aᵀ Q_vv P A)``,
        ``A`` the rotation east-north-up -> adjustment frame); NaN when the
        precision was not computed and for rejected centres.
    w : ndarray, shape (G, 3)
        Baarda's test of a blunder along E, N, U,
        ``w = dᵀ P v / sqrt(dᵀ P Q_vv P d)`` with ``d`` the axis in the frame,
        at the a priori sigmas (no variance factor); sign of the residual.
        Equals ``v / (sigma sqrt(r))`` when ``d`` is a frame axis.  NaN when
        the precision was not computed, the component has no redundancy, or
        the centre was rejected.
    critical : float
        Critical ``|w|`` of stage ``"gnss"``: Bonferroni over the
        ``3 n_used`` components at the refinement's ``alpha``, or the value
        set in ``BlunderOptions.critical_values``.
    rejected : ndarray of bool, shape (G,)
        The centre was rejected (all three components left out); default
        none.
    """

    photo_ids: tuple[str, ...]
    photo_index: IntArray
    n_given: int
    unmatched: tuple[str, ...]
    sigma_xy: FloatArray
    sigma_z: FloatArray
    residuals: FloatArray
    redundancy: FloatArray
    w: FloatArray
    critical: float
    rejected: BoolArray = None  # type: ignore[assignment]

    @property
    def plan(self) -> FloatArray:
        """(G,) horizontal length of the residuals, m (rejected centres included)."""
        return np.hypot(self.residuals[:, 0], self.residuals[:, 1])

    @property
    def rms(self) -> FloatArray:
        """(3,) RMS of the E, N, U residuals of the used centres, m (NaN without any)."""
        return _rms(self._used_residuals)

    @property
    def rms_plan(self) -> float:
        """sqrt(RMS_E**2 + RMS_N**2) of the used centres, m."""
        return float(np.hypot(self.rms[0], self.rms[1]))

    @property
    def max_plan(self) -> float:
        """Largest horizontal residual of the used centres, m."""
        used = self._used_residuals
        return float(np.max(np.hypot(used[:, 0], used[:, 1]))) if used.size else float("nan")

    @property
    def max_up(self) -> float:
        """Largest |U| residual of the used centres, m."""
        return float(_max_abs(self._used_residuals[:, 2]))


@dataclass(frozen=True)
class ImuResiduals(_PhotoTests):
    """What the IMU attitudes did in the bundle refinement.

    Residuals are **observed minus adjusted** attitudes as the rotation
    vector ``v = log(R_adj.T @ R_imu)`` about the adjusted photo's own image
    axes x (along the flight), y (to its left), z (up), so that
    ``R_imu = R_adj @ exp([v]x)``; the quantity the adjustment weights and
    tests.  For a near-vertical photo ``v`` is close to the differences of
    omega, phi, kappa, which are given as well.

    Rejected observations (data snooping stages ``"gnss"`` / ``"imu"`` of
    :func:`refine_bundle`) stay listed with ``rejected`` True: their
    residuals are still observed minus adjusted (how far the final solution
    is from them), their ``redundancy`` and ``w`` are NaN (an observation
    outside the adjustment has no redundancy number; its test value at the
    time of rejection is in the :class:`~strip_aerotri.blunders.Rejection`
    record).  The summary statistics (``rms``, ``max_*``) are over the used
    observations only.

    Attributes
    ----------
    photo_ids : tuple of str, length G
        Photos of the strip with an IMU attitude (used or rejected), in strip
        order.
    photo_index : ndarray of int, shape (G,)
    n_given : int
        Rows of the :class:`ImuAttitudes` given.
    unmatched : tuple of str
        Given photo ids that are not in the strip (ignored with a warning).
    sigma : ndarray, shape (G,)
        A priori standard deviation of each rotation component, radians.
    residuals : ndarray, shape (G, 3)
        ``v`` in radians, components about the image x, y, z axes.
    opk_differences : ndarray, shape (G, 3)
        Observed minus adjusted omega, phi, kappa (image -> local
        east-north-up, the ``photos.csv`` convention), radians, wrapped to
        [-pi, pi).
    redundancy : ndarray, shape (G, 3)
        Redundancy numbers of the components of ``v`` (NaN when the precision
        was not computed and for rejected attitudes).
    w : ndarray, shape (G, 3)
        Baarda's ``w = v / (sigma sqrt(r))`` at the a priori sigma (NaN as
        ``redundancy``).
    critical : float
        Critical ``|w|`` of stage ``"imu"``: Bonferroni over the ``3 n_used``
        components, or the value set in ``BlunderOptions.critical_values``.
    rejected : ndarray of bool, shape (G,)
        The attitude was rejected (all three angles left out); default none.
    """

    photo_ids: tuple[str, ...]
    photo_index: IntArray
    n_given: int
    unmatched: tuple[str, ...]
    sigma: FloatArray
    residuals: FloatArray
    opk_differences: FloatArray
    redundancy: FloatArray
    w: FloatArray
    critical: float
    rejected: BoolArray = None  # type: ignore[assignment]

    @property
    def residuals_deg(self) -> FloatArray:
        """(G, 3) residuals in degrees."""
        return np.degrees(self.residuals)

    @property
    def opk_differences_deg(self) -> FloatArray:
        """(G, 3) omega, phi, kappa differences in degrees."""
        return np.degrees(self.opk_differences)

    @property
    def rms(self) -> FloatArray:
        """(3,) RMS of the residual components of the used attitudes, radians."""
        return _rms(self._used_residuals)

    @property
    def max_abs(self) -> FloatArray:
        """(3,) largest |component| of the residuals of the used attitudes, radians."""
        return _max_abs(self._used_residuals)


@dataclass(frozen=True)
class RefinedResult:
    """A strip-method result refined by bundle adjustment.

    Layout as :class:`~strip_aerotri.results.StripResult`: points and photos
    in the control CRS, in ``point_ids`` / ``photo_ids`` order.

    Attributes
    ----------
    photo_ids, point_ids : tuple of str
    points : ndarray, shape (P, 3)
        X, Y, H in the control CRS (NaN for points not adjusted).
    photo_centres : ndarray, shape (M, 3)
        Projection centres X, Y, H in the control CRS.
    photo_opk : ndarray, shape (M, 3)
        omega, phi, kappa in radians of ``R = Rx Ry Rz``, image -> local
        east-north-up at the centre (image -> X, Y, H axes for "local").
    frame : LocalTangentFrame or None
        The adjustment frame (None: the site system of ``crs = "local"``).
    frame_description : str
    points_frame, photo_centres_frame : ndarray, shapes (P, 3), (M, 3)
        The same in the frame, metres.
    photo_rotations_frame : ndarray, shape (M, 3, 3)
        Image -> frame.
    sigma0 : float
        A posteriori sigma of unit weight of the final adjustment.
    redundancy : int
    iterations : int
        Accepted bundle steps over all rounds and passes.
    converged : bool
    image_residuals_um : ndarray, shape (K, 2)
        Image residuals ``computed - observed`` in µm, in the order of
        ``result.strip.observations`` (NaN for observations of points not
        adjusted).
    image_used : ndarray of bool, shape (K,)
    control_index : ndarray of int, shape (C,)
        Rows of the control (``result.control``) whose point was adjusted.
    control_residuals : ndarray, shape (C, 3)
        Given minus adjusted along E, N, H in metres (grid E, N for projected
        CRSs and "local"), NaN for components not given or not used; check
        points compared in full.
    is_check : ndarray of bool, shape (C,)
    used_xy, used_h : ndarray of bool, shape (C,)
        Control components in the final adjustment (False for check points
        and rejected components).
    control_statistics, check_statistics : AccuracyStatistics
        At the control used and at the check points.
    point_std, centre_std : ndarray, shapes (P, 3), (M, 3)
        Standard deviations in metres along the frame axes (X along the
        strip, Y to its left, Z up; X, Y, H for "local"); NaN when not
        computed.
    rejections : tuple of Rejection
    warnings : tuple of str
    timings : dict
        Seconds: ``frame`` (conversions), ``bundle`` (adjustments, precision
        and tests), ``total``.
    n_observations : int
        Scalar observations of the final adjustment.
    gnss : GnssResiduals or None
        Counts, residuals and tests of the GNSS centres (None without them).
    self_calibration : SelfCalibrationOutcome or None
        The self-calibrated camera: every parameter's estimate, standard
        deviation, t value, whether it was kept and why not.
    imu : ImuResiduals or None
        Counts, residuals and tests of the IMU attitudes (None without them).
    variance_components : VarianceComponents or None
        The observation groups' weights estimated from the residuals (None
        unless asked for).
    """

    photo_ids: tuple[str, ...]
    point_ids: tuple[str, ...]
    points: FloatArray
    photo_centres: FloatArray
    photo_opk: FloatArray
    frame: LocalTangentFrame | None
    frame_description: str
    points_frame: FloatArray
    photo_centres_frame: FloatArray
    photo_rotations_frame: FloatArray
    sigma0: float
    redundancy: int
    iterations: int
    converged: bool
    image_residuals_um: FloatArray
    image_used: BoolArray
    control_index: IntArray
    control_residuals: FloatArray
    is_check: BoolArray
    used_xy: BoolArray
    used_h: BoolArray
    control_statistics: AccuracyStatistics
    check_statistics: AccuracyStatistics
    point_std: FloatArray
    centre_std: FloatArray
    rejections: tuple[Rejection, ...]
    warnings: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)
    n_observations: int = 0
    gnss: GnssResiduals | None = None
    imu: ImuResiduals | None = None
    self_calibration: SelfCalibrationOutcome | None = None
    variance_components: VarianceComponents | None = None

    @property
    def photo_opk_degrees(self) -> FloatArray:
        """(M, 3) omega, phi, kappa in degrees (image -> local east-north-up)."""
        return np.degrees(self.photo_opk)
