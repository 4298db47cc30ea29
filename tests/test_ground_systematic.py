"""The construction by models when a bending makes the control fail a few
points at a time: the first solution fails two control points a little over
the critical value, and rejecting the worst makes the next one fail, until
more than the allowed share of the control is out.  The control is then
judged on every test value met so far, not on the first solution alone."""

from __future__ import annotations

import dataclasses
import warnings

from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.observations import ControlType
from strip_aerotri.pipeline import triangulate
from strip_aerotri.results import StripResult
from strip_aerotri.simulate import SimulatedStrip, camera_preset, simulate_strip

#: A case of the sweep's camera family (``benchmarks/sweep.py --family camera``,
#: case 6): 34 one-inch photos across, R4's "fig4" control, 23 µm of
#: uncorrected camera error at the format corner (affinity and shear mostly).
_CAMERA = {
    "k1": -4.608882925315378e-05,
    "p1": -8.508102485468112e-06,
    "p2": 2.275868857425119e-05,
    "b1": -0.00043510432970060673,
    "b2": -0.00038547238176686897,
}


def _strip(camera_errors: dict[str, float] | None) -> SimulatedStrip:
    return simulate_strip(
        34,
        preset=camera_preset(
            "oneinch",
            long_side="across",
            forward_overlap=0.7493052640562228,
            flying_height_m=131.74835241540035,
            tilt_deg=1.1356056890743504,
            kappa_deg=7.987009149011515,
            relief_m=5.386186007740973,
            noise_um=2.0241348507238874,
        ),
        crs="EPSG:2180",
        centre_lonlat=(19.5, 52.0),
        heading_deg=39.68856257393049,
        seed=605,
        control="fig4",
        control_every=5,
        camera_errors=camera_errors,
    )


def _triangulate(sim: SimulatedStrip) -> tuple[StripResult, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        result = triangulate(sim.observations, sim.control, sim.crs)
    return result, [str(w.message) for w in caught if issubclass(w.category, StripAerotriWarning)]


def test_control_failing_one_after_another_is_kept_with_a_warning() -> None:
    """It stopped with "more than 20% of the control observations fail the
    blunder test" (the first solution alone fails 2 of 26 points); it runs on
    all the control and names the camera."""
    result, messages = _triangulate(_strip(_CAMERA))
    alike = [m for m in messages if "fail the blunder test alike" in m]
    assert len(alike) == 1, messages
    assert not any(r.applied for r in result.ground.rejections if r.stage == "control")
    plan = result.check_statistics.rmse_plan
    assert plan < 0.2  # 0.12 m; the bundle given the true camera reaches 0.09


def test_a_control_blunder_on_the_same_strip_is_still_rejected() -> None:
    """The rule keeps a bending, not a blunder: the same strip without camera
    errors and a 1 m error at one control point rejects that point alone."""
    sim = _strip(None)
    control = sim.control
    full = [i for i, k in enumerate(control.kind) if k is ControlType.FULL]
    row = full[len(full) // 2]  # one in the middle of the strip
    xyz = control.xyz.copy()
    xyz[row, 2] += 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        result = triangulate(
            sim.observations,
            dataclasses.replace(control, xyz=xyz),
            sim.crs,
        )
    applied = [r for r in result.ground.rejections if r.stage == "control" and r.applied]
    assert [(r.point, r.component) for r in applied] == [(control.point_ids[row], "height")]


# ------------------------------------------------ the one judgement: fails_alike


def test_fails_alike_judges_every_test_value_met_so_far() -> None:
    """Five control points: the first solution fails one (no pattern); after
    two rejections at |w| 5.0 and 4.6 the last solution fails a third at 4.4:
    together three of five fail alike.  A single large failure that drags its
    neighbours a little over stays a blunder."""
    import numpy as np
    import pytest

    from strip_aerotri.ground.systematic import fails_alike

    nan = np.nan
    first = np.array([[5.0, 1, 2], [3.0, 2, 1], [1.0, 1, 0.5], [2.0, 1, 1], [0.5, 0.2, 1]])
    assert fails_alike(first, 4.0) is None
    last = np.array([[nan, nan, 2], [nan, nan, 1], [4.4, 1, 0.5], [2.0, 1, 1], [0.5, 0.2, 1]])
    judged = fails_alike(first, 4.0, last=last, rejected=[(0, 0, 5.0), (1, 0, -4.6)])
    assert judged is not None
    assert judged[:, 0] == pytest.approx([5.0, 4.6, 4.4, 2.0, 0.5])
    # a blunder: one point at 20, its neighbours dragged just over the limit
    blunder = np.array([[nan, nan, 1], [4.2, 1, 1], [4.1, 1, 1], [2.0, 1, 1], [0.5, 0.2, 1]])
    assert fails_alike(first, 4.0, last=blunder, rejected=[(0, 0, 20.0)]) is None


def _film_strip(**kwargs):  # type: ignore[no-untyped-def]
    return simulate_strip(16, seed=4, crs="local", control="dense", **kwargs)


def test_polynomial_construction_keeps_control_failing_alike() -> None:
    """A film strip with 30 µm of radial distortion at 100 mm and 60 ppm of
    affinity, a linear polynomial (which cannot follow the bending): it
    stopped with "more than 20% of the control observations fail"; it now
    runs on all the control and names the camera."""
    from strip_aerotri.options import GroundOptions

    sim = _film_strip(systematic_k1=3e-8, film_shrink_y=1 + 60e-6)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        result = triangulate(
            sim.observations,
            sim.control,
            sim.crs,
            ground_options=GroundOptions(route="projected", polynomial=1, construction="strips"),
        )
    messages = [str(w.message) for w in caught if issubclass(w.category, StripAerotriWarning)]
    assert sum("fail the blunder test alike" in m for m in messages) == 1, messages
    assert not any(r.applied for r in result.ground.rejections if r.stage == "control")
    assert any(not r.applied for r in result.ground.rejections if r.stage == "control")


def test_polynomial_construction_still_rejects_a_blunder() -> None:
    """The same strip without camera errors and 1 m at one control height:
    that point alone is rejected, no warning of failing alike."""
    from strip_aerotri.options import GroundOptions

    sim = _film_strip()
    control = sim.control
    full = [i for i, k in enumerate(control.kind) if k is ControlType.FULL]
    row = full[len(full) // 2]
    xyz = control.xyz.copy()
    xyz[row, 2] += 1.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        result = triangulate(
            sim.observations,
            dataclasses.replace(control, xyz=xyz),
            sim.crs,
            ground_options=GroundOptions(route="projected", polynomial=1, construction="strips"),
        )
    assert not any("alike" in str(w.message) for w in caught)
    applied = [r for r in result.ground.rejections if r.stage == "control" and r.applied]
    # the blunder first, then what the strip without it rejects too (P0186's
    # plan at |w| 4.8, a linear polynomial on a slightly bent strip)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        clean = triangulate(
            sim.observations,
            control,
            sim.crs,
            ground_options=GroundOptions(route="projected", polynomial=1, construction="strips"),
        )
    before = [(r.point, r.component) for r in clean.ground.rejections if r.stage == "control"]
    assert [(r.point, r.component) for r in applied] == [
        (control.point_ids[row], "height"),
        *before,
    ]
