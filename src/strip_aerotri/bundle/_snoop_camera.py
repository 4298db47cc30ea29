"""The self-calibration of :func:`~strip_aerotri.bundle.snooping.refine_frame`:
the adjustments ``"auto"`` chooses with (:class:`_Trials`), the camera of
the rounds and its choice (:class:`_Camera`, chosen once more after the
blunder tests), and one adjustment of the data in use (:func:`_adjust`)."""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import StripAerotriWarning
from ..geometry.camera_model import CameraModel
from ..observations import ImageObservations
from ..options import SelfCalibration
from ..results import BundleResult, FrameRefinement, SelfCalibrationOutcome
from ._snoop_sets import _compact, _Inputs, _Sets
from .adjust import NOT_CONVERGED, bundle_adjust
from .selfcal import ebner_base_mm, final_outcome, residual_cells, start_model

__all__: list[str] = []

#: Relative change of the sum of squares below which a trial adjustment of
#: ``"auto"``'s choice stops (the delivered one's is 1e-10).  Gauss-Newton
#: converges quadratically: the step that changes the sum of squares by less
#: than 1e-6 of itself leaves the t values within 1e-3 of the converged ones
#: (1.4e-6 on the drone strip of tests/test_camera_subsets.py, one iteration
#: fewer), and the first round of the data snooping goes on from there.
_TRIAL_TOLERANCE = 1e-6


def _adjust(
    inp: _Inputs,
    sets: _Sets,
    sub: ImageObservations,
    pts: IntArray,
    state: tuple[FloatArray, FloatArray, FloatArray],
    *,
    max_iterations: int,
    compute_precision: bool,
    camera: CameraModel | None,
    camera0: FloatArray | None,
    tolerance: float = 1e-10,
) -> BundleResult:
    """One bundle adjustment of the observations, control, GNSS and IMU in use
    (``tolerance`` :func:`bundle_adjust`'s)."""
    return bundle_adjust(
        sub,
        state[0],
        state[1],
        state[2][pts],
        camera=camera,
        camera0=camera0,
        motion=inp.motion,
        control_xyz=np.where(sets.ctrl_on[pts], inp.c_xyz[pts], np.nan),
        control_sigma=np.where(sets.ctrl_on[pts], inp.c_sig[pts], np.inf),
        gnss_centres=None
        if inp.g_xyz is None
        else np.where(sets.g_on[:, None], inp.g_xyz, np.nan),
        gnss_sigma=None if inp.g_xyz is None else inp.g_sig,
        imu_rotations=None
        if inp.i_rot is None
        else np.where(sets.i_on[:, None, None], inp.i_rot, np.nan),
        imu_sigma=None if inp.i_rot is None else inp.i_sig,
        max_iterations=max_iterations,
        compute_precision=compute_precision,
        tolerance=tolerance,
    )


@dataclass
class _Trials:
    """The adjustments of ``"auto"``'s choice (:class:`~strip_aerotri.bundle.selfcal.Trials`):
    on the data as given, without tests, each from the last one's photos and
    points; ``state`` the last one's (the start of the first round)."""

    inp: _Inputs
    sets: _Sets
    sub: ImageObservations
    pts: IntArray
    max_iterations: int
    state: tuple[FloatArray, FloatArray, FloatArray]

    def _run(self, model: CameraModel | None, start: FloatArray | None, iterations: int
             ) -> BundleResult:
        with warnings.catch_warnings():
            # a trial may estimate parameters the data cannot separate (the
            # choice then holds them), and a screening takes no step; only the
            # delivered adjustment's convergence is the user's concern
            warnings.filterwarnings("ignore", NOT_CONVERGED, category=StripAerotriWarning)
            return _adjust(
                self.inp, self.sets, self.sub, self.pts, self.state,
                max_iterations=iterations, compute_precision=False, camera=model,
                camera0=start, tolerance=_TRIAL_TOLERANCE,
            )  # fmt: skip

    def screen(self, model: CameraModel) -> BundleResult:
        return self._run(model, None, 0)

    def adjust(self, model: CameraModel | None, start: FloatArray | None) -> BundleResult:
        res = self._run(model, start, self.max_iterations)
        points = self.state[2].copy()
        points[self.pts] = res.points
        self.state = (res.centres, res.rotations, points)
        return res


def _rejected_text(images: int, control: int) -> str:
    """What the tests rejected, for the note of a choice made again."""
    return " and ".join(
        f"{n} {kind}"
        for n, kind in ((images, "image observation(s)"), (control, "control coordinate(s)"))
        if n
    )


@dataclass(frozen=True)
class _Camera:
    """The self-calibration of a refinement: its model, current values and choice;
    ``state`` the photos and points of the choice's adjustment of the kept set
    (None: none kept, or no choice)."""

    spec: SelfCalibration | None
    model: CameraModel | None
    values: FloatArray | None
    chosen: SelfCalibrationOutcome | None
    state: tuple[FloatArray, FloatArray, FloatArray] | None = None
    rechecked: bool = False  # "auto" chose again after the blunder tests

    @classmethod
    def start(
        cls,
        inp: _Inputs,
        sets: _Sets,
        spec: SelfCalibration | None,
        max_iterations: int,
        state: tuple[FloatArray, FloatArray, FloatArray] | None = None,
    ) -> _Camera:
        """The model to start with; ``"auto"`` chooses it on the data in use
        (``sets``), its adjustments from ``state`` (default the start values)."""
        if spec is None:
            return cls(None, None, None, None)
        obs = inp.obs
        pt_used = sets.used_points(inp)
        sub, _, pts = _compact(obs, sets.keep, pt_used)
        c_mm = float(obs.principal_distance)
        trials = _Trials(
            inp, sets, sub, pts, max_iterations,
            state or (inp.centres0, inp.rotations0, inp.points0),
        )  # fmt: skip
        base = ebner_base_mm(inp.centres0, inp.points0[pts], c_mm)
        model, values, chosen = start_model(spec, trials, c_mm, base)
        # a kept set starts where its own trial converged; none starts where the
        # refinement without self-calibration does (and ends as it does)
        return cls(spec, model, values, chosen, trials.state if model is not None else None)

    def checked_again(
        self,
        inp: _Inputs,
        initial: _Sets,
        tested: _Sets,
        max_iterations: int,
        state: tuple[FloatArray, FloatArray, FloatArray],
    ) -> _Camera | None:
        """``"auto"``'s choice made again, once, after the blunder tests
        (``tested``; ``initial`` the data before them); None when there is
        nothing to check (another choice, checked already, nothing rejected).

        A blunder inflates sigma0 and so deflates every t value (or lends a
        parameter a t of its own): on simulated drone strips with 5-15 image
        blunders and a camera error the set chosen before the tests missed
        the affinity that the blunder-free data keep, and the check points
        lost half their plan accuracy; two control points off by 0.5-2 m
        on error-free blocks lent k1 and k3 t values of their own
        (docs/bundle.md).  So the choice is made on the image observations
        the tests kept with all the control (a control point the camera
        chosen first left bent may fail no more), and, where that changes
        nothing and control was rejected, on the control kept too.  Another
        set is adjusted and tested from the start, with all the control."""
        images = int(np.count_nonzero(tested.obs_rejected))
        control = int(np.count_nonzero(tested.ctrl_rejected))
        if self.spec is None or self.spec.choice != "auto" or self.rechecked:
            return None
        trials = [
            (data, what)
            for data, what, rejected in (
                (initial.with_images_of(tested), _rejected_text(images, 0), images),
                (initial.with_tests_of(tested), _rejected_text(images, control), control),
            )
            if rejected
        ]
        if not trials:
            return None
        assert self.chosen is not None  # "auto" always tells its choice
        old, chosen = self.chosen.kept, self.chosen
        for data, what in trials:
            again = _Camera.start(inp, data, self.spec, max_iterations, state)
            assert again.chosen is not None
            new = again.chosen.kept
            if set(new) != set(old):
                note = (
                    f"self-calibration chosen again without the {what} the blunder tests "
                    f"rejected: {', '.join(old) or 'none'} became {', '.join(new) or 'none'}, "
                    "and the tests started over with it"
                )
                told = dataclasses.replace(again.chosen, notes=(*again.chosen.notes, note))
                return dataclasses.replace(again, chosen=told, rechecked=True)
            chosen = again.chosen
        # the same set: this round's adjustment stands, told the reasons and
        # values of the choice on the data kept
        return dataclasses.replace(self, chosen=chosen, rechecked=True)

    def told(self, result: FrameRefinement, sets: _Sets, obs: ImageObservations
             ) -> FrameRefinement:
        """``result`` (this camera's set adjusted) told this choice's outcome."""
        residuals = np.where(sets.keep[:, None], result.image_residuals_mm, np.nan)
        outcome = self.outcome(result.bundle, obs.xy, residuals)
        return dataclasses.replace(result, self_calibration=outcome)

    @property
    def estimated(self) -> tuple[str, ...]:
        """The parameters the next adjustment estimates."""
        return () if self.model is None else self.model.estimated

    def moved(self, res: BundleResult) -> _Camera:
        """The camera of the next round starts from this round's estimate."""
        if res.camera is None:
            return self
        return dataclasses.replace(self, values=res.camera.values)

    def outcome(
        self, res: BundleResult, xy: FloatArray, residuals_mm: FloatArray
    ) -> SelfCalibrationOutcome | None:
        """What was estimated, kept and held, with the residuals over the format."""
        if self.spec is None:
            return None
        out = final_outcome(self.spec, self.chosen, res.camera)
        if res.camera is None:
            return out
        return dataclasses.replace(out, cells=residual_cells(res.camera, xy, residuals_mm))
