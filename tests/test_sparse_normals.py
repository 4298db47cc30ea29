"""Normal equations from the nonzero entries of sparse design rows (splines
over sections): the same normal matrix and redundancy numbers as the dense
products (similarity.row_support, _gram, _redundancy_numbers)."""

import numpy as np
import pytest

from strip_aerotri.geometry.deformation import section_terms
from strip_aerotri.geometry.similarity import (
    _gram,
    _normal_inverse,
    _redundancy_numbers,
    row_support,
)


def spline_design(n_rows: int, sections: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    # every section gets rows: evenly spread u with jitter, small v across the strip
    u = np.clip(np.linspace(-1, 1, n_rows) + rng.normal(0, 0.2 / n_rows, n_rows), -1, 1)
    v = rng.uniform(-0.05, 0.05, n_rows)
    weights = rng.uniform(0.5, 2.0, n_rows)
    return section_terms(u, v, 3, np.linspace(-1, 1, sections + 1)) * weights[:, None]


@pytest.mark.parametrize("rows, sections", [(200, 30), (600, 100)])
def test_sparse_normals_equal_the_dense_products(rows, sections):
    a = spline_design(rows, sections)
    support = row_support(a)
    assert support is not None
    # at most 4 cubic B-splines and 2 linear ones per row (fewer on a breakpoint),
    # and the support gives the matrix back
    assert support.columns.shape == (rows, 6)
    rebuilt = np.zeros_like(a)
    np.add.at(rebuilt, (np.arange(rows)[:, None], support.columns), support.value)
    np.testing.assert_array_equal(rebuilt, a)
    dense = a.T @ a
    np.testing.assert_allclose(_gram(a, support), dense, rtol=1e-13, atol=1e-13 * dense.max())
    q, cond = _normal_inverse(a)
    q_s, cond_s = _normal_inverse(a, support)
    np.testing.assert_allclose(q_s, q, rtol=1e-8, atol=1e-10 * np.abs(q).max())
    assert cond_s == pytest.approx(cond, rel=1e-8)
    r = _redundancy_numbers(a, q)
    np.testing.assert_allclose(_redundancy_numbers(a, q, support), r, rtol=0, atol=1e-12)
    # least squares: the redundancy numbers add up to rows - unknowns
    assert _redundancy_numbers(a, q, support).sum() == pytest.approx(rows - a.shape[1], rel=1e-9)


def test_dense_or_narrow_designs_keep_the_dense_products():
    rng = np.random.default_rng(1)
    assert row_support(rng.normal(size=(50, 7))) is None  # the similarity: 7 columns
    full = rng.normal(size=(300, 100))
    assert row_support(full) is None  # rows of more than a quarter nonzero
    sparse = np.zeros((300, 100))
    sparse[np.arange(300), rng.integers(0, 100, 300)] = 1.0
    support = row_support(sparse)
    assert support is not None and support.columns.shape == (300, 1)
    np.testing.assert_array_equal(_gram(sparse, support), sparse.T @ sparse)
