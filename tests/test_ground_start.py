"""ground.polynomials.similarity_start: J's untested similarity as the start of
the models' ground stage, the same result as adjust_to_ground's except the
points in the CRS, given at the control points only, and its passes, which
end at a centimetre."""

from __future__ import annotations

import dataclasses
import functools
import warnings

import numpy as np
import pytest

import strip_aerotri as sa
import strip_aerotri.ground.models as ground_models
import strip_aerotri.ground.passes as passes
import strip_aerotri.ground.polynomials as polynomials
from strip_aerotri.geodesy import GroundCRS
from strip_aerotri.ground.polynomials import adjust_to_ground, similarity_start
from strip_aerotri.options import BlunderAction, BlunderOptions, GroundOptions


def _both_starts(sim, strip):  # type: ignore[no-untyped-def]
    """adjust_to_ground's untested similarity and similarity_start on the same
    strip, and the points at the control (bool over the strip's points)."""
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
    return want, got, at


def test_similarity_start_is_adjust_to_ground_with_the_points_at_the_control(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # with the ground stage's own pass tolerance, the same to the bit
    monkeypatch.setattr(polynomials, "_START_PASS_TOLERANCE_M", passes._PASS_TOLERANCE_M)
    sim = sa.simulate_strip(20, preset="drone", seed=3)
    strip = sa.form_strip(sim.observations)
    want, got, at = _both_starts(sim, strip)
    assert at.sum() == want.control_index.size
    np.testing.assert_array_equal(got.points[at], want.points[at])
    assert np.isnan(got.points[~at]).all()
    for field in dataclasses.fields(want):
        if field.name == "points":
            continue
        a, b = getattr(want, field.name), getattr(got, field.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=field.name)


@functools.cache
def _long_strip():  # type: ignore[no-untyped-def]
    """A 300-photo drone strip with height control and its formed strip."""
    sim = sa.simulate_strip(300, preset="drone", seed=5)
    return sim, sa.form_strip(sim.observations)


def test_the_start_passes_stop_at_a_centimetre() -> None:
    # the default start, in fewer passes: its points at the control within a
    # centimetre of the converged passes' (measured 7e-9 m: the guesses of
    # the last passes move the work frame, hardly the fit)
    sim, strip = _long_strip()
    want, got, at = _both_starts(sim, strip)
    assert got.passes < want.passes
    np.testing.assert_allclose(got.points[at], want.points[at], rtol=0, atol=0.01)


def test_the_models_end_where_the_strict_start_ends_them(monkeypatch: pytest.MonkeyPatch) -> None:
    # the models' solution from the start of a centimetre is that of the strict start
    sim, strip = _long_strip()
    starts = []
    real = ground_models.similarity_start

    def recorded(*args, **kwargs):  # type: ignore[no-untyped-def]
        starts.append(real(*args, **kwargs))
        return starts[-1]

    monkeypatch.setattr(ground_models, "similarity_start", recorded)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sa.StripAerotriWarning)
        loose = ground_models.adjust_models_to_ground(strip, sim.control, sim.crs)
        monkeypatch.setattr(polynomials, "_START_PASS_TOLERANCE_M", 1e-5)
        strict = ground_models.adjust_models_to_ground(strip, sim.control, sim.crs)
    # height control: the plan positions are guessed, pass after pass
    assert not sim.control.uses_xy.all()
    assert starts[0].passes < starts[1].passes
    np.testing.assert_allclose(loose.points, strict.points, rtol=0, atol=1e-8)
    np.testing.assert_allclose(loose.photo_centres, strict.photo_centres, rtol=0, atol=1e-8)
    assert [r.point for r in loose.rejections] == [r.point for r in strict.rejections]
    np.testing.assert_allclose(
        loose.control_redundancy, strict.control_redundancy, rtol=0, atol=1e-6
    )
