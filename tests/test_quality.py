"""Tests of the R4 §1.7.7 acceptance criteria on hand-made residuals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.stats import norm

from strip_aerotri.report.tolerances import (
    CHECK_PLAN_MM,
    MIN_DISTRIBUTION_SIZE,
    Criterion,
    check_interval_decrease,
    check_largest_vs_mean,
    check_limit_share,
    check_mean_plan,
    mean_error,
    residual_distribution,
)

# ----------------------------------------------------------------- mean plan at check points


def test_mean_plan_limit_is_0_3_mm_at_map_scale():
    # R4 §1.7.7.4: 0.3 mm at the map scale; 1:2000 -> 0.6 m
    assert CHECK_PLAN_MM == 0.3
    crit = check_mean_plan([0.1, 0.2], 2000)
    assert crit.limit == pytest.approx(0.6, abs=1e-15)
    assert crit.value == pytest.approx(0.15)
    assert crit.passed is True
    assert crit.unit == "m"
    assert crit.n == 2
    assert "R4" in crit.source


def test_mean_plan_exact_boundary_passes_and_just_above_fails():
    scale = 5000.0
    limit = CHECK_PLAN_MM * 1e-3 * scale  # 1.5 m, computed as the function does
    at = check_mean_plan(np.full(3, limit), scale)
    assert at.value == limit
    assert at.passed is True
    above = check_mean_plan(np.full(3, np.nextafter(limit, np.inf)), scale)
    assert above.passed is False
    assert "1.500 m" in above.explanation


def test_mean_plan_from_east_north_pairs_and_nan_ignored():
    # (0.3, 0.4) has length 0.5; the NaN row is not a plan discrepancy
    crit = check_mean_plan([[0.3, 0.4], [np.nan, np.nan], [0.0, 0.1]], 1000)
    assert crit.n == 2
    assert crit.value == pytest.approx(0.3)
    assert crit.limit == pytest.approx(0.3)
    assert crit.passed is True


def test_mean_plan_without_scale_or_points_is_not_judged():
    no_scale = check_mean_plan([0.2, 0.4], None)
    assert no_scale.passed is None
    assert no_scale.value == pytest.approx(0.3)
    assert no_scale.limit is None
    assert "no map scale" in no_scale.explanation
    empty = check_mean_plan(np.zeros(0), 2000)
    assert empty.passed is None
    assert empty.value is None
    assert empty.limit == pytest.approx(0.6)


@pytest.mark.parametrize("scale", [0.0, -500.0, np.nan, np.inf])
def test_mean_plan_rejects_bad_scale(scale):
    with pytest.raises(ValueError, match="map_scale"):
        check_mean_plan([0.1], scale)


# ----------------------------------------------------------------- distribution


def test_mean_error_rms_and_abs():
    v = [3.0, -4.0]
    assert mean_error(v) == pytest.approx(math.sqrt(12.5))
    assert mean_error(v, "abs") == pytest.approx(3.5)
    assert math.isnan(mean_error([np.nan]))
    with pytest.raises(ValueError, match="mean"):
        mean_error(v, "median")


def test_largest_vs_mean_exact_boundary():
    # nine 1s and one 9: RMS = sqrt((9 + 81) / 10) = 3, so 3 x RMS = 9 = the largest
    v = np.array([1.0] * 9 + [9.0])
    at = check_largest_vs_mean(v, unit="µm")
    assert at.limit == 9.0
    assert at.value == 9.0
    assert at.passed is True
    v[-1] = 9.001  # RMS grows by less than the largest: now beyond
    assert check_largest_vs_mean(v).passed is False


def test_largest_vs_mean_with_mean_absolute_value():
    # nine 1s and one x: 3 x mean|v| = (27 + 3x) / 10 >= x  <=>  x <= 27/7 = 3.857
    ok = check_largest_vs_mean([1.0] * 9 + [3.0], mean="abs")
    assert ok.limit == pytest.approx(3.6)
    assert ok.passed is True
    bad = check_largest_vs_mean([1.0] * 9 + [4.0], mean="abs")
    assert bad.limit == pytest.approx(3.9)
    assert bad.passed is False


def test_limit_share_exact_boundary_of_one_percent():
    # 99 ones and one 10: RMS = sqrt(199/100) = 1.41, 3 RMS = 4.23: 1 of 100 beyond = 1 %
    one = check_limit_share([1.0] * 99 + [10.0])
    assert one.value == pytest.approx(1.0)
    assert one.limit == pytest.approx(1.0)
    assert one.passed is True
    # 98 ones and two 10s: RMS = sqrt(2.98) = 1.73, 3 RMS = 5.18: 2 of 100 beyond = 2 %,
    # more than R4's 1 %, but normal errors give 2 or more of 100 beyond 3 sigma
    # with a probability of 3 %: not evidence against them (at the 1 % level)
    two = check_limit_share([1.0] * 98 + [10.0, 10.0])
    assert two.value == pytest.approx(2.0)
    assert two.passed is True and two.chance == pytest.approx(0.0303, abs=5e-4)
    assert "2 of 100" in two.explanation and "probability of 3 %" in two.explanation
    # three of 100 (3 %): a probability of 0.27 %, below 1 %: not met
    three = check_limit_share([1.0] * 97 + [10.0] * 3)
    assert three.value == pytest.approx(3.0)
    assert three.passed is False and three.chance < 0.01


def test_limit_share_value_at_the_limit_is_not_beyond():
    # nine 1s and one 9: 9 equals 3 x RMS, "не должны превосходить": not beyond
    crit = check_limit_share([1.0] * 9 + [9.0], share=0.0)
    assert crit.value == 0.0
    assert crit.passed is True


def test_interval_counts_decrease_for_normal_residuals():
    rng = np.random.default_rng(2345)
    v = rng.normal(0.0, 5.0, 200_000)
    crit = check_interval_decrease(v, what="y-parallaxes")
    assert crit.passed is True
    counts = [int(c) for c in crit.explanation.split(": ")[1].split(" (")[0].split(", ")]
    shares = np.array(counts) / v.size
    # documented expectation: 68.3 %, 27.2 %, 4.6 % (normal law, intervals of one sigma)
    expected = [2 * norm.cdf(1) - 1, 2 * (norm.cdf(2) - norm.cdf(1)), 2 * norm.sf(2)]
    np.testing.assert_allclose(shares, expected, atol=0.005)
    np.testing.assert_allclose(expected, [0.683, 0.272, 0.046], atol=0.0006)


def test_interval_counts_increasing_fail():
    # a bimodal set: twenty 5s and five 0s; RMS = 4.47, counts 5, 20, 0
    crit = check_interval_decrease([5.0] * 20 + [0.0] * 5)
    assert crit.passed is False
    assert crit.value == pytest.approx(4.0)
    assert "5, 20, 0" in crit.explanation


def test_distribution_not_judged_below_minimum_size():
    v = np.ones(MIN_DISTRIBUTION_SIZE - 1)
    for crit in (
        check_interval_decrease(v),
        check_largest_vs_mean(v),
        check_limit_share(v),
    ):
        assert crit.passed is None
        assert crit.value is None
        assert crit.n == MIN_DISTRIBUTION_SIZE - 1
    assert check_largest_vs_mean(np.ones(MIN_DISTRIBUTION_SIZE)).passed is True


def test_normal_share_beyond_three_means():
    # Why the RMS is the default mean: beyond 3 mean|v| lie 1.67 % of normal residuals
    # (more than R4's 1 %), beyond 3 RMS 0.27 % (docs/outputs.md, quality.py docstring).
    assert 2 * norm.sf(3 * math.sqrt(2 / math.pi)) == pytest.approx(0.0167, abs=5e-5)
    assert 2 * norm.sf(3.0) == pytest.approx(0.0027, abs=5e-5)
    rng = np.random.default_rng(7)
    v = rng.normal(0.0, 1.0, 100_000)
    assert check_limit_share(v).passed is True
    assert check_limit_share(v, mean="abs").passed is False


def test_residual_distribution_names_and_bad_arguments():
    inter, share = residual_distribution(np.arange(20.0), prefix="y_parallax", what="q")
    assert inter.name == "y_parallax_interval_decrease"
    assert share.name == "y_parallax_limit_share"
    with pytest.raises(ValueError, match="shape"):
        check_limit_share(np.ones((3, 3)))
    with pytest.raises(ValueError, match="n_intervals"):
        check_interval_decrease(np.ones(20), n_intervals=1)
    with pytest.raises(ValueError, match="share"):
        check_limit_share(np.ones(20), share=2.0)


def test_criterion_as_dict_is_plain_json():
    crit = Criterion("x", float("nan"), float("inf"), None, "text", "m", "R4 §1.7.7.4", 3)
    d = crit.as_dict()
    assert d["value"] is None and d["limit"] is None
    text = json.dumps(d, allow_nan=False)
    assert json.loads(text)["n"] == 3
