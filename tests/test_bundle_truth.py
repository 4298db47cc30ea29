"""The refinement on the curved earth against the simulator's truth and an
independent reference solved from the truth (benchmarks/bench_reference_bundle.py,
``compare_with_truth``; docs/bundle.md, "Against a reference bundle on strips
from another simulator")."""

from __future__ import annotations

import dataclasses
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_reference_bundle as reference

from strip_aerotri.observations import ControlType
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip


@pytest.fixture(scope="module")
def case():  # type: ignore[no-untyped-def]
    """A 16-photo drone strip in EPSG:2180 (geocentric route, plan-only and
    height-only control between full points at the ends), refined, and the
    comparison with its truth in the refinement's tangent frame."""
    sim = simulate_strip(16, preset="drone", seed=5, crs="EPSG:2180", control="fig4")
    # two check points in the middle made plan-only control (fig4 here has none)
    ctrl = sim.control
    kinds = list(ctrl.kind)
    checks = [i for i, k in enumerate(kinds) if k is ControlType.CHECK]
    xyz = ctrl.xyz.copy()
    for i in checks[len(checks) // 3 :: len(checks) // 3][:2]:
        kinds[i] = ControlType.PLAN
        xyz[i, 2] = np.nan
    ctrl = dataclasses.replace(ctrl, kind=tuple(kinds), xyz=xyz)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = triangulate(sim.observations, ctrl, sim.crs, refine="bundle")
    frame, t = result.refined.frame, sim.truth
    to_frame = frame.rotation @ t.local_to_ecef.ecef2enu.T  # simulator ENU -> tangent frame
    points = frame.ecef2local(t.local_to_ecef.local2ecef(t.points_local))
    centres = frame.ecef2local(t.local_to_ecef.local2ecef(t.photo_centres_local))
    return result, reference.compare_with_truth(
        result, points, centres, to_frame @ t.photo_rotations_local
    )


def test_the_frame_is_curved_and_the_control_mixed(case) -> None:  # type: ignore[no-untyped-def]
    result, _ = case
    assert result.refined.frame is not None
    ctrl = result.control
    rows = result.refined.control_index
    assert np.any(ctrl.uses_xy[rows] & ~ctrl.uses_h[rows])  # plan-only points
    assert np.any(ctrl.uses_h[rows] & ~ctrl.uses_xy[rows])  # height-only points


def test_the_refinement_is_at_the_minimum_a_reference_reaches_from_the_truth(case) -> None:  # type: ignore[no-untyped-def]
    """Same weighted sum of squares and same points (to 0.1 µm measured):
    the refinement stops at the least-squares solution of its own problem."""
    _, cmp = case
    assert cmp.cost_ours == pytest.approx(cmp.cost_reference, rel=1e-7)
    assert cmp.largest_point_difference_m < 1e-5


def test_the_truth_costs_what_its_unknowns_explain(case) -> None:  # type: ignore[no-untyped-def]
    """At the truth the sum of squares exceeds the minimum by a chi-square
    with as many degrees of freedom as unknowns (mean u, sd sqrt(2u)): a
    systematic error of the model (curvature, camera, weights) adds more."""
    _, cmp = case
    ref = cmp.reference
    u = 6 * len(ref.centres0) + 3 * np.unique(ref.point).size
    excess = cmp.cost_truth - cmp.cost_reference
    assert abs(excess - u) < 5 * np.sqrt(2 * u), (excess, u)


def test_errors_against_the_truth_match_the_own_standard_deviations(case) -> None:  # type: ignore[no-untyped-def]
    _, cmp = case
    assert np.all((cmp.point_z_rms > 0.6) & (cmp.point_z_rms < 1.6)), cmp.point_z_rms
    assert np.all((cmp.centre_z_rms > 0.5) & (cmp.centre_z_rms < 1.8)), cmp.centre_z_rms
