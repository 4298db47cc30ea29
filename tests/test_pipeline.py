"""Tests of the pipeline: triangulate() and run_project() (method.md §7-8)."""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest

import strip_aerotri as sa
from strip_aerotri.ground.polynomials import GroundOptions, LineSpec
from strip_aerotri.project import load_project
from strip_aerotri.results import AccuracyStatistics


@cache
def simulated(**kwargs) -> sa.SimulatedStrip:
    return sa.simulate_strip(10, seed=7, **kwargs)


def lines_of(sim) -> list[LineSpec]:
    return [
        LineSpec(point_ids=ids, weight=weight, name=f"line {k + 1}")
        for k, (ids, weight) in enumerate(sim.lines)
    ]


@pytest.mark.parametrize(
    ("kwargs", "polynomial", "route"),
    [
        ({}, 3, None),
        ({"crs": "EPSG:2180", "heading_deg": 200.0}, 2, "projected"),
        ({"preset": "corridor"}, "auto", "geocentric"),
        ({"crs": "local"}, 1, "projected"),
    ],
    ids=["utm-type3", "cs92-projected", "corridor-auto", "local"],
)
def test_run_project_gives_the_numbers_of_triangulate(tmp_path, kwargs, polynomial, route):
    sim = simulated(**kwargs)
    project = load_project(sim.write_project(tmp_path, polynomial=polynomial, route=route))
    from_files = sa.run_project(project)

    # The same inputs and options in memory: bitwise the same result (the
    # project's default max_iterations is 50, StripOptions' 30).
    in_memory = sa.triangulate(
        project.observations,
        project.control,
        project.crs,
        lines=lines_of(sim),
        strip_options=sa.StripOptions(max_iterations=project.adjustment.max_iterations),
        ground_options=GroundOptions(route=route or "geocentric", polynomial=polynomial),
    )
    np.testing.assert_array_equal(from_files.points, in_memory.points)
    np.testing.assert_array_equal(from_files.photo_centres, in_memory.photo_centres)
    np.testing.assert_array_equal(from_files.ground.photo_opk, in_memory.ground.photo_opk)
    np.testing.assert_array_equal(
        from_files.ground.control_residuals, in_memory.ground.control_residuals
    )

    # Against the simulator's own arrays: the files round image coordinates to
    # 1e-6 mm and control to 0.1 mm, so the numbers agree to a fraction of a
    # millimetre (measured at most 0.06 mm, attitudes 5e-8 rad).
    direct = sa.triangulate(
        sim.observations,
        sim.control,
        sim.crs,
        lines=lines_of(sim),
        ground_options=GroundOptions(route=route or "geocentric", polynomial=polynomial),
    )
    assert from_files.point_ids == direct.point_ids
    assert from_files.photo_ids == direct.photo_ids
    np.testing.assert_allclose(from_files.points, direct.points, rtol=0, atol=5e-4)
    np.testing.assert_allclose(from_files.photo_centres, direct.photo_centres, rtol=0, atol=5e-4)
    np.testing.assert_allclose(
        from_files.ground.photo_opk, direct.ground.photo_opk, rtol=0, atol=1e-6
    )
    np.testing.assert_allclose(
        from_files.check_statistics.rmse, direct.check_statistics.rmse, rtol=0, atol=1e-4
    )
    assert from_files.ground.route.value == (route or "geocentric")
    assert from_files.ground.polynomial_kind == direct.ground.polynomial_kind
    if polynomial != "auto":
        assert from_files.ground.polynomial_kind == polynomial
    assert from_files.ground.line_names == direct.ground.line_names
    assert len(from_files.ground.line_names) == len(sim.lines)


def hand_statistics(residuals: np.ndarray) -> dict[str, float]:
    plan_ok = np.isfinite(residuals[:, 0]) & np.isfinite(residuals[:, 1])
    h_ok = np.isfinite(residuals[:, 2])
    e, n, h = residuals[plan_ok, 0], residuals[plan_ok, 1], residuals[h_ok, 2]
    plan = np.sqrt(e**2 + n**2)
    return {
        "n_plan": int(plan_ok.sum()),
        "n_height": int(h_ok.sum()),
        "rmse_e": float(np.sqrt(np.sum(e**2) / e.size)),
        "rmse_n": float(np.sqrt(np.sum(n**2) / n.size)),
        "rmse_h": float(np.sqrt(np.sum(h**2) / h.size)),
        "rmse_plan": float(np.sqrt(np.sum(plan**2) / plan.size)),
        "mean_plan": float(np.sum(plan) / plan.size),
        "max_plan": float(np.max(plan)),
        "max_height": float(np.max(np.abs(h))),
    }


def assert_statistics(stats: AccuracyStatistics, hand: dict[str, float]) -> None:
    assert stats.n_plan == hand["n_plan"]
    assert stats.n_height == hand["n_height"]
    np.testing.assert_allclose(
        stats.rmse, [hand["rmse_e"], hand["rmse_n"], hand["rmse_h"]], rtol=1e-12
    )
    assert stats.rmse_plan == pytest.approx(hand["rmse_plan"], rel=1e-12)
    assert stats.mean_plan == pytest.approx(hand["mean_plan"], rel=1e-12)
    assert stats.max_plan == pytest.approx(hand["max_plan"], rel=1e-12)
    assert stats.max_height == pytest.approx(hand["max_height"], rel=1e-12)


def test_statistics_match_a_hand_computation_from_the_residuals():
    sim = simulated()
    result = sa.triangulate(sim.observations, sim.control, sim.crs)
    ground = result.ground
    resid = ground.control_residuals
    assert resid.shape == (len(ground.control_index), 3)
    check, control = resid[ground.is_check], resid[~ground.is_check]
    assert_statistics(result.check_statistics, hand_statistics(check))
    assert_statistics(result.control_statistics, hand_statistics(control))
    # The "ends" layout: 6 full, 2 plan, height points; checks have all three.
    kinds = [sim.control.kind[i] for i in ground.control_index[~ground.is_check]]
    assert result.control_statistics.n_plan == sum(
        k in (sa.ControlType.FULL, sa.ControlType.PLAN) for k in kinds
    )
    assert result.control_statistics.n_height == sum(
        k in (sa.ControlType.FULL, sa.ControlType.HEIGHT) for k in kinds
    )
    assert result.check_statistics.n_plan == result.check_statistics.n_height == check.shape[0]
    # Check points are the truth: their residuals are truth minus adjusted.
    idx = [result.point_ids.index(sim.control.point_ids[i]) for i in ground.control_index]
    truth = sim.truth.points_crs[idx]
    np.testing.assert_allclose(
        check[:, 2], (truth[:, 2] - result.points[idx, 2])[ground.is_check], atol=1e-4
    )


def test_statistics_of_residuals_with_missing_components():
    residuals = np.array(
        [
            [0.03, -0.04, np.nan],  # plan point
            [np.nan, np.nan, 0.10],  # height point
            [0.00, 0.05, -0.20],  # full point
        ]
    )
    stats = AccuracyStatistics.from_residuals(residuals)
    # Hand: plan residuals 0.05 and 0.05 m; heights 0.10 and -0.20 m.
    assert (stats.n_plan, stats.n_height) == (2, 2)
    np.testing.assert_allclose(
        stats.rmse, [np.sqrt(0.03**2 / 2), np.sqrt((0.04**2 + 0.05**2) / 2), np.sqrt(0.025)]
    )
    assert stats.rmse_plan == pytest.approx(0.05)
    assert stats.mean_plan == pytest.approx(0.05)
    assert stats.max_plan == pytest.approx(0.05)
    assert stats.max_height == pytest.approx(0.20)
    empty = AccuracyStatistics.from_residuals(np.zeros((0, 3)))
    assert empty.n_plan == empty.n_height == 0
    assert np.isnan(empty.rmse).all() and np.isnan(empty.mean_plan)


def test_result_carries_every_stage_and_reports_progress():
    sim = simulated()
    messages: list[str] = []
    result = sa.triangulate(sim.observations, sim.control, sim.crs, progress=messages.append)
    assert len(messages) >= 2
    assert messages[0].startswith("forming the strip: 10 photos")
    assert set(result.timings) >= {"strip_formation", "ground"}
    assert all(t >= 0 for t in result.timings.values())
    assert result.strip.n_models == 9
    assert result.points.shape == (len(result.point_ids), 3)
    assert result.photo_centres.shape == (10, 3)
    np.testing.assert_allclose(
        result.photo_opk_degrees, np.degrees(result.ground.photo_opk), rtol=0, atol=0
    )
    assert result.control is sim.control
    assert result.warnings == ()


def test_warnings_from_loading_are_carried_into_the_result():
    sim = simulated()
    result = sa.triangulate(
        sim.observations, sim.control, sim.crs, warnings=("control.csv: point 'X9' unseen",)
    )
    assert result.warnings[0] == "control.csv: point 'X9' unseen"


def test_inputs_are_not_modified():
    sim = simulated()
    xy, xyz = sim.observations.xy.copy(), sim.control.xyz.copy()
    sa.triangulate(sim.observations, sim.control, sim.crs)
    np.testing.assert_array_equal(sim.observations.xy, xy)
    np.testing.assert_array_equal(sim.control.xyz, xyz)


def test_control_statistics_leave_out_rejected_control():
    sim = simulated()
    full = [i for i, k in enumerate(sim.control.kind) if k is sa.ControlType.FULL]
    xyz = sim.control.xyz.copy()
    xyz[full[2], 0] += 3.0  # a 3 m blunder in easting (1.5 m is found in 3 of 5 strips)
    control = dataclasses.replace(sim.control, xyz=xyz)
    result = sa.triangulate(sim.observations, control, sim.crs)
    rejected = [r.point for r in result.rejections if r.stage == "control"]
    assert rejected == [sim.control.point_ids[full[2]]]  # found and rejected
    # Measured 0.041 m; 1.62 m (the rejected point) when the statistics included it.
    assert result.control_statistics.max_plan < 0.3
