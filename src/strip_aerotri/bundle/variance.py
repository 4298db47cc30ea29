"""Observation weights from the data: variance components by group.

The bundle weighs each observation by ``1 / sigma**2`` with the sigmas the
project states: the image coordinates' ``sigma`` (one pixel by default),
the control's ``sigma_xy`` and ``sigma_h``, the GNSS centres' and IMU
attitudes'.  Their ratios decide how the image rays and the control share
the solution, and a stated sigma is often a guess.  Peers (BLUH, PAT-B,
Metashape's "reference accuracy" check) estimate them from the residuals,
group by group.

Groups: the image coordinates of tie points (every point without control in
the adjustment, check points included: they are free points there), the
image coordinates of the control points (their marks), the control in
plan, the control in height, the GNSS centres and the IMU attitudes.

For a group ``g`` with weights ``P_g`` and residuals ``v_g``, its share of
the redundancy is the sum of its redundancy numbers
``r_g = sum_i (Q_vv P)_ii`` (method.md 6B: the engine gives each image
coordinate's; a control component's is ``1 - q_ii / sigma_i**2`` with the
cofactor of its adjusted coordinate, a GNSS or IMU component's
``(Q_vv)_ii / sigma_i**2``).  Förstner's estimate of the group's variance
factor is

    s_g**2 = v_g' P_g v_g / r_g,

(Förstner 1979, *Ein Verfahren zur Schätzung von Varianz- und
Kovarianzkomponenten*, AVN 86; Koch 1999, *Parameter Estimation and
Hypothesis Testing in Linear Models*, §3.6.4: the iterated estimate
converges to Helmert's / the best invariant quadratic unbiased one).
``sum_g r_g`` is the redundancy and ``sum_g v_g' P_g v_g`` the weighted
sum of squares, so the groups split sigma0**2 exactly.  Each group's sigmas
are multiplied by ``s_g`` and the bundle is adjusted again, until every
factor is within :data:`TOLERANCE` of 1 (at most :data:`MAX_ITERATIONS`).

The blunder tests run at the sigmas given, and a group stated far too
precise would fail them at many good observations (GNSS centres stated at
2 cm with 6 cm of noise: 7 of 30 rejected, and the run stopped).  So the
weights come first from adjustments without the tests, each group's factor
from the median of its normalised residuals ``v sqrt(p) / sqrt(r_i)``
(``1.4826 median |w|``, which a few gross errors barely move); the tests then
run at those weights, and Förstner's estimate follows on what they keep,
each adjustment testing at the current weights.
A group's redundancy depends on the weights: a group stated far too
precise starts with almost none, and gains it as its sigma grows.  A group
whose redundancy is below :data:`MIN_REDUNDANCY` and whose estimate does not
ask for a larger sigma rests on too few degrees of freedom (its estimate
would run towards zero with its redundancy): its sigma goes back to the
given one, held there, and the others settle again.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, StrArray
from ..choices import BlunderAction
from ..observations import ImageObservations
from ..options import DEFAULT_MAX_ITERATIONS, BlunderOptions, SelfCalibration
from ..results import FrameRefinement, VarianceComponents, VarianceGroup
from .selfcal import carried_choice
from .snooping import refine_frame

__all__ = [
    "MAX_ITERATIONS",
    "MIN_REDUNDANCY",
    "TOLERANCE",
    "GroupStatistics",
    "group_statistics",
    "refine_frame_weighted",
]

#: Stop once every estimated group's factor ``s_g`` is within this of 1.
TOLERANCE = 0.02
#: Most adjustments with re-estimated weights after the first.
MAX_ITERATIONS = 8
#: Smallest share of the redundancy a group needs to have its variance
#: estimated (below it, ``v'Pv / r`` rests on too few degrees of freedom).
MIN_REDUNDANCY = 3.0
#: Redundancy numbers below this leave an observation out of the robust
#: estimate (its normalised residual ``v / (sigma sqrt(r))`` is unstable).
_MIN_ROBUST_R = 0.05
#: Fewest such observations a group needs for a robust estimate.
_MIN_ROBUST_COUNT = 5
#: Bounds of one iteration's factor (a group's sigma moves at most tenfold
#: per step).
_FACTOR_BOUNDS = (0.1, 10.0)

IMAGE_TIES = "image, tie points"
IMAGE_MARKS = "image, control points"
CONTROL_PLAN = "control plan"
CONTROL_HEIGHT = "control height"
GNSS = "GNSS centres"
IMU = "IMU attitudes"


class GroupStatistics(NamedTuple):
    """One group's weighted sum of squares ``vpv``, its redundancy ``r`` and
    its number ``n`` of scalar observations in the adjustment."""

    vpv: float
    r: float
    n: int


class _Sigmas(NamedTuple):
    """The sigmas an adjustment runs with: image (K,) mm, control (P, 3) m,
    GNSS (M, 3) m, IMU (M, 3) rad (inf where not observed)."""

    image: FloatArray
    control: FloatArray
    gnss: FloatArray | None
    imu: FloatArray | None


def group_statistics(
    fr: FrameRefinement,
    observed_point: ArrayLike,
    sigmas: _Sigmas,
    image_groups: ArrayLike | None = None,
) -> dict[str, GroupStatistics]:
    """Each group's ``v'Pv``, redundancy and count in the adjustment ``fr``
    (which must carry exact redundancy numbers: ``compute_precision``);
    ``observed_point`` (K,) the point of each image observation, ``sigmas``
    those ``fr`` ran with, ``image_groups`` (K,) the image observations'
    groups (default: tie points and control points, module notes)."""
    labels = _image_labels(fr, observed_point, image_groups)
    return {
        name: GroupStatistics(float(np.sum(e**2)), float(np.sum(r)), int(e.size))
        for name, (e, r) in _group_rows(fr, labels, sigmas).items()
    }


def _group_rows(
    fr: FrameRefinement, labels: StrArray, sigmas: _Sigmas
) -> dict[str, tuple[FloatArray, FloatArray]]:
    """Each group's whitened residuals ``v sqrt(p)`` and redundancy numbers,
    one per scalar observation in the adjustment; ``labels`` (K,) the image
    observations' groups."""
    out: dict[str, tuple[FloatArray, FloatArray]] = {}
    used = fr.observation_used
    v = fr.image_residuals_mm / sigmas.image[:, None]
    for name in _image_names(labels):
        rows = used & (labels == name)
        if rows.any():
            out[name] = (v[rows].ravel(), fr.image_redundancy[rows].ravel())
    s0 = fr.sigma0
    q = (fr.point_std / s0) ** 2 if s0 > 0 else np.full_like(fr.point_std, np.nan)
    for name, comps in ((CONTROL_PLAN, [0, 1]), (CONTROL_HEIGHT, [2])):
        on = fr.control_used[:, comps]
        if on.any():
            w = 1.0 / sigmas.control[:, comps][on] ** 2
            out[name] = (
                fr.control_residuals[:, comps][on] * np.sqrt(w),
                1.0 - q[:, comps][on] * w,
            )
    bundle = fr.bundle
    for name, sig, on_photo, resid, cof in (
        (GNSS, sigmas.gnss, fr.gnss_used, bundle.gnss_residuals, bundle.gnss_residual_cofactor),
        (IMU, sigmas.imu, fr.imu_used, bundle.imu_residuals, bundle.imu_residual_cofactor),
    ):
        if sig is None or not on_photo.any():
            continue
        on = on_photo[:, None] & np.isfinite(sig) & np.isfinite(resid)
        if on.any():
            w = 1.0 / sig[on] ** 2
            q_vv = np.diagonal(cof, axis1=1, axis2=2)[on]
            out[name] = (resid[on] * np.sqrt(w), q_vv * w)
    return out


def _robust_factors(
    rows: dict[str, tuple[FloatArray, FloatArray]], held: frozenset[str]
) -> dict[str, float]:
    """Each group's factor from the median of its normalised residuals
    ``v sqrt(p) / sqrt(r)`` (``1.4826 median |w|``; the observations with a
    redundancy number of at least :data:`_MIN_ROBUST_R`): barely moved by a
    few gross errors, for the weights the blunder tests first run with."""
    out: dict[str, float] = {}
    for name, (e, r) in rows.items():
        ok = r >= _MIN_ROBUST_R
        if name in held or np.count_nonzero(ok) < _MIN_ROBUST_COUNT:
            continue
        factor = 1.4826 * float(np.median(np.abs(e[ok]) / np.sqrt(r[ok])))
        if factor > 0.0:
            out[name] = factor
    return out


def _marks(fr: FrameRefinement, observed_point: ArrayLike) -> BoolArray:
    """The image observations (K,) of points with control in the adjustment."""
    point = np.asarray(observed_point, dtype=np.intp)
    has_control: BoolArray = np.any(fr.control_used, axis=1)[point]
    return has_control


def _image_labels(
    fr: FrameRefinement, observed_point: ArrayLike, given: ArrayLike | None
) -> StrArray:
    """The group (K,) of each image observation: ``given``, or by default
    :data:`IMAGE_MARKS` for the points with control in ``fr`` and
    :data:`IMAGE_TIES` for the rest."""
    if given is not None:
        return np.asarray(given, dtype=str)
    marks = _marks(fr, observed_point)
    labels: StrArray = np.where(marks, IMAGE_MARKS, IMAGE_TIES)
    return labels


def _image_names(labels: StrArray) -> list[str]:
    """The image groups present, the default ones in their order (ties first)."""
    present = [str(n) for n in np.unique(labels)]
    first = [n for n in (IMAGE_TIES, IMAGE_MARKS) if n in present]
    return first + [n for n in present if n not in first]


def _factors(stats: dict[str, GroupStatistics], held: frozenset[str]) -> dict[str, float]:
    """``sqrt(v'Pv / r)`` of every group not held at its given sigma."""
    return {
        name: float(np.sqrt(s.vpv / s.r))
        for name, s in stats.items()
        if name not in held and s.r > 0.0 and s.vpv > 0.0
    }


def _reset(sigmas: _Sigmas, apriori: _Sigmas, names: frozenset[str], labels: StrArray) -> _Sigmas:
    """The sigmas with the groups ``names`` back at their given values."""
    image = np.where(np.isin(labels, sorted(names)), apriori.image, sigmas.image)
    control = np.array(sigmas.control)
    if CONTROL_PLAN in names:
        control[:, :2] = apriori.control[:, :2]
    if CONTROL_HEIGHT in names:
        control[:, 2] = apriori.control[:, 2]
    gnss = apriori.gnss if GNSS in names else sigmas.gnss
    imu = apriori.imu if IMU in names else sigmas.imu
    return _Sigmas(image, control, gnss, imu)


def _scaled(
    sigmas: _Sigmas, factors: dict[str, float], labels: StrArray
) -> _Sigmas:
    """The sigmas with each group's multiplied by its factor (bounded per step)."""
    f = {k: float(np.clip(v, *_FACTOR_BOUNDS)) for k, v in factors.items()}
    names, group = np.unique(labels, return_inverse=True)
    image = sigmas.image * np.array([f.get(str(n), 1.0) for n in names])[group]
    control = sigmas.control * np.array(
        [f.get(CONTROL_PLAN, 1.0), f.get(CONTROL_PLAN, 1.0), f.get(CONTROL_HEIGHT, 1.0)]
    )
    gnss = None if sigmas.gnss is None else sigmas.gnss * f.get(GNSS, 1.0)
    imu = None if sigmas.imu is None else sigmas.imu * f.get(IMU, 1.0)
    return _Sigmas(image, control, gnss, imu)


#: Unit and the factor from the adjustment's unit to it, per group.
_UNITS = {
    IMAGE_TIES: ("µm", 1000.0),
    IMAGE_MARKS: ("µm", 1000.0),
    CONTROL_PLAN: ("m", 1.0),
    CONTROL_HEIGHT: ("m", 1.0),
    GNSS: ("m", 1.0),
    IMU: ("deg", float(np.degrees(1.0))),
}


def _median_sigma(sigmas: _Sigmas, name: str, labels: StrArray, used: FrameRefinement) -> float:
    """The group's median sigma over its observations in the adjustment."""
    if name not in (CONTROL_PLAN, CONTROL_HEIGHT, GNSS, IMU):  # an image group
        rows = used.observation_used & (labels == name)
        values = sigmas.image[rows]
    elif name in (CONTROL_PLAN, CONTROL_HEIGHT):
        comps = [0, 1] if name == CONTROL_PLAN else [2]
        values = sigmas.control[:, comps][used.control_used[:, comps]]
    else:
        sig = sigmas.gnss if name == GNSS else sigmas.imu
        on = used.gnss_used if name == GNSS else used.imu_used
        values = np.zeros(0) if sig is None else sig[on][np.isfinite(sig[on])]
    return float(np.median(values)) * _unit(name)[1] if values.size else float("nan")


def _unit(name: str) -> tuple[str, float]:
    """The unit of a group and the factor from the adjustment's unit to it."""
    return _UNITS.get(name, _UNITS[IMAGE_TIES])


def _components(
    fr: FrameRefinement,
    observed_point: ArrayLike,
    apriori: _Sigmas,
    sigmas: _Sigmas,
    iterations: int,
    sigma0_apriori: float,
    applied: bool,
    held: frozenset[str],
    image_groups: ArrayLike | None = None,
) -> VarianceComponents:
    """The record of the estimate: each group's sigmas, redundancy and last factor."""
    stats = group_statistics(fr, observed_point, sigmas, image_groups)
    factors = _factors(stats, held)
    labels = _image_labels(fr, observed_point, image_groups)
    groups = tuple(
        VarianceGroup(
            name=name,
            unit=_unit(name)[0],
            n=s.n,
            sigma_apriori=_median_sigma(apriori, name, labels, fr),
            sigma=_median_sigma(sigmas, name, labels, fr)
            * (1.0 if applied else factors.get(name, 1.0)),
            redundancy=s.r,
            factor=factors.get(name, float("nan")),
            estimated=name in factors and s.r >= MIN_REDUNDANCY,
        )
        for name, s in stats.items()
    )
    converged = _settled(factors) if applied else False
    return VarianceComponents(groups, iterations, converged, sigma0_apriori, applied)


def refine_frame_weighted(
    observations: ImageObservations,
    centres0: ArrayLike,
    rotations0: ArrayLike,
    points0: ArrayLike,
    *,
    control_xyz: ArrayLike | None = None,
    control_sigma: ArrayLike | None = None,
    gnss_centres: ArrayLike | None = None,
    gnss_sigma: ArrayLike | None = None,
    imu_rotations: ArrayLike | None = None,
    imu_sigma: ArrayLike | None = None,
    gnss_axes: ArrayLike | None = None,
    blunders: BlunderOptions | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    compute_precision: bool = True,
    observation_used: ArrayLike | None = None,
    control_used: ArrayLike | None = None,
    gnss_used: ArrayLike | None = None,
    imu_used: ArrayLike | None = None,
    self_calibration: SelfCalibration | None = None,
    control_tested: bool = True,
    variance_components: bool = False,
    apply: bool = True,
    image_groups: ArrayLike | None = None,
) -> FrameRefinement:
    """:func:`~strip_aerotri.bundle.snooping.refine_frame` with the groups'
    weights estimated from the residuals (module notes).

    Length: the parameters of ``refine_frame``, passed through; the loop
    itself is short.

    Parameters are those of ``refine_frame``, and:

    variance_components : bool
        Estimate the groups' variances; False: exactly ``refine_frame``.
    apply : bool
        Adjust again with the estimated weights until they settle (True), or
        only estimate and report them from the adjustment at the given
        weights (False, one adjustment).
    image_groups : array_like of str, shape (K,), optional
        The group of each image observation, by name (default: the tie
        points' and the control points', module notes).

    Returns
    -------
    FrameRefinement
        The last adjustment, with every round's rejections and
        ``variance_components`` set.  Exact redundancy numbers are needed, so
        ``compute_precision`` is taken as True.
    """
    obs = observations
    k_all = obs.photo.shape[0]
    m, p = len(obs.photo_ids), len(obs.point_ids)
    sigmas = _Sigmas(
        np.array(np.broadcast_to(np.asarray(obs.sigma, dtype=np.float64), (k_all,))),
        _broadcast(control_sigma, (p, 3)),
        None if gnss_centres is None else _broadcast(gnss_sigma, (m, 3)),
        None if imu_rotations is None else _broadcast(imu_sigma, (m, 3)),
    )
    apriori = sigmas
    spec = self_calibration
    state = (np.asarray(centres0), np.asarray(rotations0), np.asarray(points0, dtype=float))
    given_used = (observation_used, control_used, gnss_used, imu_used)
    used = given_used
    chosen = None
    held: frozenset[str] = frozenset()
    fr: FrameRefinement | None = None
    iterations = robust_steps = 0
    sigma0_apriori = float("nan")
    blunders = blunders or BlunderOptions()
    # the weights the tests run with come first, from robust estimates untested
    robust = variance_components and apply and blunders.testing
    untested = dataclasses.replace(blunders, action=BlunderAction.OFF)
    for _ in range(1 + (2 * MAX_ITERATIONS + 1 if variance_components and apply else 0)):
        if fr is not None:
            labels = _image_labels(fr, obs.point, image_groups)
            if robust:
                factors = _robust_factors(_group_rows(fr, labels, sigmas), held)
                robust_steps += 1
                settled = _settled(factors)
                robust = not settled and robust_steps < MAX_ITERATIONS
                if not settled:
                    sigmas = _scaled(sigmas, factors, labels)
            else:
                stats = group_statistics(fr, obs.point, sigmas, image_groups)
                factors = _factors(stats, held)
                # too little redundancy, and not asking for the larger sigma that gives more
                weak = frozenset(
                    n
                    for n, f in factors.items()
                    if stats[n].r < MIN_REDUNDANCY and f <= 1 + TOLERANCE
                )
                if weak:
                    held |= weak
                    sigmas = _reset(sigmas, apriori, weak, labels)
                elif _settled(factors):
                    break
                else:
                    sigmas = _scaled(sigmas, factors, labels)
            iterations += 1
        new = refine_frame(
            dataclasses.replace(obs, sigma=sigmas.image),
            state[0],
            state[1],
            state[2],
            control_xyz=control_xyz,
            control_sigma=sigmas.control,
            gnss_centres=gnss_centres,
            gnss_sigma=sigmas.gnss,
            imu_rotations=imu_rotations,
            imu_sigma=sigmas.imu,
            gnss_axes=gnss_axes,
            blunders=untested if robust else blunders,
            max_iterations=max_iterations,
            compute_precision=compute_precision or variance_components,
            observation_used=used[0],
            control_used=used[1],
            gnss_used=used[2],
            imu_used=used[3],
            self_calibration=spec,
            control_tested=control_tested,
        )
        if self_calibration is not None:
            new, chosen, spec = carried_choice(self_calibration, chosen, new)
        fr = new if fr is None else _merged(fr, new)
        if not variance_components:
            return fr
        if np.isnan(sigma0_apriori):
            sigma0_apriori = fr.sigma0
        control_tested = fr.control_tested
        # rejections stay rejected in the next adjustment
        used = (
            _and_given(~fr.observation_rejected, given_used[0]),
            _and_given(~fr.control_rejected, given_used[1]),
            _and_given(~fr.gnss_rejected, given_used[2]) if fr.gnss_rejected.size else None,
            _and_given(~fr.imu_rejected, given_used[3]) if fr.imu_rejected.size else None,
        )
        state = (fr.centres, fr.rotations, np.where(fr.point_used[:, None], fr.points, state[2]))
    assert fr is not None
    record = _components(
        fr, obs.point, apriori, sigmas, iterations, sigma0_apriori, apply, held, image_groups
    )
    return dataclasses.replace(fr, variance_components=record)


def _settled(factors: dict[str, float]) -> bool:
    """Every group's factor within :data:`TOLERANCE` of one."""
    return all(abs(f - 1.0) <= TOLERANCE for f in factors.values())


def _broadcast(sigma: ArrayLike | None, shape: tuple[int, int]) -> FloatArray:
    """Sigmas broadcast to ``shape`` (inf where not given)."""
    if sigma is None:
        return np.full(shape, np.inf)
    return np.array(np.broadcast_to(np.asarray(sigma, dtype=np.float64), shape))


def _merged(before: FrameRefinement, after: FrameRefinement) -> FrameRefinement:
    """The later adjustment with the earlier one's rejections kept in its record."""
    applied = tuple(r for r in before.rejections if r.applied)
    return dataclasses.replace(
        after,
        rejections=applied + after.rejections,
        observation_rejected=before.observation_rejected | after.observation_rejected,
        control_rejected=before.control_rejected | after.control_rejected,
        gnss_rejected=_union(before.gnss_rejected, after.gnss_rejected),
        imu_rejected=_union(before.imu_rejected, after.imu_rejected),
        iterations=before.iterations + after.iterations,
        rounds=before.rounds + after.rounds,
    )


def _and_given(free: BoolArray, given: ArrayLike | None) -> BoolArray:
    """``free`` and, when given, the caller's own selection."""
    if given is None:
        return free
    out: BoolArray = free & np.asarray(given, dtype=bool)
    return out


def _union(a: BoolArray, b: BoolArray) -> BoolArray:
    out: BoolArray = a | b if a.shape == b.shape else b
    return out
