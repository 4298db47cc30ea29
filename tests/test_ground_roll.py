"""The ground stage keeps the roll of a strongly bent strip in the similarity.

A strip whose chain has bent it by far more than its width gets from the
least-squares similarity a roll (turn about the strip's axis) set by the
bend, not by its cross-section.  The polynomials take that roll as a shear of
Z across the strip, which cannot move the points' Y with their height, so the
relief carries the roll into plan.  The ground stage turns the roll the
polynomial holds back into the similarity (ground._cross_slope,
ground._turned_about_x)."""

from __future__ import annotations

import dataclasses
import warnings
from functools import cache

import numpy as np
import pytest

import strip_aerotri as sa
import strip_aerotri.ground.passes as ground
from strip_aerotri.geometry.deformation import fit_deformation
from strip_aerotri.geometry.similarity import SimilarityTransform
from strip_aerotri.ground.polynomials import GroundOptions, adjust_to_ground


@cache
def _simulated():
    return sa.simulate_strip(12, seed=1, image_noise_mm=0.0, control_noise_m=0.0)


def _bent(strip: sa.StripModel, k: float) -> sa.StripModel:
    """The strip model sheared along a parabola in Y and in Z of height
    k * L / 4 at its ends (L its length)."""
    x = strip.points[:, 0]
    x0 = float(np.nanmean(x))
    length = float(np.nanmax(x) - np.nanmin(x))

    def bend(p):
        q = p.copy()
        q[:, 1:] += (k * length * ((p[:, 0] - x0) / length) ** 2)[:, None]
        return q

    return dataclasses.replace(
        strip,
        points=bend(strip.points),
        centres=bend(strip.centres),
        model_points=bend(strip.model_points),
    )


def _plan_rmse(strip, sim) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = adjust_to_ground(
            strip,
            sim.control,
            sim.crs,
            options=GroundOptions(polynomial=3),
            blunders=sa.BlunderOptions(action="off"),
        )
    err = res.points - sim.truth.points_crs
    return float(np.sqrt(np.nanmean(np.sum(err[:, :2] ** 2, axis=1))))


def test_a_strongly_bent_strip_keeps_its_roll_in_the_similarity(monkeypatch):
    # Bent by 0.05 of its length (about 600 m over a strip 2.3 km wide): without
    # the turn the relief carries the roll into plan, 1.3 m; with it 0.09 m
    # (the rest is the shear, which is not a polynomial of X and Y exactly).
    sim = _simulated()
    strip = _bent(sa.form_strip(sim.observations), 0.2)
    with_turn = _plan_rmse(strip, sim)
    monkeypatch.setattr(ground, "_ROLL_TOLERANCE", np.inf)
    without = _plan_rmse(strip, sim)
    assert with_turn < 0.1
    assert without > 10 * with_turn


def test_an_unbent_strip_is_not_turned(monkeypatch):
    # The roll left to the polynomial of an ordinary strip is noise: the turn
    # would move no point by a tenth of its expected sigma and is not made.
    sim = sa.simulate_strip(12, seed=3)
    strip = sa.form_strip(sim.observations)
    base = _plan_rmse(strip, sim)
    monkeypatch.setattr(ground, "_ROLL_TOLERANCE", np.inf)
    assert _plan_rmse(strip, sim) == base


def test_turned_about_x_keeps_the_axis_and_turns_about_it():
    rng = np.random.default_rng(0)
    t = SimilarityTransform(2.0, sa.matrix_from_rotvec([0.1, -0.2, 0.3]), np.array([1.0, 2, 3]))
    axis_point = np.array([5.0, -1.0, 2.0])
    turned = ground._turned_about_x(t, 0.25, axis_point)
    p = rng.normal(size=(10, 3))
    d = t.apply(p) - axis_point
    c, s = np.cos(0.25), np.sin(0.25)
    expected = axis_point + np.column_stack(
        [d[:, 0], c * d[:, 1] - s * d[:, 2], s * d[:, 1] + c * d[:, 2]]
    )
    np.testing.assert_allclose(turned.apply(p), expected, rtol=0, atol=1e-12)
    assert turned.scale == t.scale


@pytest.mark.parametrize("sections", [1, 4])
def test_cross_slope_is_the_tilt_the_polynomial_holds(sections):
    # w_Z = 0.003 Y + bending along X: the mean slope across is 0.003.
    rng = np.random.default_rng(1)
    xyz = np.column_stack(
        [rng.uniform(0, 8000, 300), rng.uniform(-900, 900, 300), rng.normal(0, 30, 300)]
    )
    target = xyz.copy()
    target[:, 2] -= 0.003 * xyz[:, 1] + 2e-7 * (xyz[:, 0] - 4000) ** 2
    use = np.ones(300, dtype=bool)
    d = fit_deformation(xyz, target, use_xy=use, use_z=use, kind=3, sections=sections)
    assert ground._cross_slope(d, xyz) == pytest.approx(0.003, rel=1e-9)
