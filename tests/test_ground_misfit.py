"""A ground fit that cannot follow the strip is warned about.

The control tests scale their statistics by a robust variance factor (the
expected sigmas leave out the error the chain accumulates), so a polynomial
far too stiff for the strip's bend rejects nothing and would otherwise pass
in silence: one cubic over bench_strip's 5000-photo strip leaves 333 m
(plan) and 516 m (height) at the control, sigma0 5521."""

from __future__ import annotations

import dataclasses
import warnings
from functools import cache

import numpy as np
import pytest

import strip_aerotri as sa
from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.ground.polynomials import GroundOptions, adjust_to_ground
from strip_aerotri.observations import ControlPoints, ControlType


@cache
def _wavy_strip():
    """30 photos, noise-free, the model's heights bent by 2.5 sine waves of
    amplitude 1e-3 of its length (a cubic cannot follow them, 7 sections
    can), full control on both edges at 15 stations."""
    sim = sa.simulate_strip(30, seed=1, image_noise_mm=0.0, control_noise_m=0.0)
    strip = sa.form_strip(sim.observations)
    p = strip.points
    ok = np.flatnonzero(np.isfinite(p[:, 0]))
    edges = np.linspace(p[ok, 0].min(), p[ok, 0].max(), 16)[1:-1]
    station = np.digitize(p[ok, 0], edges)
    chosen = []
    for s in range(15):
        here = ok[station == s]
        chosen += [here[np.argmin(p[here, 1])], here[np.argmax(p[here, 1])]]
    chosen = np.array(chosen)
    control = ControlPoints(
        point_ids=tuple(sim.observations.point_ids[i] for i in chosen),
        xyz=sim.truth.points_crs[chosen],
        kind=tuple(ControlType.FULL for _ in chosen),
        sigma_xy=np.full(chosen.size, 0.02),
        sigma_h=np.full(chosen.size, 0.02),
        source_line=np.zeros(chosen.size, dtype=np.intp),
    )
    x0 = float(np.nanmin(p[:, 0]))
    length = float(np.nanmax(p[:, 0])) - x0

    def bend(q):
        q = q.copy()
        q[:, 2] += 1e-3 * length * np.sin(2 * np.pi * 2.5 * (q[:, 0] - x0) / length)
        return q

    bent = dataclasses.replace(
        strip,
        points=bend(strip.points),
        centres=bend(strip.centres),
        model_points=bend(strip.model_points),
    )
    return sim, bent, control


def _fit(sections: int, polynomial: int = 3):
    sim, strip, control = _wavy_strip()
    return adjust_to_ground(
        strip,
        control,
        sim.crs,
        options=GroundOptions(polynomial=polynomial, sections=sections),
        blunders=sa.BlunderOptions(action="off"),
    )


def test_one_cubic_over_a_wavy_strip_is_warned_about():
    with pytest.warns(
        StripAerotriWarning,
        match=r"polynomial type 3 leaves the control 1\d\d times its expected error .*"
        r"use \[adjustment\] sections",
    ):
        result = _fit(1)
    assert result.deformation.sigma0 > 100


def test_sections_that_follow_the_strip_are_not_warned_about():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = _fit(7)
    assert result.deformation.sigma0 < 30


def test_the_similarity_alone_is_told_to_take_a_polynomial():
    with pytest.warns(
        StripAerotriWarning,
        match=r"the similarity transformation alone leaves the control \d+ times .*"
        r"use a deformation polynomial",
    ):
        _fit(1, polynomial=0)
