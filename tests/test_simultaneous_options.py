"""adjust_units' options for long strips: weights that turn with their units,
control that follows the adjustment, points projected after each step.

Each is checked against an adjustment that does not need it: the same
problem posed with the weights at the solution's rotations, the control
given at its final value, or no projection."""

from __future__ import annotations

import functools
import threading
import time

import numpy as np
import pytest

from strip_aerotri.geometry.rotation import matrix_from_rotvec
from strip_aerotri.geometry.simultaneous import UnitObservations, UnitTransforms, adjust_units

N_UNITS = 6


def _problem(seed: int):
    """Units along X, 8 points each, neighbours sharing 3.  Returns the rows
    (unit, point, unit coordinates), their weights in their units (the
    information of the unit coordinates), the true rotations, the points and
    their count."""
    rng = np.random.default_rng(seed)
    n_points = 3 + N_UNITS * 5
    truth = np.column_stack(
        [
            np.linspace(0.0, 100.0 * N_UNITS, n_points) + rng.normal(0, 5, n_points),
            rng.uniform(-40.0, 40.0, n_points),
            rng.normal(0.0, 4.0, n_points),
        ]
    )
    unit, point, xyz, w_local = [], [], [], []
    rotations = []
    for u in range(N_UNITS):
        pts = np.arange(5 * u, 5 * u + 8)
        rot = matrix_from_rotvec(rng.normal(0.0, 0.05, 3))
        rotations.append(rot)
        local = (truth[pts] - rng.normal(0.0, 10.0, 3)) @ rot  # X = t + R x
        # weak along the unit's own z (a model point along its rays)
        sig = np.array([0.02, 0.03, 0.2])
        for k, p in enumerate(pts):
            a = rng.normal(size=(3, 3)) * 0.5 + np.diag(1.0 / sig)
            unit.append(u)
            point.append(p)
            xyz.append(local[k] + rng.normal(0.0, 0.01, 3))
            w_local.append(a.T @ a)
    return (
        np.array(unit), np.array(point), np.array(xyz), np.array(w_local),
        np.array(rotations), truth, n_points,
    )  # fmt: skip


def _in_work(unit, w_local, rotations):
    """The rows' weights in the work frame for units at ``rotations``: R W Rᵀ."""
    r = rotations[unit]
    return r @ w_local @ np.swapaxes(r, 1, 2)


def _start(rotations, truth, obs):
    """Similarities with the given rotations, unit scale, translations that
    put each unit's centroid on its points' centroid."""
    trans = np.array(
        [truth[obs.point[obs.unit == u]].mean(axis=0) for u in range(N_UNITS)]
    )
    centroid = np.array([obs.xyz[obs.unit == u].mean(axis=0) for u in range(N_UNITS)])
    return UnitTransforms(np.ones(N_UNITS), rotations.copy(), trans, centroid)


CONTROL = np.array([0, 2, 14, 18, 30, 32])


def _control(truth):
    xyz = truth[CONTROL] + 0.01
    xyz[2, 2] = np.nan
    return xyz, np.array([[0.03, 0.03, 0.05]] * CONTROL.size)


def test_turning_weights_equal_the_weights_at_the_solution():
    """Weights given at a start turned 0.5 rad off and turning with their
    units reach the solution of the weights posed at the solution's own
    rotations (those fixed in the work frame); held in the work frame
    instead they give another, worse-weighted solution."""
    unit, point, xyz, w_local, rotations, truth, n_points = _problem(3)
    off = np.array([matrix_from_rotvec([0.5, 0.1, 0.0]) @ r for r in rotations])
    obs0 = UnitObservations(unit, point, xyz, _in_work(unit, w_local, off))
    control_xyz, control_sigma = _control(truth)
    kwargs = {"control_point": CONTROL, "control_xyz": control_xyz, "control_sigma": control_sigma}
    turning = adjust_units(
        obs0, N_UNITS, n_points, start=_start(off, truth, obs0), points0=truth,
        weight_rotation=off, **kwargs,
    )  # fmt: skip
    assert turning.converged
    # the same problem posed with the weights at the solution's rotations
    solved = turning.transforms.rotation
    obs1 = UnitObservations(unit, point, xyz, _in_work(unit, w_local, solved))
    fixed = adjust_units(
        obs1, N_UNITS, n_points, start=turning.transforms, points0=turning.points, **kwargs
    )
    np.testing.assert_allclose(turning.points, fixed.points, rtol=0, atol=1e-5)
    assert turning.sigma0 == pytest.approx(fixed.sigma0, rel=1e-4)
    held = adjust_units(
        obs0, N_UNITS, n_points, start=_start(off, truth, obs0), points0=truth, **kwargs
    )
    assert np.max(np.abs(held.points - fixed.points)) > 1e-3


def test_control_that_follows_reaches_the_control_it_settles_on():
    """A control update that moves a height target by a function of the
    adjusted point (as a curved work frame does) ends where the adjustment
    given the settled target directly ends; the callback is told when the
    adjustment met its tolerance."""
    unit, point, xyz, w_local, rotations, truth, n_points = _problem(4)
    obs = UnitObservations(unit, point, xyz, _in_work(unit, w_local, rotations))
    control_xyz, control_sigma = _control(truth)
    control_xyz[0, :2] = np.nan  # a height point: its height depends on where it is
    base = control_xyz.copy()

    def target_at(points):
        out = base.copy()
        out[0, 2] = base[0, 2] - 1e-2 * points[CONTROL[0], 0]  # "curvature"
        return out

    class Follow:
        def __init__(self) -> None:
            self.current = target_at(truth)
            self.calls: list[bool] = []

        def __call__(self, points, settled):
            self.calls.append(settled)
            new = target_at(points)
            if abs(new[0, 2] - self.current[0, 2]) < 1e-9:
                return None
            self.current = new
            return new

    follow = Follow()
    start = _start(rotations, truth, obs)
    kwargs = {"control_point": CONTROL, "control_sigma": control_sigma}
    followed = adjust_units(
        obs, N_UNITS, n_points, start=start, points0=truth, control_xyz=follow.current,
        control_update=follow, **kwargs,
    )  # fmt: skip
    assert followed.converged and len(follow.calls) >= 2
    # the target moved after the start (the point's X moved): it was followed
    assert follow.current[0, 2] != target_at(truth)[0, 2]
    settled = target_at(followed.points)
    direct = adjust_units(
        obs, N_UNITS, n_points, start=start, points0=truth, control_xyz=settled, **kwargs
    )
    np.testing.assert_allclose(followed.points, direct.points, rtol=0, atol=1e-7)
    # the statistics come from the factor of the last step (formed a step
    # before the state settled): w to 1e-5
    np.testing.assert_allclose(followed.control_w, direct.control_w, rtol=0, atol=1e-5)


def test_projected_points_change_the_path_not_the_solution():
    """From units turned 0.8 rad off, with the points projected the solution
    is the one without, in fewer iterations."""
    unit, point, xyz, w_local, rotations, truth, n_points = _problem(5)
    obs = UnitObservations(unit, point, xyz, _in_work(unit, w_local, rotations))
    control_xyz, control_sigma = _control(truth)
    off = np.array([matrix_from_rotvec([0.8, 0.0, 0.2]) @ r for r in rotations])
    kwargs = {
        "start": _start(off, truth, obs), "points0": truth, "control_point": CONTROL,
        "control_xyz": control_xyz, "control_sigma": control_sigma,
    }  # fmt: skip
    plain = adjust_units(obs, N_UNITS, n_points, **kwargs)
    projected = adjust_units(obs, N_UNITS, n_points, project_points=True, **kwargs)
    assert plain.converged and projected.converged
    np.testing.assert_allclose(projected.points, plain.points, rtol=0, atol=1e-7)
    np.testing.assert_allclose(projected.control_w, plain.control_w, rtol=1e-6, atol=1e-9)
    assert projected.iterations <= plain.iterations


def test_weight_lead_extrapolates_a_geometric_series_of_turns():
    """Two steps turning the units the same way, the second half the first:
    the weights are turned ahead by the rest of the series (once as much as
    the last step, rho / (1 - rho) = 1), then two plain steps again; steps
    that disagree are not led."""
    from strip_aerotri.geometry.units import WeightLead as _WeightLead

    rng = np.random.default_rng(8)
    rotation = matrix_from_rotvec(rng.normal(0.0, 0.3, (5, 3)))
    step = rng.normal(0.0, 1e-3, (5, 3))
    lead = _WeightLead()
    lead.record(step)
    assert lead.ahead(rotation) is rotation  # one step: nothing to measure
    lead.record(0.5 * step)
    ahead = lead.ahead(rotation)
    np.testing.assert_allclose(ahead, matrix_from_rotvec(0.5 * step) @ rotation, atol=1e-15)
    # just led: the next two steps are plain
    lead.record(0.25 * step)
    assert lead.ahead(rotation) is rotation
    lead.record(0.125 * step)
    assert lead.ahead(rotation) is not rotation
    # turns that disagree (cosine below 0.9), or grow, are not led
    lead = _WeightLead()
    lead.record(step)
    lead.record(rng.normal(0.0, 1e-3, (5, 3)))
    assert lead.ahead(rotation) is rotation
    lead = _WeightLead()
    lead.record(step)
    lead.record(1.5 * step)
    assert lead.ahead(rotation) is rotation


@functools.cache
def _long_problem():
    """A 300-photo drone strip's models as the ground stage poses them
    (the rows, the control and the start of the groups' adjustment)."""
    import warnings

    import strip_aerotri as sa
    import strip_aerotri.ground.models as ground_models

    sim = sa.simulate_strip(300, preset="drone", seed=5)
    strip = sa.form_strip(sim.observations)
    posed = {}
    real = ground_models.adjust_units

    def capture(*args, **kwargs):
        posed.setdefault("call", (args, kwargs))
        return real(*args, **kwargs)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sa.StripAerotriWarning)
        ground_models.adjust_units = capture
        try:
            ground_models.adjust_models_to_ground(strip, sim.control, sim.crs)
        finally:
            ground_models.adjust_units = real
    return posed["call"]


def _posed():
    """The 300-photo strip's models posed as adjust_units poses them: the
    problem, its start state (weights turned to it) and the call's keywords."""
    from strip_aerotri.geometry import simultaneous as sim_module

    args, kwargs = _long_problem()
    obs, n_units, n_points = args
    prob = sim_module._Problem(
        obs, n_units, n_points, kwargs["control_point"], np.asarray(kwargs["control_xyz"]),
        np.asarray(kwargs["control_sigma"]), (), None, "given", kwargs["weight_rotation"],
    )  # fmt: skip
    st = sim_module._start_state(prob, kwargs["start"], kwargs["points0"])
    prob.turn_weights(st.rotation)
    return prob, st, kwargs


def test_gradients_and_chord_step_are_the_engines_own():
    """At one state, the right-hand side the chord steps form
    (_gradients) is the one the engine forms with the full normal
    equations, and the chord step on that state's own factor is its full
    step (to rounding)."""
    from strip_aerotri.geometry import simultaneous as sim_module

    prob, st, _ = _posed()
    st = sim_module._projected(prob, st)
    formed = prob.structure.form(*sim_module._engine_rows(prob, st))
    g_unit, g_point = sim_module._gradients(prob, st)
    normals = formed._normals
    scale = np.max(np.abs(normals.g_unit))
    np.testing.assert_allclose(g_unit, normals.g_unit, rtol=0, atol=1e-12 * scale)
    scale = np.max(np.abs(normals.g_point))
    np.testing.assert_allclose(g_point, normals.g_point, rtol=0, atol=1e-12 * scale)
    sol = formed.solve()
    du, dp = sol.chord_step(g_unit, g_point)
    for chord, full in ((du, sol.unit_step), (dp, sol.point_step)):
        np.testing.assert_allclose(chord, full, rtol=0, atol=1e-9 * np.abs(full).max())


def _counted_runs(monkeypatch, *rules):
    """``adjust_units`` on the 300-photo strip's models once per rule
    (``_CHORD_FROM``, ``_CHORD_BELOW_MOVE``): the result and its count of
    formed normal equations, per rule."""
    from strip_aerotri.geometry import simultaneous as sim_module

    args, kwargs = _long_problem()
    solves = []
    real_solve = sim_module._solve

    def counted(prob, st):
        solves.append(prob.n_units)
        return real_solve(prob, st)

    monkeypatch.setattr(sim_module, "_solve", counted)
    out = []
    for chord_from, below_move in rules:
        monkeypatch.setattr(sim_module, "_CHORD_FROM", chord_from)
        monkeypatch.setattr(sim_module, "_CHORD_BELOW_MOVE", below_move)
        solves.clear()
        out.append((sim_module.adjust_units(*args, **kwargs), len(solves)))
    return out


def test_chord_steps_change_the_cost_not_the_solution(monkeypatch):
    """The ground stage's adjustment of a 300-photo strip's models: with chord
    steps once a full step is below 1e3 times the tolerance it forms the
    normal equations fewer times and ends where full steps all the way end
    (to 1e-8 m), its statistics (from the last full factor, 1e-7 of the
    strip from the solution) within 1e-6 of theirs."""
    from strip_aerotri.geometry import simultaneous as sim_module

    (with_chords, n_chorded), (full, n_full) = _counted_runs(
        monkeypatch, (sim_module._CHORD_FROM, 0.0), (0.0, 0.0)
    )
    assert with_chords.converged and full.converged
    assert n_chorded < n_full
    np.testing.assert_allclose(with_chords.points, full.points, rtol=0, atol=1e-8)
    np.testing.assert_allclose(
        with_chords.control_redundancy, full.control_redundancy, rtol=0, atol=1e-6
    )
    np.testing.assert_allclose(with_chords.control_w, full.control_w, rtol=0, atol=1e-5)
    finite = np.isfinite(full.row_statistic)
    np.testing.assert_allclose(
        with_chords.row_statistic[finite], full.row_statistic[finite], rtol=1e-6
    )


def test_chords_from_a_small_move_spare_a_factor_and_keep_the_solution(monkeypatch):
    """The default rule also starts the chords after a full step below
    ``_CHORD_BELOW_MOVE`` (relative): one formation fewer than the rule of
    the tolerance alone, the same solution as full steps all the way (to
    1e-8 m).  The statistics come from the factor of a state about 5e-6 (of
    the strip) from the solution, instead of 1e-7: the redundancy numbers
    within 1e-6 of the full steps', w and the rows' statistics within 1e-4
    relative (measured: 9e-6 and 2.7e-5; a model point's weight is weak
    along its rays, so a turn of 5e-6 rad changes it by more than that
    share)."""
    from strip_aerotri.geometry import simultaneous as sim_module

    (fast, n_fast), (tolerance_only, n_tolerance), (full, _) = _counted_runs(
        monkeypatch,
        (sim_module._CHORD_FROM, sim_module._CHORD_BELOW_MOVE),
        (sim_module._CHORD_FROM, 0.0),
        (0.0, 0.0),
    )
    assert fast.converged and full.converged
    assert n_fast == n_tolerance - 1
    np.testing.assert_allclose(fast.points, full.points, rtol=0, atol=1e-8)
    np.testing.assert_allclose(fast.control_redundancy, full.control_redundancy, rtol=0, atol=1e-6)
    finite = np.isfinite(full.control_w)
    np.testing.assert_allclose(fast.control_w[finite], full.control_w[finite], rtol=1e-4)
    finite = np.isfinite(full.row_statistic)
    np.testing.assert_allclose(fast.row_statistic[finite], full.row_statistic[finite], rtol=1e-4)


def test_the_rows_work_on_two_threads_gives_the_result_of_one(monkeypatch):
    """The work row by row (weights turned, design, residuals, projection,
    leverage) in blocks over two threads: the worker takes blocks, and the
    result is that of one thread to the last bit."""
    from strip_aerotri import _threads
    from strip_aerotri.geometry import _normal_entries
    from strip_aerotri.geometry import simultaneous as sim_module

    args, kwargs = _long_problem()
    monkeypatch.setenv(_threads.WORKERS_VARIABLE, "1")
    one = sim_module.adjust_units(*args, **kwargs)
    monkeypatch.setattr(_threads, "_usable_cores", lambda: 2)
    monkeypatch.setattr(_threads, "MIN_PARALLEL_SIZE", 0)
    monkeypatch.setattr(_normal_entries, "BLOCK", 512)
    monkeypatch.setenv(_threads.WORKERS_VARIABLE, "2")
    names: set[str] = set()
    real = sim_module._by_rows

    def by_rows(n_rows, block):
        def recorded(rows):
            names.add(threading.current_thread().name)
            time.sleep(0.0002)  # blocks long enough for the worker to take some
            return block(rows)

        return real(n_rows, recorded)

    monkeypatch.setattr(sim_module, "_by_rows", by_rows)
    two = sim_module.adjust_units(*args, **kwargs)
    assert any(name.startswith("strip_aerotri-worker") for name in names)
    for name in ("points", "residuals", "row_statistic", "control_w", "control_redundancy"):
        np.testing.assert_array_equal(getattr(two, name), getattr(one, name), err_msg=name)
    np.testing.assert_array_equal(two.transforms.rotation, one.transforms.rotation)
    assert two.iterations == one.iterations and two.sigma0 == one.sigma0


def test_rows_whitening_is_the_cholesky_factor_and_refuses_weights_not_positive_definite():
    """The rows' whitening in closed form is LAPACK's Cholesky factor
    transposed; a weight that is not positive definite (a zero pivot, a
    negative one, NaN) is refused."""
    from strip_aerotri.geometry import simultaneous as sim_module

    rng = np.random.default_rng(11)
    a = rng.normal(size=(50, 3, 3))
    weight = a @ np.swapaxes(a, 1, 2) + 1e-3 * np.eye(3)
    got = sim_module._rows_whitening(weight)
    np.testing.assert_allclose(got, np.swapaxes(np.linalg.cholesky(weight), 1, 2), atol=1e-12)
    np.testing.assert_allclose(np.swapaxes(got, 1, 2) @ got, weight, atol=1e-12)
    for bad in (np.diag([1.0, 0.0, 1.0]), np.diag([1.0, 1.0, -1.0]), np.full((3, 3), np.nan)):
        with pytest.raises(ValueError, match="positive definite"):
            sim_module._rows_whitening(np.concatenate([weight, bad[None]]))
    # the whitening turned (upper triangular times any matrix), entry by entry
    from strip_aerotri.geometry._row_kernels import upper_entries, upper_times

    turn = rng.normal(size=(50, 3, 3))
    np.testing.assert_allclose(
        upper_times(upper_entries(got), np.ascontiguousarray(turn.reshape(-1, 9).T)),
        got @ turn, rtol=0, atol=1e-13 * np.abs(got @ turn).max(),
    )  # fmt: skip


def test_rows_gram_and_the_cost_of_a_state():
    """``L Lᵀ`` of the rows' whitening written out equals the batched product;
    the rows' share of the cost is kept per state and whitening: a control
    that moves changes the cost by its own share alone, a turned whitening
    recomputes it."""
    from strip_aerotri.geometry import simultaneous as sim_module

    rng = np.random.default_rng(5)
    lt = rng.normal(size=(30, 3, 3))
    np.testing.assert_allclose(
        sim_module._gram(lt), np.swapaxes(lt, 1, 2) @ lt, rtol=0, atol=1e-13
    )
    prob, st, kwargs = _posed()
    first = sim_module._cost(prob, st)
    assert st.rows_cost is not None and st.rows_cost[0] is prob.whiten
    fresh = sim_module._start_state(prob, kwargs["start"], kwargs["points0"])
    assert sim_module._cost(prob, fresh) == first
    moved = np.where(prob.control_given, prob.control_xyz + 0.01, np.nan)
    prob.set_control(moved)
    recomputed = sim_module._start_state(prob, kwargs["start"], kwargs["points0"])
    assert sim_module._cost(prob, st) == sim_module._cost(prob, recomputed)
    assert sim_module._cost(prob, st) != first
    turned = st.rotation @ matrix_from_rotvec(np.array([0.0, 0.0, 1e-3]))
    prob.turn_weights(turned)
    before = st.rows_cost[1]
    sim_module._cost(prob, st)
    assert st.rows_cost[0] is prob.whiten and st.rows_cost[1] != before
