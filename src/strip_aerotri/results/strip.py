"""Results of strip formation: the relative orientation and the strip model."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..observations import ImageObservations
from ..options import DEFAULT_PHOTO_STEP, RelativeOrientationMethod, StripOptions
from .common import Rejection

#: The unit of residuals measured in a model before the strip reaches the
#: ground: the model's own base length.
BASE_UNITS = "base units"

__all__ = ["RelativeOrientation", "StripModel"]


@dataclass(frozen=True)
class RelativeOrientation:
    """Relative orientation of a chain of pairs.

    Pair m is formed by photos m and m + 1 of the chain.  Arrays with a
    leading ``n_pairs`` axis hold one row per pair; arrays with a leading
    ``n`` axis hold one row per point measured on both photos of a pair (all
    pairs concatenated, sorted by pair).

    Attributes
    ----------
    method : RelativeOrientationMethod
    base : ndarray, shape (n_pairs, 3)
        Base vector in the strip system, normalised so that its component
        along the left photo's image x axis is 1 (J(5)'s ``b_x = 1`` for
        near-vertical photos of a strip along x; valid for any heading).
    rotation_left, rotation_right : ndarray, shape (n_pairs, 3, 3)
        Image -> strip rotations of the two photos; ``rotation_left[m + 1]``
        equals ``rotation_right[m]``.
    relative_rotation : ndarray, shape (n_pairs, 3, 3)
        ``rotation_left.T @ rotation_right``: right image -> left image.
    elements : ndarray, shape (n_pairs, 5)
        The five elements of the formulation: ``(b_y, b_z, a, b, c)`` with
        the base components along the left photo's image y and z axes and the
        Schut parameters of the relative rotation for ``"dependent"``;
        ``(alpha1, chi1, alpha2, omega2, chi2)`` in radians, the base-system
        angles of B(125)-(135), for ``"base"``.
    iterations : ndarray of int, shape (n_pairs,)
        Gauss-Newton iterations until the pair's corrections fell below the
        tolerance.
    n_points : ndarray of int, shape (n_pairs,)
    sigma0_um : ndarray, shape (n_pairs,)
        A posteriori standard deviation of one image coordinate, from the
        residual y-parallaxes, in µm at image scale (a y-parallax combines two
        image coordinates, hence the factor 1/√2 against ``rms_parallax_um``).
    rms_parallax_um, max_parallax_um : ndarray, shape (n_pairs,)
        RMS and largest absolute residual y-parallax at image scale, µm.
    pair : ndarray of int, shape (n,)
        Pair index of each point row.
    parallax_um : ndarray, shape (n,)
        Residual y-parallax of each point at the left photo's image scale, µm.
    history : ndarray
        Largest absolute y-parallax (µm) among the pairs still iterating, at
        each evaluation (the first ones on a subsample of large pairs); shows
        the convergence rate.
    redundancy_numbers : ndarray, shape (n,)
        Diagonal of ``I − A (AᵀPA)⁻¹ AᵀP`` for each y-parallax (0..1; they
        sum to n − 5 per pair): the share of a blunder that shows in its own
        residual.
    w_statistic : ndarray, shape (n,)
        Baarda's w-test of each y-parallax with the a priori sigmas:
        ``q / sqrt((sigma_left² + sigma_right²) · r)`` at image scale (NaN
        where r ≈ 0).
    """

    method: RelativeOrientationMethod
    base: FloatArray
    rotation_left: FloatArray
    rotation_right: FloatArray
    relative_rotation: FloatArray
    elements: FloatArray
    iterations: IntArray
    n_points: IntArray
    sigma0_um: FloatArray
    rms_parallax_um: FloatArray
    max_parallax_um: FloatArray
    pair: IntArray
    parallax_um: FloatArray
    history: FloatArray
    redundancy_numbers: FloatArray | None = None
    w_statistic: FloatArray | None = None

    @property
    def n_pairs(self) -> int:
        n: int = self.base.shape[0]
        return n


@dataclass(frozen=True)
class StripModel:
    """One strip model in the strip system.

    Photo arrays follow ``photo_index`` (the photos that form the models, in
    strip order); model m is formed by photos m and m + 1 of it.  Arrays with
    a leading ``n`` axis hold one row per determination of a point in a model
    (the pair-points of the relative orientation, sorted by model).

    Attributes
    ----------
    observations : ImageObservations
    options : StripOptions
    photo_index : ndarray of int, shape (n_photos,)
        Index into ``observations.photo_ids``.
    centres : ndarray, shape (n_photos, 3)
        Projection centres, strip system.
    rotations : ndarray, shape (n_photos, 3, 3)
        Image -> strip rotations.
    relative : RelativeOrientation
    scale : ndarray, shape (n_models,)
        λ of each model: its base is ``scale * relative.base``.
    scale_ratio : ndarray, shape (n_models,)
        λ_m / λ_(m-1) from the tie points (1 for the first model).
    points : ndarray, shape (n_points, 3)
        Mean of all determinations of each point of ``observations.point_ids``
        (NaN for points in no model: seen on one photo only).
    n_determinations : ndarray of int, shape (n_points,)
        Number of models that determined each point.
    model, model_point : ndarray of int, shape (n,)
        Model and point index of each determination.
    model_points : ndarray, shape (n, 3)
        Each determination in the strip system.
    model_parallax : ndarray, shape (n,)
        Remaining y-parallax of the rays at the model point, strip units.
    tie_model, tie_point : ndarray of int, shape (t,)
        For each tie point of each model m >= 1: the model and the point.
    tie_difference : ndarray, shape (t, 3)
        Determination in model m minus determination in model m - 1, strip
        units (J §3, R4 §2.2: the accuracy criterion of strip formation).
    tie_count : ndarray of int, shape (n_models,)
        Tie points used for the scale of each model (0 for the first).
    tie_rms : ndarray, shape (n_models, 3)
        RMS of the tie-point differences per model and coordinate (NaN for the
        first model).
    model_labels : tuple of str
        "pair A-B" for each model.
    rejections : tuple of Rejection
        Observations that failed the blunder tests of the relative
        orientation (y-parallaxes) and of the scale transfer (tie-point
        differences), in the order found.
    rejected_points : tuple of str
        Points all of whose determinations failed the tie test (consecutive
        models disagree): left out of the strip model (NaN in ``points``).
    rejected_determinations : ndarray of bool, shape (n,), optional
        The determinations (rows of ``model_points``) the tie test left
        out: both models of every failed tie.  None: the rows of
        ``rejected_points``.
    model_photos : ndarray of int, optional
        See :attr:`model_photo_positions`.
    model_rows : ndarray of int, shape (n, 2), optional
        The observations (rows of ``observations``) on the left and the
        right photo behind each determination.
    breaks : ndarray of int
        Models that share no tie point with the one before
        (``StripOptions.allow_breaks``): their scale is not transferred.
    photo_step : int
        The step k of the photos that formed the models (1: every photo;
        the step ``photo_step = "auto"`` chose, :mod:`strip_aerotri.strip.densify`).
    """

    observations: ImageObservations
    options: StripOptions
    photo_index: IntArray
    centres: FloatArray
    rotations: FloatArray
    relative: RelativeOrientation
    scale: FloatArray
    scale_ratio: FloatArray
    points: FloatArray
    n_determinations: IntArray
    model: IntArray
    model_point: IntArray
    model_points: FloatArray
    model_parallax: FloatArray
    tie_model: IntArray
    tie_point: IntArray
    tie_difference: FloatArray
    tie_count: IntArray
    tie_rms: FloatArray
    model_labels: tuple[str, ...] = field(default=())
    rejections: tuple[Rejection, ...] = field(default=())
    rejected_points: tuple[str, ...] = field(default=())
    rejected_determinations: BoolArray | None = None
    model_photos: IntArray | None = None
    model_rows: IntArray | None = None
    breaks: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    photo_step: int = DEFAULT_PHOTO_STEP

    @property
    def break_warnings(self) -> tuple[str, ...]:
        """One warning per model that shares no tie point with the one before:
        its scale comes from the control alone."""
        labels = self.model_labels or tuple(f"model {m + 1}" for m in range(self.n_models))
        return tuple(
            f"{labels[m]} shares no tie point with {labels[m - 1]} (0 tie points): its scale "
            "is not carried over from its neighbour and comes from the control alone, so it "
            "is only as good as the control on it; measure points on the three photos of the "
            "two pairs to join them"
            for m in np.asarray(self.breaks, dtype=np.intp).tolist()
            if 0 < m < len(labels)
        )

    def with_rejections_in_metres(self, metres_per_unit: float) -> StripModel:
        """The strip with its tie-point rejections told in ground metres: a
        residual in the units of its model's base (the strip system's units
        times the model's scale) times ``metres_per_unit``, the metres per
        unit of the strip system once the strip is on the ground."""
        if not np.isfinite(metres_per_unit) or metres_per_unit <= 0:
            return self
        model_of = {label: k for k, label in enumerate(self.model_labels)}
        out = []
        for r in self.rejections:
            k = model_of.get(f"pair {r.photos[1]}-{r.photos[2]}") if len(r.photos) == 3 else None
            if r.unit == BASE_UNITS and k is not None:
                metres = r.residual * float(self.scale[k]) * metres_per_unit
                r = replace(r, residual=metres, unit="m")
            out.append(r)
        return replace(self, rejections=tuple(out))

    @property
    def kept_determinations(self) -> BoolArray:
        """(n,) the determinations (rows of ``model_points``) the tie test
        kept: all but ``rejected_determinations``, or, without them, all but
        those of ``rejected_points``."""
        if self.rejected_determinations is not None:
            kept: BoolArray = ~self.rejected_determinations
            return kept
        names = np.asarray(self.observations.point_ids)[self.model_point]
        return ~np.isin(names, list(self.rejected_points))

    def lost_to_blunder_tests(self) -> dict[str, str]:
        """Why a point may have no ground position, for the points whose
        observations failed a blunder test of the strip's formation (point id
        -> the cause, naming the stage); the others were seen on fewer than
        two photos of a model."""
        why = {
            r.point: f"its observations failed the blunder tests, see the {r.stage} rejections"
            for r in self.rejections
            if r.applied and r.point
        }
        failed = (
            "every determination of it failed the tie-point test, see the tie_points rejections"
        )
        why.update((p, failed) for p in self.rejected_points)
        return why

    @property
    def model_photo_positions(self) -> IntArray:
        """Positions in the photo arrays of the photos that form the models:
        model m is formed by photos ``model_photo_positions[m]`` and
        ``[m + 1]`` (all photos unless the strip was completed from every
        k-th photo, :func:`strip_aerotri.strip.densify.complete_strip`)."""
        if self.model_photos is None:
            return np.arange(self.photo_index.shape[0], dtype=np.intp)
        return self.model_photos

    @property
    def photo_ids(self) -> tuple[str, ...]:
        return tuple(self.observations.photo_ids[i] for i in self.photo_index)

    @property
    def n_models(self) -> int:
        n: int = self.scale.shape[0]
        return n

    @property
    def triangulated(self) -> np.ndarray:
        """Boolean mask (n_points,) of points determined in at least one model."""
        return self.n_determinations > 0
