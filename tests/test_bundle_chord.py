"""The bundle's chord step (bundle/adjust.py ``_chord``): once a full
Gauss-Newton step is small, the next step takes the gradient at the new
state with the factor at hand; the same adjustment as full steps to 1e-9,
one reduction and factoring of the normal equations fewer."""

from __future__ import annotations

import numpy as np
import pytest

import strip_aerotri.bundle._snoop_camera as snoop_camera
import strip_aerotri.bundle.adjust as adjust
from strip_aerotri.bundle.refine import refine_bundle
from strip_aerotri.geometry import normals as normals_module
from strip_aerotri.pipeline import triangulate
from strip_aerotri.results import BundleResult, RefinedResult
from strip_aerotri.simulate import simulate_strip

CHORD_FROM = adjust._CHORD_BELOW_MOVE  # the module's own, before any test changes it


def _refined(chord_from: float,
             **kwargs: object) -> tuple[RefinedResult, list[float], int, list[BundleResult]]:
    """A refinement with ``_CHORD_BELOW_MOVE = chord_from``: its result, the
    dampings of its solves, its count of chord steps and its bundles."""
    sim = simulate_strip(30, preset="drone", seed=5, control="every_k_models", control_every=5)
    strip = triangulate(sim.observations, sim.control, sim.crs)
    solves: list[float] = []
    chords = [0]
    bundles: list[BundleResult] = []
    solve, chord = normals_module.FormedNormals.solve, normals_module.FormedNormals.chord_step

    def counted_solve(self, damping=0.0, **kwargs):  # type: ignore[no-untyped-def]
        solves.append(damping)
        return solve(self, damping, **kwargs)

    def counted_chord(self, solution):  # type: ignore[no-untyped-def]
        chords[0] += 1
        return chord(self, solution)

    def kept(*args, **kw):  # type: ignore[no-untyped-def]
        bundles.append(adjust.bundle_adjust(*args, **kw))
        return bundles[-1]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(adjust, "_CHORD_BELOW_MOVE", chord_from)
        mp.setattr(normals_module.FormedNormals, "solve", counted_solve)
        mp.setattr(normals_module.FormedNormals, "chord_step", counted_chord)
        mp.setattr(snoop_camera, "bundle_adjust", kept)
        refined = refine_bundle(strip, **kwargs)  # type: ignore[arg-type]
    return refined, solves, chords[0], bundles


def test_the_chord_step_gives_the_full_steps_adjustment_with_one_factor_fewer() -> None:
    full, full_solves, no_chords, full_bundles = _refined(0.0)
    fast, fast_solves, chords, fast_bundles = _refined(CHORD_FROM)
    assert no_chords == 0 and chords >= 1
    assert len(fast_solves) == len(full_solves) - chords
    assert fast.iterations == full.iterations
    assert [b.iterations for b in fast_bundles] == [b.iterations for b in full_bundles]
    scale = np.abs(full.points_frame).max()
    np.testing.assert_allclose(fast.points_frame, full.points_frame, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(fast.photo_centres_frame, full.photo_centres_frame, rtol=1e-12,
                               atol=1e-9 * scale)
    np.testing.assert_allclose(fast.photo_opk, full.photo_opk, rtol=0, atol=1e-9)
    assert fast.sigma0 == pytest.approx(full.sigma0, rel=1e-9)
    np.testing.assert_allclose(fast.point_std, full.point_std, rtol=1e-9)
    for a, b in zip(fast_bundles, full_bundles, strict=True):
        np.testing.assert_allclose(a.image_redundancy, b.image_redundancy, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.residuals_mm, b.residuals_mm, rtol=0, atol=1e-9)
    # and the test that fails: without the chord, the chord's count of solves
    assert len(full_solves) > len(fast_solves)


def test_a_border_takes_full_steps_only() -> None:
    # the chord has no border (camera or shutter parameters) in its right-hand side
    from strip_aerotri.options import SelfCalibration

    _, _, chords, _ = _refined(1.0, self_calibration=SelfCalibration(("k1",)))
    assert chords == 0
