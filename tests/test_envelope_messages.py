"""Messages met at the edges of the envelope of projects (simulated strips
with blunders, self-calibration on clean data): each names the point and
the true cause."""

from __future__ import annotations

import warnings

from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip


def test_points_lost_to_blunder_tests_are_not_said_unseen() -> None:
    """A 20-photo film strip with 5 image blunders: control points P0126 and
    P0169 are seen on three photos, but the relative orientation rejected
    the y-parallax of each in both its pairs; the warning names that cause,
    not "seen on fewer than two photos"."""
    sim = simulate_strip(20, preset="film", seed=0, crs="EPSG:32634", image_blunders=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        res = triangulate(sim.observations, sim.control, sim.crs)
    rejected = {r.point for r in res.strip.rejections if r.stage == "relative_orientation"}
    assert {"P0126", "P0169"} <= rejected
    for pid in ("P0126", "P0169"):
        (line,) = [w for w in res.warnings if w.startswith(f"control point {pid!r}")]
        assert "see the relative_orientation rejections" in line, line
    unseen = [w for w in res.warnings if "(seen on fewer than two photos)" in w]
    assert not any("P0126" in w or "P0169" in w for w in unseen), unseen


def test_tie_point_failures_are_not_said_unseen() -> None:
    """A clean 6-photo film strip whose corner tie P0018 (seen on three
    photos) fails the tie-point test: the point is listed as lost to the
    blunder tests, not as seen on fewer than two photos."""
    sim = simulate_strip(6, preset="film", seed=0, crs="EPSG:32634")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        res = triangulate(sim.observations, sim.control, sim.crs)
    assert "P0018" in res.strip.rejected_points
    assert not any("P0018" in w and "fewer than two photos" in w for w in res.warnings)
    assert any("P0018" in w and "failed the blunder tests" in w for w in res.warnings)


def test_block_points_lost_to_blunder_tests_are_not_said_unmeasured() -> None:
    """A 3 x 8 film block with 15 image blunders (seed 5): check point P00055
    is measured on a pair, but the relative orientation rejected its
    y-parallaxes; the warning names that stage."""
    from strip_aerotri.block.strips import adjust_block
    from strip_aerotri.observations import StripSpec
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(3, 8, preset="film", seed=5, image_blunders=15)
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        res = adjust_block(sim.observations, sim.control, sim.crs, specs, construction="models")
    (line,) = [w for w in res.warnings if w.startswith("check point 'P00055' is not triangulated")]
    assert "see the relative_orientation rejections" in line, line
