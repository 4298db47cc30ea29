"""What :func:`~strip_aerotri.bundle.snooping.refine_frame` adjusts and tests:
its validated inputs (:class:`_Inputs`), the observations in use and those
rejected (:class:`_Sets`, changed by each round's rejections) and the
observations of the points in use (:func:`_compact`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import GeometryError
from ..geometry.camera_model import ShutterMotion
from ..observations import ImageObservations
from ..options import BlunderOptions
from ._given import observed_with_sigma
from .photo_tests import _photo_flags

__all__ = ["CONTROL_STAGE", "GNSS_STAGE", "IMAGE_STAGE", "IMU_STAGE"]

#: Stage name of the image-coordinate tests in :class:`Rejection` records.
IMAGE_STAGE = "bundle"
#: Stage name of the control tests (shared with the ground stage's options).
CONTROL_STAGE = "control"
#: Stage names of the GNSS centre and IMU attitude tests.
GNSS_STAGE = "gnss"
IMU_STAGE = "imu"


class _Inputs(NamedTuple):
    """The validated inputs of :func:`refine_frame` (frame units: m, rad)."""

    obs: ImageObservations
    n_photos: int
    n_points: int
    centres0: FloatArray
    rotations0: FloatArray
    points0: FloatArray
    sigma_img: FloatArray  # (K,) mm
    c_xyz: FloatArray  # (P, 3), NaN where not given
    c_sig: FloatArray  # (P, 3), inf where not given
    c_given: BoolArray  # (P, 3)
    g_xyz: FloatArray | None
    g_sig: FloatArray
    g_given: BoolArray
    g_axes: FloatArray
    i_rot: FloatArray | None
    i_sig: FloatArray
    i_given: BoolArray
    motion: ShutterMotion | None = None  # a rolling shutter's groups, if estimated


def _inputs(
    obs: ImageObservations,
    centres0: ArrayLike,
    rotations0: ArrayLike,
    points0: ArrayLike,
    control_xyz: ArrayLike | None,
    control_sigma: ArrayLike | None,
    gnss_centres: ArrayLike | None,
    gnss_sigma: ArrayLike | None,
    imu_rotations: ArrayLike | None,
    imu_sigma: ArrayLike | None,
    gnss_axes: ArrayLike | None,
) -> _Inputs:
    """Shapes checked, control, GNSS and IMU with their sigmas; ValueError naming
    the argument otherwise."""
    k_all, m, p = obs.photo.shape[0], len(obs.photo_ids), len(obs.point_ids)
    centres = np.array(centres0, dtype=np.float64)
    rotations = np.array(rotations0, dtype=np.float64)
    points = np.array(points0, dtype=np.float64)
    if points.shape != (p, 3):
        raise ValueError(f"Expected `points0` to have shape {(p, 3)}, got {points.shape}")
    if centres.shape != (m, 3) or rotations.shape != (m, 3, 3):
        raise ValueError(
            f"Expected `centres0` (M, 3) and `rotations0` (M, 3, 3) with M = {m}, got "
            f"{centres.shape}, {rotations.shape}"
        )
    if control_xyz is None:
        c_xyz, c_sig = np.full((p, 3), np.nan), np.full((p, 3), np.inf)
    else:
        c_xyz, c_sig = observed_with_sigma(
            control_xyz, control_sigma, (p, 3), "control_xyz", "control_sigma"
        )
    c_given = np.isfinite(c_xyz) & np.isfinite(c_sig)
    if np.any(c_sig[c_given] <= 0):
        raise ValueError("Expected positive standard deviations for `control_xyz`")
    g_xyz = i_rot = None
    g_sig = i_sig = np.full((m, 3), np.inf)
    g_given = np.zeros(m, bool)
    i_given = np.zeros(m, bool)
    if gnss_centres is not None:
        g_xyz, g_sig = observed_with_sigma(
            gnss_centres, gnss_sigma, (m, 3), "gnss_centres", "gnss_sigma"
        )
        g_given = np.any(np.isfinite(g_xyz) & np.isfinite(g_sig), axis=1)
    if imu_rotations is not None:
        i_rot, i_sig = observed_with_sigma(
            imu_rotations, imu_sigma, (m, 3, 3), "imu_rotations", "imu_sigma"
        )
        i_given = np.all(np.isfinite(i_rot), axis=(1, 2)) & np.any(np.isfinite(i_sig), axis=1)
    if gnss_axes is None:
        g_axes = np.broadcast_to(np.eye(3), (m, 3, 3))
    else:
        g_axes = np.asarray(gnss_axes, dtype=np.float64)
        if g_axes.shape != (m, 3, 3):
            raise ValueError(f"Expected `gnss_axes` to have shape {(m, 3, 3)}, got {g_axes.shape}")
    return _Inputs(
        obs,
        m,
        p,
        centres,
        rotations,
        points,
        np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), (k_all,)),
        c_xyz,
        c_sig,
        c_given,
        g_xyz,
        g_sig,
        g_given,
        g_axes,
        i_rot,
        i_sig,
        i_given,
    )


@dataclass
class _Sets:
    """What is in use and what was rejected; changed by each round's rejections."""

    keep: BoolArray  # (K,) image observations in use
    rejected_before: BoolArray  # (K,) rejected by an earlier call's tests
    obs_rejected: BoolArray  # (K,)
    ctrl_on: BoolArray  # (P, 3)
    ctrl_rejected: BoolArray  # (P, 3)
    g_on: BoolArray  # (M,)
    g_rejected: BoolArray
    i_on: BoolArray
    i_rejected: BoolArray
    n_img_start: int
    n_ctrl_start: int
    #: False once the control is kept for failing alike: no more control tests
    control_tested: bool = True

    @classmethod
    def start(
        cls,
        inp: _Inputs,
        blunders: BlunderOptions,
        observation_used: ArrayLike | None,
        control_used: ArrayLike | None,
        gnss_used: ArrayLike | None,
        imu_used: ArrayLike | None,
    ) -> _Sets:
        obs, m, p = inp.obs, inp.n_photos, inp.n_points
        k_all = obs.photo.shape[0]
        keep = (
            np.ones(k_all, bool) if observation_used is None else np.array(observation_used, bool)
        )
        if keep.shape != (k_all,):
            raise ValueError(f"Expected `observation_used` to have shape {(k_all,)}")
        ctrl_on = (
            inp.c_given.copy()
            if control_used is None
            else np.array(control_used, bool) & inp.c_given
        )
        excluded_points, excluded_obs = blunders.excluded(obs)
        rejected_before = ~keep & ~excluded_obs
        keep &= ~excluded_obs
        ctrl_on[excluded_points] = False
        g_on = inp.g_given & _photo_flags(gnss_used, m, "gnss_used")
        i_on = inp.i_given & _photo_flags(imu_used, m, "imu_used")
        return cls(
            keep=keep,
            rejected_before=rejected_before,
            obs_rejected=np.zeros(k_all, bool),
            ctrl_on=ctrl_on,
            ctrl_rejected=np.zeros((p, 3), bool),
            g_on=g_on,
            g_rejected=inp.g_given & ~g_on,
            i_on=i_on,
            i_rejected=inp.i_given & ~i_on,
            n_img_start=int(keep.sum()),
            n_ctrl_start=int(ctrl_on.sum()),
        )

    def copy(self) -> _Sets:
        """A copy that later rejections leave alone."""
        arrays = {
            f.name: getattr(self, f.name).copy()
            for f in dataclasses.fields(self)
            if isinstance(getattr(self, f.name), np.ndarray)
        }
        return dataclasses.replace(self, **arrays)

    def with_images_of(self, other: _Sets) -> _Sets:
        """A copy with ``other``'s image observations in use and rejected (and
        this one's control, GNSS and IMU)."""
        return dataclasses.replace(
            self.copy(), keep=other.keep.copy(), obs_rejected=other.obs_rejected.copy()
        )

    def with_tests_of(self, other: _Sets) -> _Sets:
        """A copy with ``other``'s image observations and control in use and
        rejected (and this one's GNSS and IMU)."""
        return dataclasses.replace(
            self.with_images_of(other),
            ctrl_on=other.ctrl_on.copy(),
            ctrl_rejected=other.ctrl_rejected.copy(),
        )

    def used_points(self, inp: _Inputs) -> BoolArray:
        """Points with a start value and enough rays.

        A point that lost a ray to a rejection keeps a check on the rest only
        with three rays left: with two, the ray rejected may have been the
        good one (a wrong ray pulls the point towards itself, and a good
        neighbour can show the larger w) and nothing would show it."""
        obs, p = inp.obs, inp.n_points
        rays = np.bincount(obs.point[self.keep], minlength=p)
        full = np.all(self.ctrl_on, axis=1)
        lost = np.bincount(obs.point[self.obs_rejected | self.rejected_before], minlength=p) > 0
        need = np.where(lost, 3, 2)
        has_start = np.all(np.isfinite(inp.points0), axis=1)
        used: BoolArray = has_start & ((rays >= need) | ((rays >= need - 1) & full))
        return used

    def reject(self, picks: list[tuple[str, int]]) -> None:
        for kind, k in picks:
            if kind == "image":
                self.keep[k] = False
                self.obs_rejected[k] = True
            elif kind == "plan":
                self.ctrl_on[k, :2] = False
                self.ctrl_rejected[k, :2] = True
            elif kind == "height":
                self.ctrl_on[k, 2] = False
                self.ctrl_rejected[k, 2] = True
            elif kind == "gnss":
                self.g_on[k] = False
                self.g_rejected[k] = True
            else:
                self.i_on[k] = False
                self.i_rejected[k] = True

    def control_over_limit(self, blunders: BlunderOptions) -> bool:
        """More than ``max_fraction`` of the control components rejected."""
        n_ctrl_rej = self.n_ctrl_start - int(self.ctrl_on.sum())
        return n_ctrl_rej > blunders.max_fraction * max(self.n_ctrl_start, 1)

    def keep_control(self) -> None:
        """Every rejected control component back in use, and no more control tests."""
        self.ctrl_on |= self.ctrl_rejected
        self.ctrl_rejected[:] = False
        self.control_tested = False

    def check_fractions(self, inp: _Inputs, blunders: BlunderOptions) -> None:
        """GeometryError when a kind of observation lost more than
        ``max_fraction`` to the tests: the rest cannot be trusted either."""
        limit = blunders.max_fraction
        n_img_rej = self.n_img_start - int(self.keep.sum())
        if n_img_rej > limit * max(self.n_img_start, 1):
            raise GeometryError(
                f"bundle adjustment: more than {limit:.0%} of the image "
                f"observations fail the blunder test ({n_img_rej} of {self.n_img_start}); the "
                "observations cannot be trusted"
            )
        if self.control_over_limit(blunders):
            raise GeometryError(
                f"bundle adjustment: more than {limit:.0%} of the control "
                "observations fail the blunder test; the control cannot be trusted, or "
                "uncorrected camera errors bend the block (when many points fail together, "
                'add [adjustment] self_calibration = "auto")'
            )
        for stage, what, given_k, rejected_k in (
            (GNSS_STAGE, "GNSS centres", inp.g_given, self.g_rejected),
            (IMU_STAGE, "IMU attitudes", inp.i_given, self.i_rejected),
        ):
            n_given_k = int(np.count_nonzero(given_k))
            n_rej_k = int(np.count_nonzero(rejected_k))
            if n_rej_k > limit * max(n_given_k, 1):
                raise GeometryError(
                    f"bundle adjustment, stage {stage!r}: more than {limit:.0%} "
                    f"of the {what} fail the blunder test ({n_rej_k} of {n_given_k} photos); "
                    f"the {what} cannot be trusted"
                )


def _compact(
    obs: ImageObservations, keep_obs: BoolArray, point_used: BoolArray
) -> tuple[ImageObservations, IntArray, IntArray]:
    """Observations of the used points only, points renumbered.

    Returns the sub-observations, the rows of ``obs`` they came from and the
    original point index of each new point.
    """
    rows = np.flatnonzero(keep_obs & point_used[obs.point])
    points = np.flatnonzero(point_used)
    new_index = np.full(point_used.shape[0], -1, dtype=np.intp)
    new_index[points] = np.arange(points.size)
    sub = ImageObservations(
        photo_ids=obs.photo_ids,
        point_ids=tuple(obs.point_ids)
        if points.size == len(obs.point_ids)
        else tuple(obs.point_ids[i] for i in points),
        photo=obs.photo[rows],
        point=new_index[obs.point[rows]],
        xy=obs.xy[rows],
        sigma=np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), obs.photo.shape)[rows],
        principal_distance=obs.principal_distance,
    )
    return sub, rows, points
