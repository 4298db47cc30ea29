"""The statistics of the simultaneous transformation against a dense reference.

A small problem (units along a strip, each point in two or three of them,
control given in full, in plan and in height only, a straight line, a
polynomial per unit) is solved by ``adjust_units`` on the structured engine;
at its solution the full Jacobian of every observation with respect to every
unknown is taken by central differences of a forward model written here,
and the dense normal matrix is inverted.  The control points' cofactors,
the control's and the line's redundancy numbers and the coefficients'
variances must equal that inverse's, and the redundancy numbers of the
dense reference sum to the adjustment's redundancy.
"""

from __future__ import annotations

import numpy as np
import pytest

from strip_aerotri.errors import GeometryError
from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.geometry.simultaneous import (
    LineCondition,
    UnitObservations,
    UnitPolynomial,
    UnitTransforms,
    adjust_units,
)

N_UNITS = 6


def _problem(seed: int):
    """Units along X, 8 points each, neighbours sharing 3 points; returns the
    observations, the truth of the points and the unit count."""
    rng = np.random.default_rng(seed)
    n_points = 3 + N_UNITS * 5
    truth = np.column_stack(
        [
            np.linspace(0.0, 100.0 * N_UNITS, n_points) + rng.normal(0, 5, n_points),
            rng.uniform(-40.0, 40.0, n_points),
            rng.normal(0.0, 4.0, n_points),
        ]
    )
    unit, point, xyz, weight = [], [], [], []
    for u in range(N_UNITS):
        pts = np.arange(5 * u, 5 * u + 8)
        rot = matrix_from_rotvec(rng.normal(0.0, 0.05, 3))
        scale, shift = 1.0 + rng.normal(0.0, 0.01), rng.normal(0.0, 10.0, 3)
        local = (truth[pts] - shift) @ rot / scale  # X = shift + s R x
        sig = np.array([0.02, 0.02, 0.05])
        for k, p in enumerate(pts):
            a = rng.normal(size=(3, 3)) * 0.2 + np.diag(1.0 / sig)  # a full weight
            unit.append(u)
            point.append(p)
            xyz.append(local[k] + rng.normal(0.0, 0.01, 3))
            weight.append(a.T @ a)
    obs = UnitObservations(
        np.array(unit), np.array(point), np.array(xyz), np.array(weight)
    )
    return obs, truth, n_points


def _forward(obs, centroid, poly, scale, rot, trans, coef, points, line_ab, line, ctrl):
    """Whitened-free residuals of every observation, in one vector, with
    their weights: the unit rows (3 each), the control components given, the
    line equations and the coefficients' priors."""
    u = obs.unit
    x = obs.xyz
    d = x - centroid[u]
    if poly is not None:
        d = d + np.einsum("nik,nk->ni", poly.basis(u, x), coef[u])
    v = trans[u] + scale[u, None] * np.einsum("nij,nj->ni", rot[u], d) - points[obs.point]
    cp, cxyz = ctrl
    c = (points[cp] - cxyz)[np.isfinite(cxyz)]
    e = points[line.point, 1] - line_ab[0] - line_ab[1] * points[line.point, 0]
    parts = [v.ravel(), c, e]
    if poly is not None:
        parts.append(coef.ravel())
    return np.concatenate(parts)


@pytest.mark.parametrize("degree", [0, 2])
def test_cofactors_and_redundancy_equal_the_dense_inverse(degree):
    obs, truth, n_points = _problem(3)
    control_point = np.array([0, 2, 14, 18, 30, 32])
    control_xyz = truth[control_point] + 0.01
    control_xyz[2, 2] = np.nan  # plan only
    control_xyz[3, :2] = np.nan  # height only
    control_sigma = np.array([[0.03, 0.03, 0.05]] * 6)
    line = LineCondition(point=np.array([5, 9, 12, 16, 21, 25]), sigma=0.5)
    poly = (
        UnitPolynomial.fit(obs.unit, obs.xyz, N_UNITS, degree) if degree else None
    )
    res = adjust_units(
        obs, N_UNITS, n_points, start=_fitted_start(obs, truth), points0=truth,
        control_point=control_point, control_xyz=control_xyz, control_sigma=control_sigma,
        lines=[line], polynomial=poly, tolerance=1e-14,
    )
    assert res.converged
    t = res.transforms
    coef = t.coefficients if t.coefficients is not None else np.zeros((N_UNITS, 0))
    n_extra = coef.shape[1]
    width = 7 + n_extra

    # the unknowns: per unit dt, dω (R <- exp(ω) R), ds/s, da; points; line a, b
    n_unknowns = width * N_UNITS + 3 * n_points + 2

    def residuals(x):
        du = x[: width * N_UNITS].reshape(N_UNITS, width)
        dp = x[width * N_UNITS : -2].reshape(n_points, 3)
        return _forward(
            obs, t.centroid, poly, t.scale * (1 + du[:, 6]),
            matrix_from_rotvec(du[:, 3:6]) @ t.rotation, t.translation + du[:, :3],
            coef + du[:, 7:], res.points + dp, res.line_parameters[0] + x[-2:], line,
            (control_point, control_xyz),
        )

    jac = np.empty((residuals(np.zeros(n_unknowns)).size, n_unknowns))
    h = 1e-6
    for j in range(n_unknowns):  # a dense reference: one column at a time
        e = np.zeros(n_unknowns)
        e[j] = h
        jac[:, j] = (residuals(e) - residuals(-e)) / (2 * h)
    # the weights: the rows' 3 x 3 blocks, then 1/σ² of the rest
    n_rows = obs.unit.size
    given = np.isfinite(control_xyz)
    p = np.zeros((jac.shape[0], jac.shape[0]))
    for i in range(n_rows):
        p[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = obs.weight[i]
    rest = np.concatenate(
        [
            1.0 / control_sigma[given] ** 2,
            np.full(line.point.size, 1.0 / line.sigma**2),
            poly.prior_weights().ravel() if poly is not None else np.zeros(0),
        ]
    )
    k = 3 * n_rows
    p[k:, k:] = np.diag(rest)
    normal = jac.T @ p @ jac
    scale = 1.0 / np.sqrt(np.diag(normal))  # equilibrated before the inverse
    q = np.linalg.inv(normal * scale[:, None] * scale[None, :]) * scale[:, None] * scale[None, :]

    # control: the cofactors of the given components and their redundancy
    # (r = 1 - q / σ² near 0 loses digits: compared in absolute terms)
    comp = width * N_UNITS + 3 * control_point[:, None] + np.arange(3)
    q_ctrl = np.where(given, q[comp, comp], np.nan)
    diag = np.einsum("cii->ci", res.control_cofactor)
    np.testing.assert_allclose(diag[given], q_ctrl[given], rtol=1e-6)
    assert np.isnan(diag[~given]).all()
    np.testing.assert_allclose(
        res.control_redundancy[given], 1 - q_ctrl[given] / control_sigma[given] ** 2,
        rtol=0, atol=1e-7,
    )
    # the line: e's cofactor with the line's a, b, exact
    rows_line = slice(k + int(given.sum()), k + int(given.sum()) + line.point.size)
    a_line = jac[rows_line]
    q_ee = np.einsum("ij,jk,ik->i", a_line, q, a_line)
    np.testing.assert_allclose(
        res.line_redundancy[0], 1 - q_ee / line.sigma**2, rtol=0, atol=1e-7
    )
    # the coefficients' variances
    if poly is not None:
        cols = width * np.arange(N_UNITS)[:, None] + np.arange(7, width)
        np.testing.assert_allclose(res.coefficient_variance, q[cols, cols], rtol=1e-6)
    # the plan precision of the probe points
    has = res.probe_points >= 0
    assert has.any()
    cols = width * N_UNITS + 3 * res.probe_points[has]
    np.testing.assert_allclose(
        res.probe_plan_sigma[has], np.sqrt(q[cols, cols] + q[cols + 1, cols + 1]), rtol=1e-6
    )
    # the reference itself: its redundancy numbers sum to the redundancy
    r_all = 1 - np.einsum("ij,jk,ki->i", jac, q, jac.T @ p)
    assert r_all.sum() == pytest.approx(res.redundancy, abs=1e-6)


def _fitted_start(obs, truth):
    """Each unit's similarity from its points to the truth (Horn's method)."""
    from strip_aerotri.geometry.similarity import similarity_from_points

    fits = [
        similarity_from_points(obs.xyz[obs.unit == u], truth[obs.point[obs.unit == u]])
        for u in range(N_UNITS)
    ]
    return UnitTransforms(
        np.array([f.scale for f in fits]),
        np.array([f.rotation for f in fits]),
        np.array([f.translation for f in fits]),
        np.zeros((N_UNITS, 3)),
    )


def _adjust(obs, truth, n_points, **kwargs):
    control_point = np.array([0, 2, 14, 18, 30, 32])
    control_xyz = truth[control_point] + 0.01
    control_xyz[2, 2] = np.nan
    control_sigma = np.array([[0.03, 0.03, 0.05]] * 6)
    return adjust_units(
        obs, N_UNITS, n_points, start=_fitted_start(obs, truth), points0=truth,
        control_point=control_point, control_xyz=control_xyz, control_sigma=control_sigma,
        lines=[LineCondition(point=np.array([5, 9, 12, 16, 21, 25]), sigma=0.5)], **kwargs,
    )


def test_the_units_order_changes_the_cost_not_the_solution():
    obs, truth, n_points = _problem(4)
    given = _adjust(obs, truth, n_points, order="given")
    shuffled = np.random.default_rng(1).permutation(N_UNITS)
    for order in ("rcm", "auto", shuffled):
        other = _adjust(obs, truth, n_points, order=order)
        np.testing.assert_allclose(other.points, given.points, rtol=0, atol=1e-9)
        np.testing.assert_allclose(
            other.control_redundancy, given.control_redundancy, rtol=0, atol=1e-10
        )
        np.testing.assert_allclose(other.line_w[0], given.line_w[0], rtol=1e-8)


def test_statistics_later_equal_statistics_at_once():
    obs, truth, n_points = _problem(5)
    poly = UnitPolynomial.fit(obs.unit, obs.xyz, N_UNITS, 1)
    now = _adjust(obs, truth, n_points, polynomial=poly)
    without = _adjust(obs, truth, n_points, polynomial=poly, statistics=False)
    assert np.isnan(without.control_w).all() and np.isnan(without.line_w[0]).all()
    later = without.with_statistics()
    for name in ("control_cofactor", "control_redundancy", "control_w", "row_statistic"):
        np.testing.assert_array_equal(getattr(later, name), getattr(now, name))
    np.testing.assert_array_equal(later.line_redundancy[0], now.line_redundancy[0])
    np.testing.assert_array_equal(later.coefficient_variance, now.coefficient_variance)
    assert now.with_statistics() is now


def test_a_unit_not_tied_to_the_others_is_named():
    obs, truth, n_points = _problem(6)
    # unit 5 keeps two of the points it shares with unit 4 (all its others
    # are its own, no control on them): it can turn about their line
    last = obs.unit == N_UNITS - 1
    shared = np.isin(obs.point, obs.point[obs.unit == N_UNITS - 2])
    keep = ~(last & shared) | np.isin(obs.point, [25, 26])
    rows = UnitObservations(obs.unit[keep], obs.point[keep], obs.xyz[keep], obs.weight[keep])
    with pytest.raises(GeometryError, match="unit 5 shares too few points"):
        adjust_units(
            rows, N_UNITS, n_points, start=_fitted_start(rows, truth), points0=truth,
            control_point=np.array([0, 2, 14]), control_xyz=truth[[0, 2, 14]],
            control_sigma=0.03,
        )
