"""The start of an adjustment of units from the same adjustment on groups
of units (geometry/grouped_start.py): the groups along a strip, and a start
that changes the path, not the solution."""

from __future__ import annotations

import numpy as np
import pytest

from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.geometry.grouped_start import grouped_start, groups_along
from strip_aerotri.geometry.simultaneous import UnitObservations, UnitTransforms, adjust_units


def test_groups_along_runs_of_units_starting_again_at_breaks():
    assert groups_along(10, 4).tolist() == [0, 0, 0, 0, 1, 1, 1, 1, 1, 1]
    # a run shorter than a group is one group
    assert groups_along(10, 4, [5]).tolist() == [0] * 5 + [1] * 5
    # the rest of a run (fewer than `size` units) joins its last group
    assert groups_along(10, 2, [3]).tolist() == [0, 0, 0, 1, 1, 2, 2, 3, 3, 3]
    assert groups_along(3, 1).tolist() == [0, 1, 2]
    with pytest.raises(ValueError, match="Expected a group size of at least 1"):
        groups_along(3, 0)


N_UNITS = 64
PER_UNIT = 10  # points of a unit; neighbours share 4


def _bent_strip(seed: int):
    """A strip of units in one frame (a chain) whose rotation against the
    ground drifts from unit to unit (3e-4 rad a step, a roll and a random
    walk): the rows are each unit's points turned into the chain by its own
    rotation, with noise.  Returns the rows, the ground points, the control
    and their count."""
    rng = np.random.default_rng(seed)
    n_points = (N_UNITS - 1) * (PER_UNIT - 4) + PER_UNIT
    along = np.linspace(0.0, 60.0 * N_UNITS, n_points)
    ground = np.column_stack(
        [along, rng.uniform(-40.0, 40.0, n_points), rng.normal(0.0, 3.0, n_points)]
    )
    drift = np.cumsum(rng.normal(0.0, 3e-4, (N_UNITS, 3)) + [3e-4, 0.0, 0.0], axis=0)
    to_ground = matrix_from_rotvec(drift)  # chain -> ground of each unit
    unit = np.repeat(np.arange(N_UNITS), PER_UNIT)
    point = (np.arange(N_UNITS)[:, None] * (PER_UNIT - 4) + np.arange(PER_UNIT)).reshape(-1)
    xyz = np.einsum("nji,nj->ni", to_ground[unit], ground[point])
    xyz += rng.normal(0.0, 0.005, (point.size, 3))
    weight = np.broadcast_to(np.diag([1.0 / 0.01**2] * 2 + [1.0 / 0.03**2]), (point.size, 3, 3))
    obs = UnitObservations(unit, point, xyz, weight.copy())
    # heights all along, plan at the ends and in the middle
    control_point = np.arange(0, n_points, 7)
    control_xyz = ground[control_point] + rng.normal(0.0, 0.01, (control_point.size, 3))
    plan = np.zeros(control_point.size, dtype=bool)
    plan[[0, 1, control_point.size // 2, -2, -1]] = True
    control_xyz[~plan, :2] = np.nan
    return obs, ground, control_point, control_xyz, n_points


#: Rotations of the two paths' solutions agree to this (rad).  The adjustment
#: stops when its step or its relative change of the cost is below its
#: tolerance (1e-10), and the cost's change is flat near the solution: on
#: seeds 1-7 the two paths ended 4e-11 to 1.9e-9 rad apart, with either
#: inverse of the points' V in the projection after a step (LAPACK's: 1.5e-9
#: at seed 1, 1.9e-9 at seed 5; the engine's: 1.7e-9 at seed 7), and both
#: within 2e-9 rad of the solution iterated on to 1e-15.
SAME_ROTATION = 2.5e-9
#: Points agree to this (m): such a rotation over a unit's 100 m (seed 5,
#: LAPACK's inverse: 1.1e-7 m; seed 7, the engine's: 9.8e-8 m).
SAME_POINT = SAME_ROTATION * 100.0


@pytest.mark.parametrize("seed", [1, 5, 7])
def test_grouped_start_reaches_the_same_solution_in_fewer_iterations(seed):
    """From one similarity of the whole strip rolled 1.4 rad off (as J's
    similarity of a long strip bent by its chain is) the units must turn
    back; from the groups' adjustment they
    start near their own similarities: the same solution (to 2.5e-7 m), in
    fewer iterations of the units' adjustment."""
    obs, ground, control_point, control_xyz, n_points = _bent_strip(seed)
    one = UnitTransforms(
        np.ones(N_UNITS),
        np.broadcast_to(matrix_from_rotvec([1.4, 0.0, 0.0]), (N_UNITS, 3, 3)).copy(),
        np.zeros((N_UNITS, 3)),
        np.zeros((N_UNITS, 3)),
    )
    common = {
        "control_point": control_point,
        "control_xyz": control_xyz,
        "control_sigma": np.full((control_point.size, 3), 0.01),
    }
    points0 = np.zeros((n_points, 3))
    points0[obs.point] = obs.xyz
    direct = adjust_units(
        obs, N_UNITS, n_points, start=one, points0=points0,
        project_points=True, order="given", **common,
    )  # fmt: skip
    group = groups_along(N_UNITS, 8)
    start = grouped_start(obs, group, n_points, start=one, points0=points0, **common)
    assert start.groups == 8
    # only merged rows of points shared by two groups or carrying control
    assert start.rows < obs.unit.size // 2
    grouped = adjust_units(
        obs, N_UNITS, n_points, start=start.transforms, points0=start.points,
        project_points=True, order="given", **common,
    )  # fmt: skip
    assert direct.converged and grouped.converged
    np.testing.assert_allclose(grouped.points, direct.points, rtol=0, atol=SAME_POINT)
    np.testing.assert_allclose(
        grouped.transforms.rotation, direct.transforms.rotation, atol=SAME_ROTATION
    )
    assert grouped.iterations < direct.iterations
    # the start is near each unit's own rotation: far nearer than the identity
    turn = start.transforms.rotation - direct.transforms.rotation
    assert np.max(np.abs(turn)) < 0.1 * np.max(np.abs(one.rotation - direct.transforms.rotation))
    # and the solution is the ground, the chain's drift taken out (to 0.3 m:
    # the plan is carried 1.9 km between plan points; the start was 1.4 rad off)
    used = np.isfinite(direct.points).all(axis=1)
    assert np.max(np.abs(direct.points[used] - ground[used])) < 0.5


@pytest.mark.parametrize("line", [False, True], ids=["control", "control-and-line"])
def test_ground_stage_from_the_groups_gives_the_solution_from_one_similarity(
    monkeypatch, line
):
    """The ground stage of a 100-photo drone strip (99 models, 6 groups)
    starts from its groups; started from J's similarity of the whole strip
    instead, it ends at the same points (to 1e-6 m), rejections and passes;
    with a straight line along the strip too (its points kept in the
    groups, its a, b in their adjustment)."""
    import warnings

    import strip_aerotri as sa
    import strip_aerotri.ground.models as ground_models

    sim = sa.simulate_strip(100, preset="drone", seed=3, line=line)
    strip = sa.form_strip(sim.observations)
    lines = tuple(sa.LineSpec(tuple(ids), weight) for ids, weight in sim.lines) if line else ()
    assert len(lines) == int(line)
    starts = []
    real = ground_models.grouped_start

    def counted(*args, **kwargs):
        starts.append(1)
        return real(*args, **kwargs)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sa.StripAerotriWarning)
        monkeypatch.setattr(ground_models, "grouped_start", counted)
        grouped = ground_models.adjust_models_to_ground(strip, sim.control, sim.crs, lines=lines)
        assert starts == [1]
        monkeypatch.setattr(ground_models, "_GROUPS_FROM", 10**9)
        one = ground_models.adjust_models_to_ground(strip, sim.control, sim.crs, lines=lines)
    assert starts == [1]
    np.testing.assert_allclose(grouped.points, one.points, rtol=0, atol=1e-6)
    np.testing.assert_allclose(grouped.photo_centres, one.photo_centres, rtol=0, atol=1e-6)
    assert [r.point for r in grouped.rejections] == [r.point for r in one.rejections]
    assert grouped.passes == one.passes


def test_groups_that_do_not_converge_are_no_start(monkeypatch):
    """A groups' adjustment that runs out of iterations reports it
    (``converged`` False), and the ground stage then starts every model
    from J's similarity, as when the groups fail: on a 1900-photo drone
    strip (seed 0) the groups did not settle in 50 iterations and the models
    started from them ended at sigma0 8.9 after 50 more (check plan RMSE
    1.9 km); from J's similarity they converge in 10 (sigma0 0.92). Here a
    100-photo strip whose groups get one iteration: the models' first
    adjustment starts from J's similarity."""
    import warnings

    import strip_aerotri as sa
    import strip_aerotri.ground.models as ground_models

    sim = sa.simulate_strip(100, preset="drone", seed=3)
    strip = sa.form_strip(sim.observations)
    real = ground_models.grouped_start
    outcomes = []

    def one_iteration(*args, **kwargs):
        out = real(*args, **dict(kwargs, max_iterations=1))
        outcomes.append(out.converged)
        return out

    first_starts = []
    real_adjust = ground_models._adjust

    def spied(p, keep_rows, use_xy, use_z, conditions, passes, starts, points0):
        first_starts.append((starts, p.start_units))
        return real_adjust(p, keep_rows, use_xy, use_z, conditions, passes, starts, points0)

    monkeypatch.setattr(ground_models, "grouped_start", one_iteration)
    monkeypatch.setattr(ground_models, "_adjust", spied)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sa.StripAerotriWarning)
        ground_models.adjust_models_to_ground(strip, sim.control, sim.crs)
    assert outcomes == [False]
    starts, similarity = first_starts[0]
    assert starts is similarity
