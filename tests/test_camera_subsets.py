"""The camera subsets of "auto" from one adjustment's border, against
adjusting each subset for real; the choice they make, against the choice
made by adjusting every subset; the screening's correlations."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from strip_aerotri.bundle import selfcal
from strip_aerotri.bundle.adjust import NOT_CONVERGED, bundle_adjust
from strip_aerotri.bundle.camera_subsets import LinearisedCamera
from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.geometry.camera_model import CameraModel
from strip_aerotri.options import SelfCalibration
from strip_aerotri.results import BundleResult
from strip_aerotri.simulate import simulate_strip

#: about 25 µm at the corner of the drone format: radial, decentring, affinity
_ERRORS = {"k1": -5.0e-5, "p2": -8.0e-5, "b1": 1.0e-3}
_SET = ("k1", "k2", "p1", "p2", "b1", "b2")


class _Frame:
    """A simulated drone strip in its local frame, started from the truth,
    control at the simulated points (5 cm), as bundle_adjust takes it."""

    def __init__(self, errors: dict[str, float] | None, seed: int = 4) -> None:
        sim = simulate_strip(16, preset="drone", seed=seed, crs="local", camera_errors=errors)
        t = sim.truth
        self.obs = sim.observations
        self.start = (t.photo_centres_local, t.photo_rotations_local, t.points_local)
        kinds = np.array([k.value for k in sim.control.kind])
        index = np.array([self.obs.point_ids.index(p) for p in sim.control.point_ids])
        used = index[kinds != "check"]
        self.control = np.full((self.obs.n_points, 3), np.nan)
        self.control[used] = t.points_local[used]
        self.c_mm = float(self.obs.principal_distance)

    def model(self, names: tuple[str, ...] | list[str]) -> CameraModel:
        return CameraModel("brown", tuple(names), self.c_mm)

    def adjust(
        self, names: tuple[str, ...] | list[str] | None, iterations: int = 50
    ) -> BundleResult:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", NOT_CONVERGED, category=StripAerotriWarning)
            return bundle_adjust(
                self.obs, *self.start, control_xyz=self.control, control_sigma=0.05,
                camera=None if names is None else self.model(names),
                compute_precision=False, max_iterations=iterations,
            )  # fmt: skip


@pytest.fixture(scope="module")
def frame() -> _Frame:
    return _Frame(_ERRORS)


def test_the_whole_set_is_its_own_subset(frame: _Frame) -> None:
    fit = LinearisedCamera.of(frame.adjust(_SET))
    same = fit.subset(_SET, frame.model(_SET))
    assert np.allclose(same.estimate.values, fit.estimate.values, rtol=1e-9, atol=0)
    assert np.allclose(same.estimate.cofactor, fit.estimate.cofactor, rtol=1e-9, atol=0)
    assert same.cost == pytest.approx(fit.cost, rel=1e-12)
    assert same.redundancy == fit.redundancy


@pytest.mark.parametrize("names", [("k1", "p2", "b1"), ("k1",), ("b1", "b2")])
def test_a_subset_from_the_border_matches_its_own_adjustment(
    frame: _Frame, names: tuple[str, ...]
) -> None:
    """Estimates, standard deviations, t values, correlations, sigma0 and
    redundancy of a subset predicted from the whole set's border agree with
    an adjustment of that subset (the rest held at zero)."""
    fit = LinearisedCamera.of(frame.adjust(_SET))
    predicted = fit.subset(names, frame.model(names))
    real = frame.adjust(names)
    assert real.camera is not None
    p, r = predicted.estimate, real.camera
    assert predicted.redundancy == real.redundancy
    # what the linearisation leaves out is the nonlinearity of the camera's
    # change: within 1 % of the change of the sum of squares the subset makes
    # (0.34 of 70 when the significant k1 and p2 are held, t -5.6 and -6.1)
    real_cost = r.sigma0**2 * real.redundancy
    assert abs(predicted.cost - real_cost) <= 0.01 * (real_cost - fit.cost) + 1e-3
    assert np.all(np.abs(p.values - r.values) < 0.03 * r.std)
    assert np.allclose(p.std, r.std, rtol=3e-3)
    assert np.all(np.abs(p.t_values - r.t_values) < 0.02)
    assert np.allclose(p.correlations, r.correlations, atol=1e-3)
    assert np.allclose(p.orientation_correlation, r.orientation_correlation, atol=1e-4)
    # the same subset from another superset agrees too
    other = LinearisedCamera.of(frame.adjust(("k1", "p2", "b1", "b2")))
    if set(names) <= {"k1", "p2", "b1", "b2"}:
        again = other.subset(names, frame.model(names)).estimate
        assert np.all(np.abs(again.values - r.values) < 0.03 * r.std)


def test_the_cost_without_a_camera_matches_that_adjustment(frame: _Frame) -> None:
    fit = LinearisedCamera.of(frame.adjust(_SET))
    none = frame.adjust(None)
    k = len(_SET)
    assert none.redundancy == fit.redundancy + k
    cost = none.sigma0**2 * none.redundancy
    assert abs(fit.cost_without - cost) <= 0.01 * (cost - fit.cost)
    # the simulated errors are far from negligible here: the camera matters
    assert none.sigma0 > 1.15 * fit.estimate.sigma0


def test_a_subset_must_be_ordered_as_the_set(frame: _Frame) -> None:
    fit = LinearisedCamera.of(frame.adjust(("k1", "b1")))
    with pytest.raises(ValueError, match="in the order of"):
        fit.subset(("k1", "b1"), frame.model(("k1", "p2")))


def test_the_screening_sees_the_design_correlations_of_the_converged_adjustment(
    frame: _Frame,
) -> None:
    """The multiple correlations with the orientation from the start values,
    no step taken, agree with those of the adjustment to convergence: they
    are the design's, and hold c, x0 and y0 alike."""
    names = ("c", "x0", "y0", "k1", "b1")
    start = frame.adjust(names, iterations=0).camera
    end = frame.adjust(("k1", "b1")).camera
    assert start is not None and end is not None
    r0 = dict(zip(start.names, start.orientation_correlation, strict=True))
    r1 = dict(zip(end.names, end.orientation_correlation, strict=True))
    assert all(r0[n] > selfcal.INTERIOR_CORRELATION for n in ("c", "x0", "y0"))
    for n in ("k1", "b1"):
        assert r0[n] == pytest.approx(r1[n], abs=1e-4)
    # the camera's values at no step are one linearised step's: the first
    # iteration's camera of the same adjustment
    one = frame.adjust(names, iterations=1).camera
    assert one is not None
    assert np.allclose(start.values, one.values, rtol=1e-6, atol=0)


class _RealTrials:
    """Trials as ``refine_frame`` gives them, on the frame (and counted)."""

    def __init__(self, frame: _Frame) -> None:
        self.frame = frame
        self.screens = 0
        self.adjustments = 0

    def screen(self, model: CameraModel) -> BundleResult:
        self.screens += 1
        return self.frame.adjust(model.estimated, iterations=0)

    def adjust(self, model: CameraModel | None, start: np.ndarray | None) -> BundleResult:
        self.adjustments += 1
        return self.frame.adjust(None if model is None else model.estimated)


def _adjusting_every_subset(frame: _Frame) -> tuple[tuple[str, ...], dict[str, str]]:
    """The rules of "auto" with every subset adjusted for real (what the choice
    did before the border's algebra): the kept set and the held reasons."""
    from strip_aerotri.geometry.camera_model import BROWN_PARAMETERS

    active = list(BROWN_PARAMETERS)
    held: dict[str, str] = {}
    absorbed: set[str] = set()
    while active:
        cam = frame.adjust(active, iterations=50 if len(active) < 10 else 0).camera
        assert cam is not None
        hold = selfcal._next_to_hold(cam, absorbed)
        if not hold:
            break
        for name, reason, by_orientation in hold:
            held[name] = reason
            active.remove(name)
            if by_orientation:
                absorbed.add(name)
    return tuple(active), held


def _t_values(reason: str) -> list[float]:
    return [float(x) for x in re.findall(r"t = ([-0-9.]+)", reason)]


def _words(reason: str) -> str:
    """The reason with its t values blanked (the correlations kept)."""
    return re.sub(r"t = [-0-9.]+", "t = _", reason)


@pytest.mark.parametrize("errors", [_ERRORS, None])
def test_the_choice_equals_adjusting_every_subset(errors: dict[str, float] | None) -> None:
    frame = _Frame(errors)
    trials = _RealTrials(frame)
    cam, outcome = selfcal._auto(SelfCalibration("auto"), trials, frame.c_mm, 0.0)
    kept, held = _adjusting_every_subset(frame)
    reasons = {p.name: p.reason for p in outcome.parameters if not p.kept}
    # the same decisions, told with the same values: correlations to the
    # printed digits, t values within 2 %.  (c, 1 - rho of 4e-6 here, goes into
    # the walk; the border's algebra at the first adjustment's point and an
    # adjustment of each subset differ in its t by about 1 %: 1.54 against
    # 1.52, both far below 3.)
    assert set(outcome.kept) == set(kept) == set(errors or ())
    assert reasons.keys() == held.keys()
    for name, reason in reasons.items():
        assert _words(reason) == _words(held[name]), (reason, held[name])
        assert np.allclose(_t_values(reason), _t_values(held[name]), rtol=0.02, atol=0)
    assert (cam is None) == (errors is None)
    # one screening and one or two adjustments, not one per decision
    assert trials.screens == 1 and trials.adjustments <= 2


# ---------------------------------------------------------------- after the blunder tests


def _strip_with_blunders(n_blunders: int):  # type: ignore[no-untyped-def]
    from strip_aerotri.pipeline import triangulate

    sim = simulate_strip(
        20, preset="drone", seed=2, camera_errors={"k1": -4e-5, "b1": 8e-4},
        image_blunders=n_blunders,
    )  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sim, triangulate(sim.observations, sim.control, sim.crs)


def test_the_set_is_chosen_again_without_the_blunders() -> None:
    """A drone strip with 20 µm of radial distortion and affinity and five
    image blunders: on the data as given the blunders inflate sigma0 and the
    affinity's t falls to 2.3 (held); chosen again without the observations
    the tests rejected, it is kept (t 4.7), as on the data without the
    blunders, and the check points are those of the blunder-free data."""
    from strip_aerotri.bundle.refine import refine_bundle
    from strip_aerotri.options import BlunderOptions

    sim, strip = _strip_with_blunders(5)
    obs = sim.observations
    truth = tuple(
        (obs.photo_ids[obs.photo[k]], obs.point_ids[obs.point[k]])
        for k in sim.truth.blunder_observations
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        auto = refine_bundle(strip, self_calibration=SelfCalibration("auto"))
        clean = refine_bundle(
            strip, self_calibration=SelfCalibration("auto"),
            blunders=BlunderOptions(exclude_observations=truth),
        )  # fmt: skip
    assert auto.self_calibration is not None and clean.self_calibration is not None
    assert set(auto.self_calibration.kept) == set(clean.self_calibration.kept) == {"k1", "b1"}
    assert any("chosen again" in n and "k1 became" in n for n in auto.self_calibration.notes)
    assert any("chosen again" in w for w in auto.warnings)
    plan, clean_plan = auto.check_statistics.rmse_plan, clean.check_statistics.rmse_plan
    assert plan == pytest.approx(clean_plan, rel=0.01)
    # the rejections are those of the tests with the new set, from the start:
    # no record of the first set's rounds is left
    rejected = {(r.photos[0], r.point) for r in auto.rejections if r.stage == "bundle"}
    assert len(rejected & set(truth)) >= 4 and len(rejected) <= 5


def test_nothing_rejected_nothing_chosen_again() -> None:
    """Without blunders nothing is rejected and the choice is not made again."""
    from strip_aerotri.bundle.refine import refine_bundle

    _, strip = _strip_with_blunders(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        auto = refine_bundle(strip, self_calibration=SelfCalibration("auto"))
    assert auto.self_calibration is not None
    assert set(auto.self_calibration.kept) == {"k1", "b1"}
    assert not any("chosen again" in n for n in auto.self_calibration.notes)


def test_a_parameter_the_data_cannot_determine_is_held_and_named(frame: _Frame) -> None:
    """When the engine finds a parameter not determined at all (a singular
    border, ``CameraUndetermined``), in the screening or in the adjustment,
    "auto" holds it with that reason and goes on without it; the rest is
    chosen as before."""
    from strip_aerotri.bundle.adjust import CameraUndetermined

    class Refusing(_RealTrials):
        def __init__(self, frame: _Frame, name: str, where: str) -> None:
            super().__init__(frame)
            self.name, self.where = name, where

        def screen(self, model: CameraModel) -> BundleResult:
            if self.where == "screen" and self.name in model.estimated:
                raise CameraUndetermined("not determined", self.name)
            return super().screen(model)

        def adjust(self, model: CameraModel | None, start: np.ndarray | None) -> BundleResult:
            if self.where == "adjust" and model is not None and self.name in model.estimated:
                raise CameraUndetermined("not determined", self.name)
            return super().adjust(model, start)

    for name, where in (("c", "screen"), ("b2", "adjust")):
        trials = Refusing(frame, name, where)
        cam, outcome = selfcal._auto(SelfCalibration("auto"), trials, frame.c_mm, 0.0)
        reasons = {p.name: p.reason for p in outcome.parameters}
        assert reasons[name] == "not determined by the data"
        assert cam is not None and set(outcome.kept) == set(_ERRORS)
        # (the refused calls are not counted)
        assert trials.screens == 1 and trials.adjustments <= 2


def test_auto_keeping_nothing_is_the_plain_refinement() -> None:
    """When "auto" keeps nothing, the delivered adjustment starts where the
    refinement without self-calibration starts: the same points, to the bit."""
    from strip_aerotri.bundle.refine import refine_bundle
    from strip_aerotri.pipeline import triangulate

    sim = simulate_strip(14, preset="drone", seed=6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        strip = triangulate(sim.observations, sim.control, sim.crs)
        plain = refine_bundle(strip)
        auto = refine_bundle(strip, self_calibration=SelfCalibration("auto"))
    assert auto.self_calibration is not None and auto.self_calibration.kept == ()
    assert np.array_equal(auto.points, plain.points, equal_nan=True)
    assert np.array_equal(auto.photo_centres, plain.photo_centres)


def test_the_trials_tolerance_leaves_the_t_values() -> None:
    """A trial stops at a relative change of the sum of squares of 1e-6: its
    t values are those of the adjustment run to 1e-10 within 1e-3, from the
    strip method's start values (a real first step, not the truth)."""
    from strip_aerotri.bundle._snoop_camera import _TRIAL_TOLERANCE
    from strip_aerotri.bundle.refine import refine_bundle

    _, strip = _strip_with_blunders(0)
    seen: list[BundleResult] = []
    import strip_aerotri.bundle._snoop_camera as snoop_camera

    original = snoop_camera.bundle_adjust

    def recording(*args, **kwargs):  # type: ignore[no-untyped-def]
        res = original(*args, **kwargs)
        if kwargs.get("tolerance") == _TRIAL_TOLERANCE and kwargs.get("max_iterations", 1) > 0:
            seen.append(res)
            tight = original(*args, **{**kwargs, "tolerance": 1e-10})
            seen.append(tight)
        return res

    snoop_camera.bundle_adjust = recording  # type: ignore[assignment]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            refine_bundle(strip, self_calibration=SelfCalibration("auto"))
    finally:
        snoop_camera.bundle_adjust = original  # type: ignore[assignment]
    assert seen
    # the tolerance saves an iteration (2 against 3 on this strip's second trial)
    assert any(lo.iterations < ti.iterations for lo, ti in zip(seen[::2], seen[1::2], strict=True))
    for loose, tight in zip(seen[::2], seen[1::2], strict=True):
        assert loose.camera is not None and tight.camera is not None
        assert loose.iterations <= tight.iterations
        assert np.all(np.abs(loose.camera.t_values - tight.camera.t_values) < 1e-3)


def test_an_error_free_block_with_blunders_keeps_no_camera() -> None:
    """The envelope's error-free 3 x 12 drone block with 6 image blunders and a
    control blunder (docs/ground.md 7.7): chosen on the data as given,
    "auto" keeps k1 and b1 (p1 when the refinement took only the control the
    block's similarities kept); chosen again on the image observations the
    tests kept it still does, and without the control blunder too, nothing."""
    from strip_aerotri.observations import StripSpec
    from strip_aerotri.pipeline import triangulate_block
    from strip_aerotri.simulate import simulate_block

    block = simulate_block(3, 12, preset="drone", seed=0, image_blunders=6, control_blunders=1)
    specs = [StripSpec(s.name, s.photo_ids) for s in block.strips]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = triangulate_block(
            block.observations, block.control, block.crs, specs, refine="bundle",
            self_calibration=SelfCalibration("auto"),
        )  # fmt: skip
    sc = res.self_calibration
    assert sc is not None and sc.kept == ()
    assert any("control coordinate(s)" in n and "became none" in n for n in sc.notes)
    assert res.check_statistics.rmse_plan < 0.02 and res.check_statistics.rmse[2] < 0.025
