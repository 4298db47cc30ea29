"""Helpers of benchmarks/bench_peers.py: the scipy peer's analytic Jacobian
and the problem it shares with the Ceres peer."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_peers

from strip_aerotri.geometry.rotation import matrix_from_opk


def test_rotations_and_derivatives_match_matrix_from_opk():
    opk = np.random.default_rng(2345).normal(0.0, 1.0, (5, 3))
    rd = bench_peers._rotations_and_derivatives(opk)
    np.testing.assert_allclose(rd[0], matrix_from_opk(opk), atol=1e-15)
    h = 1e-6
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        numeric = (matrix_from_opk(opk + step) - matrix_from_opk(opk - step)) / (2 * h)
        np.testing.assert_allclose(rd[k + 1], numeric, atol=1e-8)


@pytest.fixture(scope="module")
def film():
    sim = bench_peers.simulate_case("film-12", 1)
    return sim, bench_peers.strip_method(sim)


def test_peer_problem_holds_the_full_control(film):
    sim, (points, _, _) = film
    problem = bench_peers.peer_problem(sim, points)
    assert problem.fixed.sum() > 0
    assert not (problem.fixed & ~problem.keep).any()
    full = [i for i, k in enumerate(sim.control.kind) if k.value == "full"]
    lookup = {p: i for i, p in enumerate(sim.observations.point_ids)}
    rows = [lookup[sim.control.point_ids[i]] for i in full]
    np.testing.assert_array_equal(problem.start[rows], sim.control.xyz[full])


def _central_differences(fun, x: np.ndarray) -> np.ndarray:
    """Jacobian of ``fun`` at ``x`` by central differences, a column per
    unknown, steps scaled to the unknown (the rule of scipy's "3-point")."""
    step = np.finfo(np.float64).eps ** (1 / 3) * np.maximum(1.0, np.abs(x))
    columns = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = step[j]
        columns.append((fun(x + e) - fun(x - e)) / (2.0 * step[j]))
    return np.column_stack(columns)


def test_analytic_jacobian_matches_finite_differences(film):
    sim, (points, centres, rotations) = film
    bundle = bench_peers.ScipyBundle(sim, bench_peers.peer_problem(sim, points))
    x = bundle.x0(centres, rotations)
    analytic = bundle.jacobian(x).toarray()
    numeric = _central_differences(bundle.residuals, x)
    np.testing.assert_allclose(analytic, numeric, atol=1e-6 * np.abs(analytic).max())


def test_scipy_peer_improves_on_the_strip_start(film):
    # The bundle from the strip method's start lowers the check-point RMSE
    # (film-12, seed 1: strip 0.080 / 0.210 m, bundle 0.079 / 0.160 m,
    # the same as Ceres in bench_peers.py --quick).
    sim, (points, centres, rotations) = film
    out, _, res = bench_peers.scipy_bundle(sim, centres, rotations, points)
    assert res.success
    plan, height = bench_peers.check_rmse(out, sim)
    strip_plan, strip_height = bench_peers.check_rmse(points, sim)
    assert plan <= strip_plan * 1.01
    assert height < strip_height


def test_tuned_ceres_reaches_the_default_ceres_solution(film):
    """The tuned Ceres peer (centred world coordinates, function_tolerance
    1e-10, initial trust radius 1e8) solves the same problem: the same
    points as pycolmap's defaults, back in the site system."""
    pytest.importorskip("pycolmap")
    sim, (points, centres, rotations) = film
    default, _ = bench_peers.ceres(sim, centres, rotations, points)
    tuned, seconds = bench_peers.ceres(sim, centres, rotations, points, tuned=True)
    assert seconds > 0
    ok = np.isfinite(default).all(axis=1)
    assert ok.sum() > 100
    np.testing.assert_array_equal(np.isfinite(tuned).all(axis=1), ok)
    np.testing.assert_allclose(tuned[ok], default[ok], atol=1e-3)  # metres
    # and it moved from the start: a bundle, not the start given back
    assert np.abs(tuned[ok] - points[ok]).max() > 1e-3
