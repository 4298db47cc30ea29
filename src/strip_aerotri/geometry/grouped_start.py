"""Start values of an adjustment of units from the same adjustment on groups of units.

A long strip's models chained into one strip frame agree with each other
where they overlap; what separates the strip frame from the ground is a
rotation, scale and shift that drift slowly along the strip (the chain's
accumulated errors).  One similarity of the whole strip (J's) is then far
from many models' own similarity: on a 21 km strip with height control all
along and plan control at its ends it is rolled 1.5 rad about the strip's
axis (the similarity follows the chain's bend, not the cross-section), and
Gauss-Newton spends most of its iterations turning the models back.

Here consecutive units are taken together in groups (a few dozen models),
each group one similarity: the adjustment of :func:`adjust_units` on the
groups, with every point's determinations in a group merged into one
(their weighted mean, with the sum of their weights) and only the points
that tie two groups or carry control or a line kept: a tenth of the rows
with groups of 16 models (8 339 of 84 824 on a 1000-photo drone strip).
It converges from the one similarity in 4-10 iterations (4 at 1000
photos, 10 at 10 000; the units took 5 and 24), at a small part of the
cost; each unit then starts at its group's similarity, off only by the
drift within a group, and the adjustment of the units needs 3-9
iterations.  It is a start: the solution is that of the units.

The units of a group must have their coordinates in one frame (the models
of a chained strip do); a group never spans a break of the chain (the
caller's ``group``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Literal, NamedTuple

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..options import DEFAULT_MAX_ITERATIONS
from ._normal_assembly import sum_into
from .simultaneous import LineCondition, adjust_units
from .units import UnitObservations, UnitTransforms

__all__ = ["GroupedStart", "grouped_start", "groups_along"]


class GroupedStart(NamedTuple):
    """Start values of the units from their groups' adjustment.

    Attributes
    ----------
    transforms : UnitTransforms
        Every unit at its group's similarity (U units).
    points : ndarray, shape (P, 3)
        The groups' adjusted points, the given start values elsewhere.
    iterations : int
        Gauss-Newton iterations of the groups' adjustment.
    groups : int
        Number of groups.
    rows : int
        Rows of the groups' adjustment (merged determinations).
    converged : bool
        Whether the groups' adjustment converged (a start from groups that
        did not settle is no start).
    """

    transforms: UnitTransforms
    points: FloatArray
    iterations: int
    groups: int
    rows: int
    converged: bool = True


def groups_along(n_units: int, size: int, breaks: Sequence[int] | IntArray = ()) -> IntArray:
    """The group of each of ``n_units`` units numbered along a strip: runs of
    ``size`` consecutive units, starting again at every break (a unit the
    chain did not carry the scale into); the rest of a run, fewer than
    ``size`` units, joins its last group."""
    if size < 1:
        raise ValueError(f"Expected a group size of at least 1, got {size}")
    unit = np.arange(n_units)
    edges = np.unique(np.concatenate([[0], np.asarray(breaks, dtype=np.intp), [n_units]]))
    run = np.searchsorted(edges, unit, side="right") - 1
    local = unit - edges[run]
    length = (edges[1:] - edges[:-1])[run]
    # the last, short group of a run joins the one before it
    full = np.maximum(length // size, 1)
    place = np.minimum(local // size, full - 1)
    key = run * (n_units + 1) + place
    _, group = np.unique(key, return_inverse=True)
    out: IntArray = group.astype(np.intp)
    return out


def _merged_rows(
    obs: UnitObservations,
    unit_group: IntArray,
    n_points: int,
    keep_points: BoolArray,
    weight_turn: FloatArray | None,
) -> UnitObservations:
    """Every point's determinations in a group merged into one row (the
    weighted mean, with the summed weight), for the points that lie in two
    groups or more or are in ``keep_points``; ``weight_turn`` (U, 3, 3)
    turns each unit's weights to its group's reference rotation."""
    group = unit_group[obs.unit]
    key = group * n_points + obs.point
    in_groups = np.bincount(np.unique(key) % n_points, minlength=n_points)
    wanted = (in_groups >= 2) | keep_points
    rows = np.flatnonzero(wanted[obs.point])
    key = key[rows]
    uniq, inverse = np.unique(key, return_inverse=True)
    weight = obs.weight[rows]
    if weight_turn is not None:
        turn = weight_turn[obs.unit[rows]]
        weight = turn @ weight @ np.swapaxes(turn, 1, 2)
    total = sum_into(inverse, weight, uniq.size)
    moment = sum_into(inverse, np.einsum("nij,nj->ni", weight, obs.xyz[rows]), uniq.size)
    xyz = np.asarray(np.linalg.solve(total, moment[:, :, None])[:, :, 0], dtype=np.float64)
    return UnitObservations(
        (uniq // n_points).astype(np.intp), (uniq % n_points).astype(np.intp), xyz, total
    )


def grouped_start(
    observations: UnitObservations,
    group: IntArray,
    n_points: int,
    *,
    start: UnitTransforms,
    points0: FloatArray,
    control_point: IntArray,
    control_xyz: FloatArray,
    control_sigma: FloatArray,
    lines: Sequence[LineCondition] = (),
    weight_rotation: FloatArray | None = None,
    control_update: Callable[[FloatArray, bool], FloatArray | None] | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    tolerance: float = 1e-6,
    order: Literal["auto", "given", "rcm"] = "given",
) -> GroupedStart:
    """Start values of the units of an :func:`adjust_units` problem from
    the same adjustment on groups of units (module docstring).

    Parameters
    ----------
    observations : UnitObservations
        The rows of the units' adjustment; the units of a group in one frame.
    group : ndarray of int, shape (U,)
        The group of every unit, 0 .. G - 1 (:func:`groups_along`).
    n_points : int
    start : UnitTransforms
        The units' start (each group starts at its first unit's).
    points0 : ndarray, shape (P, 3)
        Start values of the points, work frame.
    control_point, control_xyz, control_sigma, lines
        As :func:`adjust_units` (kept whatever groups their points are in).
    weight_rotation : ndarray, shape (U, 3, 3), optional
        As :func:`adjust_units`: the rotations the rows' weights are given
        at; a group's weights are given at its first unit's.
    control_update : callable, optional
        As :func:`adjust_units` (the plan/height passes of the control).
    max_iterations, tolerance, order
        Of the groups' adjustment (a start: to 1e-6 it ends 3e-8 m from
        where 1e-8 ends the units' adjustment on a 1000-photo strip, one
        iteration of the groups sooner).

    Returns
    -------
    GroupedStart

    Raises
    ------
    GeometryError, ConvergenceError
        As :func:`adjust_units` on the groups.
    """
    group = np.asarray(group, dtype=np.intp)
    n_groups = int(group.max()) + 1 if group.size else 0
    _, first_unit = np.unique(group, return_index=True)  # the first unit of each group
    if first_unit.size != n_groups:
        raise ValueError(f"Expected groups numbered 0..{n_groups - 1}, each with a unit")
    keep = np.zeros(n_points, dtype=bool)
    keep[np.asarray(control_point, dtype=np.intp)] = True
    for line in lines:
        keep[line.point] = True
    turn = None
    group_rotation = None
    if weight_rotation is not None:
        group_rotation = weight_rotation[first_unit]
        reference = group_rotation[group]
        if not np.array_equal(reference, weight_rotation):
            turn = reference @ np.swapaxes(weight_rotation, 1, 2)
    rows = _merged_rows(observations, group, n_points, keep, turn)
    result = adjust_units(
        rows,
        n_groups,
        n_points,
        start=UnitTransforms(
            start.scale[first_unit],
            start.rotation[first_unit],
            start.translation[first_unit],
            start.centroid[first_unit],
        ),
        points0=points0,
        control_point=control_point,
        control_xyz=control_xyz,
        control_sigma=control_sigma,
        lines=lines,
        max_iterations=max_iterations,
        tolerance=tolerance,
        statistics=False,
        order=order,
        weight_rotation=group_rotation,
        control_update=control_update,
        project_points=True,
    )
    t = result.transforms
    points = np.where(np.isfinite(result.points), result.points, points0)
    return GroupedStart(
        UnitTransforms(t.scale[group], t.rotation[group], t.translation[group], t.centroid[group]),
        points,
        result.iterations,
        n_groups,
        int(rows.unit.shape[0]),
        bool(result.converged),
    )
