"""Scale transfer J(13)-(15) and B(139)-(140) (method.md §5)."""

import numpy as np
import pytest

from strip_aerotri.strip.scaling import scale_ratios


def _ties(seed=0):
    rng = np.random.default_rng(seed)
    model = np.repeat([1, 2, 3], 6)
    new = rng.normal(0, 1, (18, 3))
    new[:, 2] -= 3.0
    true_ratio = np.array([np.nan, 0.8, 1.25, 1.1])
    previous = true_ratio[model, None] * new
    return previous, new, model, true_ratio


@pytest.mark.parametrize("method", ["z", "distance"])
def test_exact_ratios(method):
    previous, new, model, truth = _ties()
    ratio = scale_ratios(previous, new, model, 4, method=method)
    assert np.isnan(ratio[0])  # model 0 has no tie points
    np.testing.assert_allclose(ratio[1:], truth[1:], rtol=1e-14)


def test_j13_sign_fix():
    """J(13) prints Δr_z = r'_z − s_lz + λ k̃ l_z; minimising that gives −λ."""
    previous, new, model, truth = _ties(1)
    u, d = new[:, 2], previous[:, 2]
    printed = -np.bincount(model, u * d)[1:] / np.bincount(model, u * u)[1:]
    assert np.all(printed < 0)
    np.testing.assert_allclose(scale_ratios(previous, new, model, 4)[1:], truth[1:], rtol=1e-14)


def test_z_least_squares_weights_by_height():
    previous, new, model, truth = _ties(2)
    rng = np.random.default_rng(9)
    noisy = previous + rng.normal(0, 1e-3, previous.shape)
    z = scale_ratios(noisy, new, model, 4, method="z")
    dist = scale_ratios(noisy, new, model, 4, method="distance")
    np.testing.assert_allclose(z[1:], truth[1:], rtol=2e-3)
    np.testing.assert_allclose(dist[1:], truth[1:], rtol=2e-3)
