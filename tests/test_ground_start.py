"""ground.polynomials.similarity_start: J's untested similarity as the start of
the models' ground stage, the same result as adjust_to_ground's except the
points in the CRS, given at the control points only, and its passes, which
end at a centimetre."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import strip_aerotri as sa
import strip_aerotri.ground.passes as passes
import strip_aerotri.ground.polynomials as polynomials
from strip_aerotri.geodesy import GroundCRS
from strip_aerotri.ground.polynomials import adjust_to_ground, similarity_start
from strip_aerotri.options import BlunderAction, BlunderOptions, GroundOptions


def test_similarity_start_is_adjust_to_ground_with_the_points_at_the_control(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # with the ground stage's own pass tolerance, the same to the bit
    monkeypatch.setattr(polynomials, "_START_PASS_TOLERANCE_M", passes._PASS_TOLERANCE_M)
    sim = sa.simulate_strip(20, preset="drone", seed=3)
    strip = sa.form_strip(sim.observations)
    crs = GroundCRS.from_user_input(sim.crs)
    want = adjust_to_ground(
        strip,
        sim.control,
        crs,
        options=GroundOptions(polynomial=0, max_iterations=30),
        blunders=BlunderOptions(action=BlunderAction.OFF),
    )
    got = similarity_start(strip, sim.control, crs, route=None, max_iterations=30)
    ids = np.asarray(strip.observations.point_ids)
    at = np.isin(ids, np.asarray(sim.control.point_ids)[want.control_index])
    assert at.sum() == want.control_index.size
    np.testing.assert_array_equal(got.points[at], want.points[at])
    assert np.isnan(got.points[~at]).all()
    for field in dataclasses.fields(want):
        if field.name == "points":
            continue
        a, b = getattr(want, field.name), getattr(got, field.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=field.name)


def test_the_start_passes_stop_at_a_centimetre() -> None:
    # the default start, in fewer passes: its points at the control within a
    # centimetre of the converged passes' (measured 7e-9 m: the guesses of
    # the last passes move the work frame, hardly the fit)
    sim = sa.simulate_strip(300, preset="drone", seed=5)
    strip = sa.form_strip(sim.observations)
    crs = GroundCRS.from_user_input(sim.crs)
    want = adjust_to_ground(
        strip,
        sim.control,
        crs,
        options=GroundOptions(polynomial=0, max_iterations=30),
        blunders=BlunderOptions(action=BlunderAction.OFF),
    )
    got = similarity_start(strip, sim.control, crs, route=None, max_iterations=30)
    ids = np.asarray(strip.observations.point_ids)
    at = np.isin(ids, np.asarray(sim.control.point_ids)[want.control_index])
    assert got.passes < want.passes
    np.testing.assert_allclose(got.points[at], want.points[at], rtol=0, atol=0.01)
