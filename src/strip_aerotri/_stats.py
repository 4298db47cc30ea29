"""Critical values of the blunder tests, and medians for their robust scales."""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

from ._typing import ArrayLike, IntArray

#: Values above which a robust scale is taken from an evenly spaced sample.
MEDIAN_SAMPLE = 65_536


def sample_median(values: ArrayLike) -> float:
    """Median of `values`, or of every k-th of them when there are more than
    `MEDIAN_SAMPLE` (k the smallest step that leaves at most that many).

    For the robust scales of the tests (1.4826 MAD) and the image scale a
    sample of 65 536 spread over the whole strip estimates the median within
    about 0.5 % (its standard error for normal data), far below what the
    critical values resolve, and costs a tenth of a full partition of a
    1000-photo strip's 300 000 values.  Smaller arrays give their exact
    median.
    """
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    step = -(-arr.size // MEDIAN_SAMPLE)
    return float(np.median(arr[::step] if step > 1 else arr))


def exact_median(values: ArrayLike) -> float:
    """Median of all `values`; a constant array (one sigma for every
    observation, the usual case) is recognised in two O(n) passes instead of
    a partition."""
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.size and arr.min() == arr.max():
        return float(arr[0])
    return float(np.median(arr))


def critical_value(n_tests: int, alpha: float) -> float:
    """Two-sided critical value of n normal tests at family-wise level alpha.

    ``Φ⁻¹(1 − alpha / (2 n))`` (Bonferroni); n < 1 is taken as 1.
    """
    n = max(int(n_tests), 1)
    # the lower tail, Φ⁻¹(alpha / 2n), has no cancellation in 1 − p
    return -NormalDist().inv_cdf(float(alpha) / (2.0 * n))


def chi_critical_value(n_tests: int, alpha: float, dof: int) -> float:
    """Square root of the chi-square(dof) quantile at ``1 − alpha / n``: the
    critical ``sqrt(vᵀ P v)`` of n tests of ``dof`` components each (Bonferroni).

    The quantile solves ``Q(x) = alpha / n`` for the chi-square survival
    function of an integer dof, which is a finite sum (:func:`_chi2_survival`),
    by Newton's method on ``log Q``: no scipy.special (25 ms of CPU to import
    for this one value, scipy.stats 0.2 s); it agrees with scipy's ``chdtri``
    to 1e-13 (tests/test_stats.py).
    """
    return math.sqrt(_chi2_upper_quantile(int(dof), float(alpha) / max(int(n_tests), 1)))


def _chi2_survival(x: float, dof: int) -> tuple[float, float]:
    """``Q(x)`` and the density ``f(x)`` of chi-square(dof), dof >= 1 an integer:
    with ``h = x / 2``, ``Q = e^-h Σ_{j<dof/2} h^j / j!`` for an even dof and
    ``erfc(√h) + e^-h Σ_{1<=j<=(dof-1)/2} h^(j-1/2) / Γ(j + 1/2)`` for an odd one
    (Abramowitz and Stegun 26.4.4-5), the terms in logarithms (no overflow)."""
    h = 0.5 * x
    if h <= 0.0:
        return 1.0, (0.5 if dof == 2 else (math.inf if dof == 1 else 0.0))
    log_h = math.log(h)
    if dof % 2 == 0:
        terms = [math.exp(j * log_h - math.lgamma(j + 1.0) - h) for j in range(dof // 2)]
        q = math.fsum(terms)
    else:
        terms = [
            math.exp((j - 0.5) * log_h - math.lgamma(j + 0.5) - h)
            for j in range(1, (dof - 1) // 2 + 1)
        ]
        q = math.fsum([math.erfc(math.sqrt(h)), *terms])
    density = math.exp((0.5 * dof - 1.0) * log_h - h - math.log(2.0) - math.lgamma(0.5 * dof))
    return q, density


def _chi2_upper_quantile(dof: int, p: float) -> float:
    """The x with ``Q(x) = p`` of chi-square(dof): Newton's method on
    ``log Q(x) − log p`` (Q decreasing, log Q nearly linear in the tail) from
    the Wilson-Hilferty approximation, to the last bits."""
    if dof < 1 or not 0.0 < p < 1.0:
        raise ValueError(f"Expected dof >= 1 and 0 < p < 1, got {dof}, {p}")
    z = -NormalDist().inv_cdf(p)
    c = 2.0 / (9.0 * dof)
    x = max(dof * (1.0 - c + z * math.sqrt(c)) ** 3, 1e-3 * dof)
    log_p = math.log(p)
    for _ in range(100):
        q, density = _chi2_survival(x, dof)
        if density <= 0.0 or q <= 0.0:
            break
        step = (math.log(q) - log_p) * q / density
        new = x + step if x + step > 0.0 else 0.5 * x
        if abs(new - x) <= 1e-15 * x:
            return new
        x = new
    return x


def leading_failures(score: ArrayLike, critical: float, *groups: ArrayLike) -> IntArray:
    """The tests that fail and lead each of their groups: indices of every
    ``score`` above ``critical`` that is the largest score of each group it
    belongs to (``groups``: one integer label per test each, e.g. its point
    and its model), by decreasing score; of equal scores in a group, the
    first.

    Data snooping that rejects these together in one round rejects what
    one-at-a-time snooping would reject round after round, as long as a
    blunder's effect on the other tests stays within its groups (a point's
    other determinations, a model's other points): the largest failing test
    of a point or a model may be the echo of a blunder, so only the leader
    of both goes (method.md §6B).  NaN scores neither fail nor lead.
    """
    s = np.asarray(score, dtype=np.float64).reshape(-1)
    s = np.where(np.isfinite(s), s, -np.inf)
    if not np.any(s > critical):  # nothing fails (a clean strip): no sort of every test
        return np.zeros(0, dtype=np.intp)
    order = np.argsort(-s, kind="stable")
    lead = s[order] > critical
    for labels in groups:
        g = np.asarray(labels).reshape(-1)[order]
        _, first = np.unique(g, return_index=True)
        leads_group = np.zeros(order.size, dtype=bool)
        leads_group[first] = True
        lead &= leads_group
    chosen: IntArray = order[lead].astype(np.intp)
    return chosen


def normal_tail(x: float) -> float:
    """``Φ(−x)``, the chance of a standard normal beyond x: ``erfc(x √½) / 2``
    (no cancellation for large x; what scipy's ``ndtr(-x)`` returns)."""
    return 0.5 * math.erfc(float(x) * math.sqrt(0.5))


def binomial_tail(count: int, n: int, p: float) -> float:
    """``P(X >= count)`` of ``X ~ B(n, p)``, to a few units of the last place.

    A finite sum, not scipy.special's incomplete beta (25 ms of CPU to
    import): one term ``P(X = a)`` is taken in Loader's saddle-point form
    (:func:`_binomial_term`, accurate whatever n), the others follow from it
    by the ratio ``P(X = j + 1) / P(X = j) = (n − j) p / ((j + 1) q)``.  Above
    the mean the upper tail is summed from ``a = count``; below it ``1 −`` the
    lower tail from ``a = count − 1`` down (then the sum is at least about 1/2,
    so nothing cancels).  It agrees with scipy's ``betainc(count, n − count + 1,
    p)`` to 2e-13, its error: to 1e-15 of the exact sum (tests/test_binomial_tail.py).
    """
    count, n, p = int(count), int(n), float(p)
    if count <= 0 or p >= 1.0:
        return 1.0
    if count > n or p <= 0.0:
        return 0.0
    q = 1.0 - p
    if count > n * p:
        j = np.arange(count, n, dtype=np.float64)
        ratios = (n - j) / (j + 1.0) * (p / q)
        return float(_binomial_term(count, n, p) * np.sum(np.cumprod(np.r_[1.0, ratios])))
    j = np.arange(count - 1, 0, -1, dtype=np.float64)
    ratios = j / (n - j + 1.0) * (q / p)
    lower = _binomial_term(count - 1, n, p) * np.sum(np.cumprod(np.r_[1.0, ratios]))
    return float(1.0 - lower)


#: Stirling's series of ``log(n!) − log(√(2πn) (n/e)^n)``: 1/12, 1/360, 1/1260, ...
_STIRLING = (1.0 / 12.0, 1.0 / 360.0, 1.0 / 1260.0, 1.0 / 1680.0, 1.0 / 1188.0)


def _stirling_error(n: float) -> float:
    """``log(n!) − log(√(2πn) (n/e)^n)`` (Loader 2000): lgamma for n <= 15,
    else Stirling's series, its terms fewer the larger n."""
    if n <= 15.0:
        if n == 0.0:
            return 0.0
        return math.lgamma(n + 1.0) - (n + 0.5) * math.log(n) + n - 0.5 * math.log(2.0 * math.pi)
    n_terms = 2 if n > 500.0 else 3 if n > 80.0 else 4 if n > 35.0 else 5
    inverse_square = 1.0 / (n * n)
    total = 0.0
    for coefficient in reversed(_STIRLING[:n_terms]):
        total = coefficient - total * inverse_square
    return total / n


def _deviance(x: float, mean: float) -> float:
    """``x log(x / mean) + mean − x`` without cancellation near x = mean (Loader 2000)."""
    if abs(x - mean) >= 0.1 * (x + mean):
        return x * math.log(x / mean) + mean - x
    v = (x - mean) / (x + mean)
    total = (x - mean) * v
    term = 2.0 * x * v
    v2 = v * v
    for k in range(1, 1000):
        term *= v2
        new = total + term / (2 * k + 1)
        if new == total:
            break
        total = new
    return total


def _binomial_term(x: int, n: int, p: float) -> float:
    """``P(X = x)`` of ``X ~ B(n, p)`` in Loader's saddle-point form: the
    Stirling errors and the deviances are small, so the exponent is not a
    difference of large logarithms (as lgamma's would be for large n)."""
    q = 1.0 - p
    if x == 0:
        return math.exp(n * math.log1p(-p))
    if x == n:
        return math.exp(n * math.log(p))
    exponent = (
        _stirling_error(n)
        - _stirling_error(x)
        - _stirling_error(n - x)
        - _deviance(x, n * p)
        - _deviance(n - x, n * q)
    )
    return math.exp(exponent) * math.sqrt(n / (2.0 * math.pi * x * (n - x)))
