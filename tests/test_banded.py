"""Banded normal equations (strip_aerotri.geometry._banded) against the dense path."""

from __future__ import annotations

import numpy as np
import pytest

import strip_aerotri.geometry.deformation as deformation
from strip_aerotri.errors import GeometryError
from strip_aerotri.geometry._banded import BandedNormals, _inverse_norm_1
from strip_aerotri.geometry.deformation import bspline_basis, fit_deformation, section_terms
from strip_aerotri.geometry.similarity import _normal_inverse, _redundancy_numbers, row_support


def _spline_rows(n_sections: int, n: int, seed: int = 0) -> np.ndarray:
    """Whitened rows of a type-3 spline over sections, unknowns in their own
    (not banded) order: B-splines first, then the hats."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, n)
    v = rng.uniform(-0.05, 0.05, n)
    rows = section_terms(u, v, 3, np.linspace(-1.0, 1.0, n_sections + 1))
    return rows / rng.uniform(0.5, 2.0, n)[:, None]


@pytest.mark.parametrize("n_sections", [30, 166, 400])
def test_solve_redundancy_and_condition_equal_the_dense_path(n_sections):
    a = _spline_rows(n_sections, 8 * n_sections)
    support = row_support(a)
    order = deformation._band_order(3, n_sections)
    banded = BandedNormals.from_rows(support.columns, support.value, support.n_columns, order)
    assert banded is not None
    q, cond = _normal_inverse(a, support)
    b = np.random.default_rng(1).normal(size=a.shape[1])
    x = q @ b
    np.testing.assert_allclose(banded.solve(b), x, rtol=0, atol=1e-10 * np.abs(x).max())
    np.testing.assert_allclose(
        1.0 - banded.quadratic_forms(support.columns, support.value),
        _redundancy_numbers(a, q, support),
        rtol=0,
        atol=1e-10,
    )
    # both bound the same 1-norm condition of the equilibrated matrix (symmetric)
    assert banded.cond == pytest.approx(cond, rel=1e-6)


@pytest.mark.parametrize("k, band", [(40, 3), (64, 2), (129, 5), (300, 31)])
def test_selected_inverse_holds_the_inverse_wherever_rows_need_it(k, band):
    # blocks of 64: one block padded, exactly one, a last block of 1, five;
    # rows touching band + 1 consecutive unknowns anywhere
    rng = np.random.default_rng(k)
    n = 6 * k
    first = rng.integers(0, k - band, n)
    index = first[:, None] + np.arange(band + 1)
    value = rng.normal(size=index.shape)
    dense = np.zeros((n, k))
    dense[np.arange(n)[:, None], index] = value
    banded = BandedNormals.from_rows(index, value, k, np.arange(k))
    inverse = np.linalg.inv(dense.T @ dense)
    expected = np.einsum(
        "ni,nj,nij->n", value, value, inverse[index[:, :, None], index[:, None, :]]
    )
    np.testing.assert_allclose(banded.quadratic_forms(index, value), expected, rtol=1e-10)
    b = rng.normal(size=k)
    np.testing.assert_allclose(banded.solve(b), inverse @ b, rtol=1e-10, atol=1e-12)


def test_singular_normals_are_refused_by_their_condition():
    a = _spline_rows(200, 1600)
    a[:, 5] = 0.0  # an unknown no row observes: zero diagonal
    support = row_support(a)
    order = deformation._band_order(3, 200)
    assert (
        BandedNormals.from_rows(support.columns, support.value, a.shape[1], order).cond == np.inf
    )
    b = _spline_rows(200, 1600)
    b[:, 7] = b[:, 6]  # two unknowns that only move together
    support = row_support(b)
    banded = BandedNormals.from_rows(support.columns, support.value, b.shape[1], order)
    assert banded.cond > deformation.SINGULAR_COND
    with pytest.raises(GeometryError, match="the design is singular"):
        deformation._solve(
            b, np.zeros(len(b)), np.ones(len(b)), what="test", names=["P1"], order=order
        )


def test_a_wide_band_is_declined():
    # every row ties unknown 0 to one other: after any ordering a band of k / 2
    k = 100
    a = np.zeros((3 * k, k))
    a[:, 0] = 1.0
    a[np.arange(3 * k), 1 + np.arange(3 * k) % (k - 1)] = 2.0
    support = row_support(a)
    assert BandedNormals.from_rows(support.columns, support.value, k, np.arange(k)) is None


def test_inverse_norm_estimate_is_a_close_lower_bound():
    rng = np.random.default_rng(3)
    for _ in range(20):
        m = rng.normal(size=(40, 40))
        m = m @ m.T + 0.1 * np.eye(40)
        exact = np.abs(np.linalg.inv(m)).sum(axis=0).max()
        estimate = _inverse_norm_1(lambda r, m=m: np.linalg.solve(m, r), 40)
        assert exact / 3.0 <= estimate <= exact * (1.0 + 1e-12)


def test_deformation_over_many_sections_is_the_dense_fit(monkeypatch):
    rng = np.random.default_rng(4)
    n = 1500
    xyz = np.column_stack(
        [np.sort(rng.uniform(0, 60_000, n)), rng.uniform(-900, 900, n), rng.normal(0, 30, n)]
    )
    target = (
        xyz
        - np.column_stack(
            [1e-9 * xyz[:, 0] ** 2, 3e-3 * xyz[:, 1], 1e-2 * np.sin(xyz[:, 0] / 5e3)]
        )
        + rng.normal(0, 0.02, (n, 3))
    )
    use = np.ones(n, dtype=bool)
    kwargs = {"use_xy": use, "use_z": use, "kind": 3, "sections": 120}
    banded = fit_deformation(xyz, target, **kwargs)
    monkeypatch.setattr(deformation.BandedNormals, "from_rows", lambda *a, **k: None)
    dense = fit_deformation(xyz, target, **kwargs)
    np.testing.assert_allclose(banded.coefficients, dense.coefficients, rtol=0, atol=1e-9)
    np.testing.assert_allclose(banded.residuals, dense.residuals, rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        banded.redundancy_numbers, dense.redundancy_numbers, rtol=0, atol=1e-9
    )


@pytest.mark.parametrize("kind", [1, 2, 3])
def test_sparse_section_rows_are_the_dense_design(kind):
    rng = np.random.default_rng(kind)
    u = np.concatenate([rng.uniform(-1.2, 1.2, 200), np.linspace(-1, 1, 9)])  # breakpoints too
    v = rng.uniform(-0.1, 0.1, u.size)
    breakpoints = np.linspace(-1.0, 1.0, 9)
    rows = deformation._section_support(u, v, kind, breakpoints)
    # the design of the module docstring, column by column from the B-spline bases
    expected = np.concatenate(
        [bspline_basis(u, breakpoints, kind), bspline_basis(u, breakpoints, 1) * v[:, None]],
        axis=1,
    )
    np.testing.assert_array_equal(deformation._dense(rows), expected)
    np.testing.assert_array_equal(section_terms(u, v, kind, breakpoints), expected)
