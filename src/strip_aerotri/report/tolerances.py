"""Acceptance criteria of the Russian production rules (R4 §1.7.7, method.md §7).

Each function returns one :class:`Criterion`: the figure measured, the limit
it is compared with, the verdict and a one-line explanation.  A criterion
that cannot be judged (no check points, no map scale, too few residuals for a
distribution) has ``passed = None`` and says why.

What R4 (``seeds/004_69b66c655cdc61ba.txt``) states and what is used here:

* §1.7.7.4 (last lines): "Средние расхождения в плановом положении
  контрольных точек не должны быть более 0,3 мм" -- the mean plan
  discrepancy at check points at most 0.3 mm at the map scale, i.e.
  ``0.3e-3 * S`` metres for a map scale 1:S (:func:`check_mean_plan`).
* §1.7.7.8: "Для таких погрешностей должен соблюдаться закон нормального
  распределения, т.е. количество погрешностей в каждом следующем интервале
  их должно быстро уменьшаться. Предельные значения погрешностей не должны
  превосходить утроенных средних значений, причем количество предельных
  погрешностей должно быть не более 1% общего числа их." -- residuals shall
  follow the normal law (counts in successive intervals decrease quickly),
  limit errors shall not exceed three times the mean errors, and their
  number shall be at most 1 % of all.  Implemented as
  :func:`check_interval_decrease` and :func:`check_limit_share` (the share
  of residuals beyond three "mean errors" at most 1 %); the strict reading
  "the largest at most three means" is :func:`check_largest_vs_mean`,
  reported but not part of the verdict, because with hundreds of residuals
  a normal sample exceeds it by chance (see the note on the mean below).
  R4 states the rule for the residuals of the collinearity conditions; for a
  strip formed by relative orientation the corresponding residuals are the
  y-parallaxes (the coplanarity residuals of §1.7.7.4 г), so it is applied
  to them, and to the check-point plan discrepancies when there are enough.

The "mean error" (средняя погрешность) is taken as the root mean square
(``mean="rms"``, the default), as in the Russian usage where the mean
(square) error is the unit of limit errors.  The literal arithmetic mean of
the absolute values (``mean="abs"``) is available; with it three means are
2.39 σ, beyond which 1.67 % of normally distributed residuals lie, so the
1 % clause would reject exactly normal residuals, which the same paragraph
requires; with the RMS the share beyond 3 σ is 0.27 %.

Not implemented, with the reason:

* heights at check points (§1.7.7.4): the text says the mean height
  discrepancies "не должны превышать:" and the table of limits that followed
  is missing from the source, so no height limit is invented;
* adjacent strips (§1.7.7.7, 0.5 mm) and transfer between strips
  (§1.7.7.3, 40/60 µm): a single strip has no adjacent strip;
* interior orientation scale coefficients (§1.7.7.1): image coordinates
  are taken as already reduced to the principal point;
* R4 gives no limit for the residual y-parallax of a pair, so none is
  checked (sigma0 and the largest y-parallax are reported only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._stats import binomial_tail, normal_tail
from .._typing import ArrayLike

if TYPE_CHECKING:
    from ..results import StripResult

__all__ = [
    "CHANCE_LEVEL",
    "CHECK_PLAN_MM",
    "LIMIT_FACTOR",
    "LIMIT_SHARE",
    "MIN_DISTRIBUTION_SIZE",
    "TRANSFER_UM",
    "Criterion",
    "chance_beyond",
    "check_interval_decrease",
    "check_largest_vs_mean",
    "check_limit_share",
    "check_mean_plan",
    "mean_error",
    "plan_drift_warning",
    "residual_distribution",
    "tolerance_verdicts",
    "transfer_passed",
]

CHECK_PLAN_MM = 0.3
"""Mean plan discrepancy at check points, mm at the map scale (R4 §1.7.7.4)."""

LIMIT_FACTOR = 3.0
"""Largest residual at most this times the mean (R4 §1.7.7.8)."""

LIMIT_SHARE = 0.01
"""At most this share of the residuals at the limit (R4 §1.7.7.8: 1 %)."""

MIN_DISTRIBUTION_SIZE = 10
"""Fewer residuals than this are not judged for their distribution."""

CHANCE_LEVEL = 0.01
"""A count beyond the limit above :data:`LIMIT_SHARE` fails only when normally
distributed errors give so many with a probability below this."""


@dataclass(frozen=True)
class Criterion:
    """One acceptance criterion and its verdict.

    Attributes
    ----------
    name : str
        Stable identifier (``"check_mean_plan"``, ...).
    value : float or None
        The figure measured (unit in ``unit``); None when nothing to measure.
    limit : float or None
        The limit it is compared with (same unit); None when not applicable.
    passed : bool or None
        True or False; None when the criterion cannot be judged.
    explanation : str
        One sentence: what was compared, the source, and why None if so.
    unit : str
        Unit of ``value`` and ``limit`` (``"m"``, ``"µm"``, ``"%"``, ...).
    source : str
        Paragraph of R4 the criterion comes from.
    n : int
        Number of values the figure is computed from.
    chance : float or None
        For a count of values beyond a limit: the probability that normally
        distributed errors give at least as many (None where not applicable).
    """

    name: str
    value: float | None
    limit: float | None
    passed: bool | None
    explanation: str
    unit: str = ""
    source: str = "R4 §1.7.7"
    n: int = 0
    chance: float | None = None

    def as_dict(self) -> dict[str, object]:
        """Plain-JSON form (floats, str, bool or None)."""
        return {
            "name": self.name,
            "value": _num(self.value),
            "limit": _num(self.limit),
            "passed": self.passed,
            "unit": self.unit,
            "n": int(self.n),
            "source": self.source,
            "explanation": self.explanation,
            "chance": _num(self.chance),
        }


def _num(value: float | None) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if np.isfinite(value) else None


def _abs_finite(values: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"Expected `{name}` to have shape (N,), got {arr.shape}")
    return np.abs(arr[np.isfinite(arr)])


def _check_scale(map_scale: float | None) -> float | None:
    if map_scale is None:
        return None
    scale = float(map_scale)
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"Expected `map_scale` > 0 (the denominator S of 1:S), got {map_scale!r}")
    return scale


# --------------------------------------------------------------------------- criteria


def check_mean_plan(
    plan_discrepancies: ArrayLike,
    map_scale: float | None,
    *,
    limit_mm: float = CHECK_PLAN_MM,
    name: str = "check_mean_plan",
    what: str = "check points",
) -> Criterion:
    """Mean plan discrepancy at check points against ``limit_mm`` at map scale 1:S.

    Parameters
    ----------
    plan_discrepancies : array_like, shape (N,) or (N, 2)
        Plan discrepancies in metres: their lengths, or (dE, dN) pairs. NaN
        entries are ignored.
    map_scale : float or None
        Scale denominator S (5000 for 1:5000). None: not judged.
    limit_mm : float
        Limit in millimetres at the map scale (R4 §1.7.7.4: 0.3 mm).

    Returns
    -------
    Criterion
        ``value`` mean plan discrepancy (m), ``limit = limit_mm * 1e-3 * S``
        (m); passed when ``value <= limit``.
    """
    arr = np.asarray(plan_discrepancies, dtype=np.float64)
    if arr.ndim == 2 and arr.shape[1] == 2:
        arr = np.hypot(arr[:, 0], arr[:, 1])
    plan = _abs_finite(arr, "plan_discrepancies")
    scale = _check_scale(map_scale)
    limit = None if scale is None else limit_mm * 1e-3 * scale
    source = "R4 §1.7.7.4"
    if plan.size == 0:
        return Criterion(
            name, None, limit, None, f"no {what} with a plan discrepancy: not judged", "m", source
        )
    mean = float(plan.mean())
    if limit is None:
        return Criterion(
            name,
            mean,
            None,
            None,
            f"mean plan discrepancy at {plan.size} {what}; no map scale given: not judged",
            "m",
            source,
            plan.size,
        )
    passed = mean <= limit
    return Criterion(
        name,
        mean,
        limit,
        passed,
        f"mean plan discrepancy at {plan.size} {what} {mean:.3f} m "
        f"{'≤' if passed else '>'} {limit_mm:g} mm at 1:{scale:g} = {limit:.3f} m",
        "m",
        source,
        plan.size,
    )


def _too_few(name: str, n: int, what: str, unit: str) -> Criterion:
    return Criterion(
        name,
        None,
        None,
        None,
        f"{n} {what}: fewer than {MIN_DISTRIBUTION_SIZE}, distribution not judged",
        unit,
        "R4 §1.7.7.8",
        n,
    )


def mean_error(residuals: ArrayLike, mean: str = "rms") -> float:
    """The "mean error" of R4 §1.7.7.8: RMS (``"rms"``) or mean absolute value (``"abs"``).

    NaN entries are ignored; NaN when none is left.
    """
    v = _abs_finite(residuals, "residuals")
    if mean not in ("rms", "abs"):
        raise ValueError(f"Expected `mean` 'rms' or 'abs', got {mean!r}")
    if v.size == 0:
        return float("nan")
    return float(np.sqrt(np.mean(v**2))) if mean == "rms" else float(v.mean())


def _mean_text(mean: str) -> str:
    return "RMS" if mean == "rms" else "mean |v|"


def check_largest_vs_mean(
    residuals: ArrayLike,
    *,
    factor: float = LIMIT_FACTOR,
    mean: str = "rms",
    name: str = "largest_vs_mean",
    what: str = "residuals",
    unit: str = "",
) -> Criterion:
    """The largest absolute residual at most ``factor`` times the mean error.

    Parameters
    ----------
    residuals : array_like, shape (N,)
        Residuals in any unit (NaN ignored); their absolute values are used.
    factor : float
        R4 §1.7.7.8: three.
    mean : {"rms", "abs"}
        The mean error: root mean square, or mean absolute value.

    Returns
    -------
    Criterion
        ``value`` = max |v|, ``limit`` = factor × mean error (unit of the
        residuals); passed when ``value <= limit``.  Not judged below
        :data:`MIN_DISTRIBUTION_SIZE` residuals.
    """
    v = _abs_finite(residuals, "residuals")
    m = mean_error(v, mean)
    if v.size < MIN_DISTRIBUTION_SIZE:
        return _too_few(name, v.size, what, unit)
    largest = float(v.max())
    limit = factor * m
    passed = bool(largest <= limit)
    return Criterion(
        name,
        largest,
        limit,
        passed,
        f"largest of {v.size} {what} {largest:.3g} {unit} {'≤' if passed else '>'} "
        f"{factor:g} × {_mean_text(mean)} {m:.3g} {unit} = {limit:.3g} {unit}",
        unit,
        "R4 §1.7.7.8",
        v.size,
    )


def check_limit_share(
    residuals: ArrayLike,
    *,
    factor: float = LIMIT_FACTOR,
    share: float = LIMIT_SHARE,
    mean: str = "rms",
    name: str = "limit_share",
    what: str = "residuals",
    unit: str = "",
) -> Criterion:
    """At most ``share`` of the residuals beyond ``factor`` times the mean error.

    A residual beyond the limit (R4's "предельная погрешность") is one with
    ``|v| > factor * m``, m the mean error (:func:`mean_error`).

    Returns
    -------
    Criterion
        ``value`` = percentage of residuals beyond the limit, ``limit`` =
        ``100 * share`` (1 %); passed when the count is at most ``share * N``.
        Not judged below :data:`MIN_DISTRIBUTION_SIZE` residuals.
    """
    v = _abs_finite(residuals, "residuals")
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"Expected `share` in [0, 1], got {share!r}")
    m = mean_error(v, mean)
    if v.size < MIN_DISTRIBUTION_SIZE:
        return _too_few(name, v.size, what, "%")
    limit_value = factor * m
    count = int(np.count_nonzero(v > limit_value))
    percent = 100.0 * count / v.size
    # the share beyond the limit that errors within the rule may have: that of
    # normal errors (2 Φ(−3) = 0.27 % beyond three RMS), at most R4's share
    # (three mean absolute values are only 2.39 σ: 1.67 % of normal errors)
    sigmas = factor if mean == "rms" else factor * float(np.sqrt(2.0 / np.pi))
    chance = chance_beyond(count, v.size, sigmas, at_most=share)
    literal = count <= share * v.size
    passed = bool(literal or chance >= CHANCE_LEVEL)
    if literal:
        verdict = f"at most {100.0 * share:g} % allowed"
    else:
        verdict = (
            f"R4 allows {100.0 * share:g} %; normally distributed errors within it give {count} "
            "or more "
            f"of {v.size} beyond {factor:g} × {_mean_text(mean)} with a probability of "
            f"{100.0 * chance:.2g} %, "
            + (
                "so this is not evidence against them"
                if passed
                else f"below {100.0 * CHANCE_LEVEL:g} %: not a chance result"
            )
        )
    return Criterion(
        name,
        percent,
        100.0 * share,
        passed,
        f"{count} of {v.size} {what} ({percent:.2f} %) beyond {factor:g} × "
        f"{_mean_text(mean)} = {limit_value:.3g} {unit} (largest {float(v.max()):.3g} {unit}); "
        + verdict,
        "%",
        "R4 §1.7.7.8",
        v.size,
        chance,
    )


def chance_beyond(
    count: int, n: int, factor: float = LIMIT_FACTOR, *, at_most: float = 1.0
) -> float:
    """Probability that at least ``count`` of ``n`` normally distributed errors
    lie beyond ``factor`` standard deviations (binomial tail, each with
    probability 2 Φ(−factor), 0.27 % for three, or ``at_most`` if smaller).

    >>> round(chance_beyond(1, 40), 3)
    0.102
    >>> chance_beyond(0, 40)
    1.0
    """
    # Neither scipy.stats (0.2-0.35 s to import, a tenth of a run) nor
    # scipy.special (25 ms): P(X >= k) of X ~ B(n, p) is a finite sum
    # (_stats.binomial_tail; scipy's ``binom.sf(k - 1, n, p)`` within 2e-13),
    # and Φ(−x) is ``erfc(x √½) / 2``, as scipy's ``ndtr(-x)`` within an ulp.
    if count <= 0:
        return 1.0
    if count > n:
        return 0.0
    p = min(2.0 * normal_tail(factor), float(at_most))
    return binomial_tail(count, n, p)


def check_interval_decrease(
    residuals: ArrayLike,
    *,
    n_intervals: int = 3,
    mean: str = "rms",
    name: str = "interval_decrease",
    what: str = "residuals",
) -> Criterion:
    """Counts of |v| in successive intervals of one mean error do not increase.

    The intervals are ``[0, m), [m, 2m), ..., [(k-1)m, ∞)`` with m the mean
    error (:func:`mean_error`) and k = ``n_intervals``; the criterion passes
    when each count is at most the previous one.  For normally distributed
    residuals and k = 3 the expected shares are 68.3 %, 27.2 %, 4.6 % with
    the RMS (57.5 %, 31.5 %, 11.0 % with the mean absolute value).

    Returns
    -------
    Criterion
        ``value`` = the largest ratio of a count to the previous one (0 when
        a count is 0), ``limit`` = 1; passed when every ratio is at most 1.
        Not judged below :data:`MIN_DISTRIBUTION_SIZE` residuals.
    """
    v = _abs_finite(residuals, "residuals")
    if n_intervals < 2:
        raise ValueError(f"Expected `n_intervals` >= 2, got {n_intervals}")
    m = mean_error(v, mean)
    if v.size < MIN_DISTRIBUTION_SIZE:
        return _too_few(name, v.size, what, "")
    if m == 0.0:
        counts = np.zeros(n_intervals, dtype=np.int64)
        counts[0] = v.size
    else:
        index = np.minimum(np.floor(v / m).astype(np.int64), n_intervals - 1)
        counts = np.bincount(index, minlength=n_intervals)
    later = counts[1:].astype(np.float64)
    prev = counts[:-1].astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(later == 0, 0.0, later / prev)
    worst = float(ratio.max())
    passed = bool(np.all(np.diff(counts) <= 0))
    return Criterion(
        name,
        worst,
        1.0,
        passed,
        f"counts of {what} in intervals of one {_mean_text(mean)}: "
        f"{', '.join(str(int(c)) for c in counts)} "
        f"({'decreasing' if passed else 'not decreasing'})",
        "",
        "R4 §1.7.7.8",
        v.size,
    )


def residual_distribution(
    residuals: ArrayLike, *, prefix: str, what: str, unit: str = "", mean: str = "rms"
) -> tuple[Criterion, Criterion]:
    """The R4 §1.7.7.8 verdict checks of one set of residuals, names prefixed.

    Returns ``(interval_decrease, limit_share)``.
    """
    return (
        check_interval_decrease(
            residuals, name=f"{prefix}_interval_decrease", what=what, mean=mean
        ),
        check_limit_share(
            residuals, name=f"{prefix}_limit_share", what=what, unit=unit, mean=mean
        ),
    )


def tolerance_verdicts(result: StripResult, map_scale: float | None) -> tuple[Criterion, ...]:
    """All implemented R4 §1.7.7 criteria for a :class:`~strip_aerotri.results.StripResult`.

    The check-point criteria judge the final points: those of the bundle
    refinement when the run refined them (``result.refined``), else those
    of the ground stage; at the check points of the statistics, without the
    weakly determined ones (``result.weak_checks``).  The y-parallax criteria judge the relative
    orientation, which the refinement does not change.

    Parameters
    ----------
    result : StripResult
    map_scale : float or None
        Map scale denominator S; None leaves the plan criterion unjudged.

    Returns
    -------
    tuple of Criterion
        ``check_mean_plan``; then the distribution checks
        (:func:`residual_distribution`) of the residual y-parallaxes (µm,
        image scale) of all pairs (``y_parallax_*``) and of the check-point
        discrepancies dE and dN taken together (``check_en_*``, metres).
    """
    from ..ground.check_precision import strong_checks

    scale = _check_scale(map_scale)
    final = result.ground if result.refined is None else result.refined
    resid = np.asarray(final.control_residuals, dtype=np.float64).reshape(-1, 3)
    # the check points of the statistics: without the weakly determined ones
    check = strong_checks(final, result.control, result.weak_checks)
    check_plan = np.hypot(resid[check, 0], resid[check, 1])
    check_en = resid[check, :2].reshape(-1)
    parallax = np.asarray(result.strip.relative.parallax_um, dtype=np.float64)
    return (
        check_mean_plan(check_plan, scale),
        *residual_distribution(
            parallax, prefix="y_parallax", what="residual y-parallaxes", unit="µm"
        ),
        *residual_distribution(
            check_en, prefix="check_en", what="check-point discrepancies dE, dN", unit="m"
        ),
    )


#: R4 1.7.7.3: mean transfer error of the common points from strip to strip
#: in the free block, micrometres in the image, with digital identification
#: of the points (60 um with other identification).
TRANSFER_UM = 40.0


def transfer_passed(mean_transfer_um: float) -> bool | None:
    """R4 1.7.7.3's verdict on a join's mean transfer error in the image
    (:data:`TRANSFER_UM`); None when it was not computed."""
    if not math.isfinite(mean_transfer_um):
        return None
    return bool(mean_transfer_um <= TRANSFER_UM)


def plan_drift_warning(result: StripResult, map_scale: float | None) -> str | None:
    """A warning when the plan position of the strip, held only by its plan
    control, is far weaker between the control than the map scale needs.

    The simultaneous transformation of the models gives, for one point per
    model (the one most models share), its a priori plan standard deviation
    from the geometry and the weights (metres at σ0 = 1). When the largest
    exceeds R4's mean plan discrepancy at check points (0.3 mm at 1:S), the
    check points between the control cannot be expected to meet it: a strip
    with plan control only at its ends drifts between them. None without a
    map scale, for J's polynomials (no such precision), or after a bundle
    refinement (which judges its own points).
    """
    scale = _check_scale(map_scale)
    models = result.ground.models
    if scale is None or models is None or result.refined is not None:
        return None
    probe, sigma = models.result.probe_points, models.result.probe_plan_sigma
    if probe is None or sigma is None:
        return None
    n_points = result.strip.observations.n_points
    valid = (probe >= 0) & (probe < n_points) & np.isfinite(sigma)
    if not valid.any():
        return None
    limit = CHECK_PLAN_MM * 1e-3 * scale
    model = int(np.flatnonzero(valid)[np.argmax(sigma[valid])])
    worst = float(sigma[model])
    if worst <= limit:
        return None
    labels = result.strip.model_labels
    where = labels[model] if model < len(labels) else f"model {model + 1}"
    point = result.strip.observations.point_ids[int(probe[model])]
    return (
        f"plan precision between the plan control: point {point!r} ({where}) is held to "
        f"{worst:.2f} m in plan (standard deviation from the strip's geometry), while a map at "
        f"1:{scale:g} needs check points within {limit:.2f} m on average (R4 §1.7.7.4): the "
        "strip drifts between its plan control; add plan control points between them, or "
        'observe the photo centres by GNSS ([gnss] with [adjustment] refine = "bundle")'
    )
