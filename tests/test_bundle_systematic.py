"""The bundle refinement when the control fails at many points alike:
camera errors, not blunders (issue item "systematic errors are not
blunders", for the plain bundle), and the remedy the warnings name."""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import pytest

from strip_aerotri.errors import GeometryError, StripAerotriWarning
from strip_aerotri.ground.systematic import (
    KEPT_EFFECT,
    self_calibration_follows,
    systematic_message,
)
from strip_aerotri.options import BlunderOptions, GroundOptions, Route, SelfCalibration
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip

#: ``stripaero simulate drone --camera-error k1=-3e-4``: 13 of its 14 control
#: points fail the first bundle's control test at |w| 4.8-20.
_K1 = {"k1": -3e-4}


def _drone(camera_errors: dict[str, float] | None = _K1) -> Any:
    return simulate_strip(12, preset="drone", seed=0, camera_errors=camera_errors)


def _run(sim: Any, **kwargs: Any) -> tuple[Any, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        result = triangulate(
            sim.observations,
            sim.control,
            sim.crs,
            ground_options=GroundOptions(route=Route.PROJECTED),
            refine="bundle",
            **kwargs,
        )
    return result, [str(w.message) for w in caught if issubclass(w.category, StripAerotriWarning)]


def test_plain_bundle_keeps_control_failing_alike_and_warns() -> None:
    """It used to stop with "more than 20% of the control observations fail";
    now it runs on all the control, warns once and names the remedy."""
    sim = _drone()
    result, messages = _run(sim)
    refined = result.refined
    assert refined is not None
    bundle_warnings = [m for m in messages if m.startswith("bundle adjustment:")]
    assert len(bundle_warnings) == 1, messages
    assert "fail the blunder test alike" in bundle_warnings[0]
    assert 'self_calibration = "auto"' in bundle_warnings[0]
    # every control component is used, no control rejection is applied
    control = [r for r in refined.rejections if r.stage == "control"]
    assert not any(r.applied for r in control)
    assert all(r.effect.startswith(KEPT_EFFECT) for r in control)
    kind = np.array([str(getattr(k, "value", k)) for k in sim.control.kind])[refined.control_index]
    given = ~refined.is_check
    assert np.array_equal(refined.used_xy[given], np.isin(kind[given], ("full", "plan")))
    assert np.array_equal(refined.used_h[given], np.isin(kind[given], ("full", "height")))
    # the bundle with the camera calibrated does much better: the warning
    # named the right remedy
    auto, _ = _run(sim, self_calibration=SelfCalibration("auto"))
    assert auto.refined is not None
    assert auto.refined.check_statistics.rmse[2] < 0.2 * refined.check_statistics.rmse[2]


def test_one_bad_control_point_is_still_rejected_by_the_bundle() -> None:
    """Not every control failure is kept: a blunder of 0.5 m at one control
    point of the error-free drone strip is rejected as before."""
    sim = _drone(None)
    control = sim.control
    full = [i for i, k in enumerate(control.kind) if str(getattr(k, "value", k)) == "full"]
    xyz = control.xyz.copy()
    xyz[full[3], 2] += 0.5
    bad = type(control)(control.point_ids, xyz, control.kind, control.sigma_xy, control.sigma_h)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = triangulate(
            sim.observations,
            bad,
            sim.crs,
            ground_options=GroundOptions(route=Route.PROJECTED),
            refine="bundle",
            blunders=BlunderOptions(),
        )
    assert result.refined is not None
    applied = [r for r in result.refined.rejections if r.stage == "control" and r.applied]
    assert [r.point for r in applied] == [control.point_ids[full[3]]]


def test_too_many_failing_control_points_that_are_not_alike_still_stop() -> None:
    """Two gross errors among five control points: not a pattern, so the
    bundle stops as before."""
    from strip_aerotri.bundle.snooping import refine_frame

    sim = _drone(None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        strip = triangulate(
            sim.observations,
            sim.control,
            sim.crs,
            ground_options=GroundOptions(route=Route.PROJECTED),
        )
    obs = strip.strip.observations
    refined = _run(sim)[0].refined
    assert refined is not None
    pts = refined.points_frame
    given = np.where(np.isfinite(pts), pts, np.nan)
    # five control points, two of them off by metres
    chosen = np.flatnonzero(np.all(np.isfinite(pts), axis=1))[:5]
    control = np.full_like(pts, np.nan)
    control[chosen] = given[chosen]
    control[chosen[1], 2] += 3.0
    control[chosen[3], 0] -= 4.0
    trusted = pytest.raises(GeometryError, match="control cannot be trusted")
    with trusted, warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        refine_frame(
            obs,
            refined.photo_centres_frame,
            refined.photo_rotations_frame,
            pts,
            control_xyz=control,
            control_sigma=np.full_like(pts, 0.02),
            blunders=BlunderOptions(max_fraction=0.1),
        )


def test_the_remedy_named_follows_what_the_run_does() -> None:
    rng = np.random.default_rng(4)
    w = rng.normal(0, 1.5, (14, 3))
    w[[0, 3, 6, 9, 12], 2] = [-4.9, 5.1, 4.4, -4.7, 5.5]
    plain = systematic_message("control", w, 4.1)
    assert 'self_calibration = "auto"' in plain
    with self_calibration_follows():
        following = systematic_message("control", w, 4.1)
    assert "self_calibration" not in following and "self-calibration estimates" in following
    assert systematic_message("control", w, 4.1) == plain  # the context ends
    calibrating = systematic_message("bundle adjustment", w, 4.1, self_calibrating=True)
    assert 'self_calibration = "auto"' not in calibrating
    assert "camera is self-calibrated" in calibrating


def test_ground_stage_warning_knows_the_bundle_self_calibrates() -> None:
    """The film strip of the camera-error family with "auto": the ground
    stage's "fails alike" warning no longer tells the user to add the
    self-calibration the run already has."""
    sim = simulate_strip(12, seed=1, crs="local", systematic_k1=3e-8, film_shrink_y=1 + 60e-6)
    _, messages = _run(sim, self_calibration=SelfCalibration("auto"))
    alike = [m for m in messages if "fail the blunder test alike" in m]
    assert alike and all('self_calibration = "auto"' not in m for m in alike)
    _, plain = _run(sim)
    assert any('self_calibration = "auto"' in m for m in plain if "alike" in m)

