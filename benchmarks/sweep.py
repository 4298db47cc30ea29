"""Robustness and accuracy of the strip method over the envelope of real projects.

Run from the repository root::

    python benchmarks/sweep.py               # every case (a few minutes)
    python benchmarks/sweep.py --quick       # the subset that tests/test_sweep.py runs
    python benchmarks/sweep.py --family drone-along -v

Each case is a seeded strip of the package's simulator
(:func:`strip_aerotri.simulate.simulate_strip`) whose parameters are drawn
from its family's ranges (camera and format, the format's long side along or
across the flight, forward overlap, flying height, tilt and kappa scatter,
relief, image noise, photos, control layout: R4's "fig4", "ends", every k
models, dense, weak; straight-line points; image and control blunders).  A
case is *valid* when every pair has at least 12 common points spread over at
least 55 % of the format across the flight; invalid draws are replaced by
the next seed.  On each valid case (with its gross errors, where the family
has them), on the same observations:

* the strip method as ``stripaero run`` does it (its defaults: every model
  at once, blunder tests rejecting), :func:`strip_aerotri.pipeline.triangulate`;
* its bundle refinement (``refine = "bundle"``);
* in the camera-error family (uncorrected lens distortion, decentring,
  affinity and shear of 10-50 µm at the format corner), also the
  refinement with ``self_calibration = "auto"`` and the reference given the
  true camera (the observations corrected by the simulated errors);
* the reference: the package's rigorous bundle adjustment with its data
  snooping, started from the truth, in the simulator's local east-north-up
  frame, on the same observations, the control at its sigmas
  (:func:`strip_aerotri.bundle.refine.refine_frame`); where the case has blunders
  also an *oracle* bundle on the observations without them and no tests
  (what a perfect blunder detection would leave).

The table gives, per case, the check-point RMSE (plan, height) of each and
the ratios strip / reference and refined / reference; then per family and
over all cases: success rate and the median and largest ratios.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from strip_aerotri.bundle.adjust import bundle_adjust
from strip_aerotri.bundle.refine import refine_bundle, refine_frame
from strip_aerotri.errors import GeometryError
from strip_aerotri.geodesy import GroundCRS
from strip_aerotri.ground.polynomials import LineSpec
from strip_aerotri.options import SelfCalibration, StripOptions
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import CAMERAS, SimulatedStrip, camera_preset, simulate_strip


@dataclass(frozen=True)
class Case:
    """One simulated strip of the sweep (lengths in m, angles in deg)."""

    family: str
    seed: int
    n_photos: int
    camera: str
    long_side: str  # "along" or "across" the flight
    overlap: float  # forward overlap, fraction
    height_m: float  # flying height above the mean terrain
    tilt_deg: float  # standard deviation of omega and phi
    kappa_deg: float  # standard deviation of kappa about the heading
    relief_m: float
    noise_um: float
    control: str  # simulate_strip's control layout
    control_every: int = 3
    line: bool = False
    image_blunders: int = 0
    control_blunders: int = 0
    camera_error_um: float = 0.0  # uncorrected camera errors at the format corner

    def camera_errors(self) -> dict[str, float] | None:
        """Brown/Fraser errors (the corrections the measurements need) whose
        shift at the format corner is ``camera_error_um``: radial, decentring,
        affinity and shear in proportions drawn from the seed."""
        if not self.camera_error_um:
            return None
        from strip_aerotri.geometry.camera_model import BROWN_PARAMETERS, brown_correction

        rng = np.random.default_rng(self.seed + 7)
        fmt = camera_preset(self.camera, long_side=self.long_side).format_mm
        corner = np.array([[fmt[0] / 2, fmt[1] / 2]])
        r = float(np.hypot(*corner[0]))
        share = rng.dirichlet([3.0, 1.0, 1.0, 1.0, 1.0])  # radial, p1, p2, b1, b2
        sign = rng.choice([-1.0, 1.0], 5)
        unit = {
            "k1": -share[0] / r**3,
            "p1": sign[1] * share[1] / r**2,
            "p2": sign[2] * share[2] / r**2,
            "b1": sign[3] * share[3] / r,
            "b2": sign[4] * share[4] / r,
        }
        v = np.array([unit.get(n, 0.0) for n in BROWN_PARAMETERS])
        size = float(np.hypot(*brown_correction(corner, v, 100.0)[0]))
        factor = self.camera_error_um * 1e-3 / size
        return {n: factor * unit[n] for n in unit}

    @property
    def label(self) -> str:
        extra = (" line" if self.line else "") + (
            f" cam{self.camera_error_um:.0f}um" if self.camera_error_um else ""
        ) + (
            f" bl{self.image_blunders}/{self.control_blunders}"
            if self.image_blunders or self.control_blunders
            else ""
        )
        return (
            f"{self.camera}-{self.long_side[:2]} {self.n_photos}ph {self.overlap:.0%} "
            f"H{self.height_m:.0f} t{self.tilt_deg:.1f} k{self.kappa_deg:.1f} "
            f"r{self.relief_m:.0f} n{self.noise_um:.1f} {self.control}{extra}"
        )


#: Control layouts of simulate_strip: R4's strip layout (fig4), its "ends"
#: variant with plan points, full control every k models, dense, and weak.
LAYOUTS = ("ends", "fig4", "every_k_models", "dense", "weak")


def _uniform(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _film(rng, family, seed, camera=None, n=(6, 40)) -> Case:
    cam = camera or str(rng.choice(["film88", "film152", "film210"]))
    c = CAMERAS[cam].principal_distance_mm
    scale = _uniform(rng, 5000, 15000)
    height = c * scale / 1000.0
    return Case(
        family=family,
        seed=seed,
        n_photos=int(rng.integers(n[0], n[1] + 1)),
        camera=cam,
        long_side="along",
        overlap=_uniform(rng, 0.57, 0.66),
        height_m=height,
        tilt_deg=_uniform(rng, 0.5, 3.0),
        kappa_deg=_uniform(rng, 1.0, 5.0),
        relief_m=height * _uniform(rng, 0.02, 0.10),
        noise_um=_uniform(rng, 2.0, 7.0),
        control=str(rng.choice(LAYOUTS)),
        control_every=int(rng.integers(3, 6)),
    )


def _drone(rng, family, seed, long_side, n=(20, 80)) -> Case:
    cam = str(rng.choice(["ff35", "apsc16", "oneinch"]))
    pixel = CAMERAS[cam].pixel_size_um
    return Case(
        family=family,
        seed=seed,
        n_photos=int(rng.integers(n[0], n[1] + 1)),
        camera=cam,
        long_side=long_side,
        overlap=_uniform(rng, 0.70, 0.85),
        height_m=_uniform(rng, 80.0, 200.0),
        tilt_deg=_uniform(rng, 1.0, 5.0),
        kappa_deg=_uniform(rng, 2.0, 10.0),
        relief_m=_uniform(rng, 2.0, 15.0),
        noise_um=pixel * _uniform(rng, 0.5, 1.0),
        control=str(rng.choice(LAYOUTS)),
        control_every=int(rng.integers(4, 9)),
    )


def _family_cases(family: str, count: int, first_seed: int) -> Iterator[Case]:
    """``count`` draws of a family's parameters (seeds first_seed, ...)."""
    for k in range(count):
        seed = first_seed + k
        rng = np.random.default_rng(10_000 + seed)
        if family == "film":
            yield _film(rng, family, seed)
        elif family == "film-long":
            yield replace(
                _film(rng, family, seed, camera="film152", n=(60, 120)),
                control="every_k_models",
                control_every=int(rng.integers(4, 8)),
            )
        elif family == "drone-along":
            yield _drone(rng, family, seed, "along")
        elif family == "drone-across":
            yield _drone(rng, family, seed, "across")
        elif family == "drone-long":
            yield replace(
                _drone(rng, family, seed, str(rng.choice(["along", "across"])), n=(90, 120)),
                control="every_k_models",
            )
        elif family == "corridor":
            base = (
                _film(rng, family, seed)
                if rng.uniform() < 0.5
                else _drone(rng, family, seed, "across")
            )
            yield replace(base, line=True)
        elif family == "blunders":
            base = (
                _film(rng, family, seed)
                if rng.uniform() < 0.5
                else _drone(rng, family, seed, str(rng.choice(["along", "across"])))
            )
            yield replace(
                base,
                control=str(rng.choice(["ends", "fig4", "every_k_models"])),
                image_blunders=int(rng.integers(1, 4)),
                control_blunders=int(rng.integers(0, 2)),
            )
        elif family == "camera":
            base = (
                _film(rng, family, seed)
                if k % 2 == 0
                else _drone(rng, family, seed, str(rng.choice(["along", "across"])))
            )
            yield replace(base, camera_error_um=_uniform(rng, 10.0, 50.0))
        else:
            raise ValueError(f"unknown family {family!r}")


FAMILIES = {
    "film": 14,
    "film-long": 6,
    "drone-along": 12,
    "drone-across": 12,
    "drone-long": 6,
    "corridor": 8,
    "blunders": 8,
    "camera": 12,
}
QUICK = {"film": 3, "drone-along": 3, "drone-across": 2, "corridor": 2, "blunders": 2}


def simulate(case: Case) -> SimulatedStrip:
    """The simulated strip of a case, its gross errors included."""
    return simulate_strip(
        case.n_photos,
        preset=camera_preset(
            case.camera,
            long_side=case.long_side,
            forward_overlap=case.overlap,
            flying_height_m=case.height_m,
            tilt_deg=case.tilt_deg,
            kappa_deg=case.kappa_deg,
            relief_m=case.relief_m,
            noise_um=case.noise_um,
            line=case.line,
        ),
        crs="EPSG:2180",
        centre_lonlat=(19.5, 52.0),
        heading_deg=float(np.random.default_rng(case.seed).uniform(0.0, 360.0)),
        seed=case.seed,
        control=case.control,
        control_every=case.control_every,
        image_blunders=case.image_blunders,
        control_blunders=case.control_blunders,
        camera_errors=case.camera_errors(),
    )


def valid(sim: SimulatedStrip) -> tuple[bool, str]:
    """Every pair: >= 12 common points over >= 55 % of the format across."""
    from strip_aerotri.strip.chaining import pair_rows

    obs = sim.observations
    model, _, row_l, _ = pair_rows(obs, np.arange(obs.n_photos))
    n_pairs = obs.n_photos - 1
    counts = np.bincount(model, minlength=n_pairs)
    if counts.min() < 12:
        return False, f"a pair with {counts.min()} common points"
    y = obs.xy[row_l, 1]
    lo = np.full(n_pairs, np.inf)
    hi = np.full(n_pairs, -np.inf)
    np.minimum.at(lo, model, y)
    np.maximum.at(hi, model, y)
    spread = (hi - lo) / sim.preset.format_mm[1]
    if spread.min() < 0.55:
        return False, f"a pair's points span {spread.min():.0%} across"
    return True, ""


def _rmse(diff: np.ndarray) -> tuple[float, float]:
    """Plan and height RMSE of (n, 3) differences (NaN rows left out)."""
    plan = np.isfinite(diff[:, :2]).all(axis=1)
    height = np.isfinite(diff[:, 2])
    return (
        float(np.sqrt(np.mean(np.sum(diff[plan, :2] ** 2, axis=1)))),
        float(np.sqrt(np.mean(diff[height, 2] ** 2))),
    )


def control_in_local(sim: SimulatedStrip) -> tuple[np.ndarray, np.ndarray]:
    """Point index and local east-north-up coordinates (NaN where not given)
    of the control and check rows."""
    truth = sim.truth
    lookup = {p: i for i, p in enumerate(sim.observations.point_ids)}
    index = np.array([lookup[p] for p in sim.control.point_ids], dtype=np.intp)
    xyz = np.asarray(sim.control.xyz, dtype=np.float64)
    filled = np.where(np.isnan(xyz), truth.points_crs[index], xyz)
    crs = GroundCRS.from_user_input(sim.crs)
    local = truth.local_to_ecef.ecef2local(crs.to_ecef(filled))
    return index, np.where(np.isnan(xyz), np.nan, local)


def reference_bundle(
    sim: SimulatedStrip, *, oracle: bool = False, camera: dict[str, float] | None = None
) -> tuple[float, float]:
    """Check-point RMSE (plan, height) of the package's bundle adjustment
    from the truth, local frame: on the same observations with its data
    snooping (:func:`strip_aerotri.bundle.refine.refine_frame`), or with
    ``oracle`` on the observations without the simulated blunders and no
    tests (what a perfect blunder detection would leave); ``camera`` (the
    simulated camera errors) corrects the observations first: a bundle given
    the true camera."""
    obs = sim.observations
    if camera is not None:
        from strip_aerotri.geometry.camera_model import BROWN_PARAMETERS, brown_correction

        values = np.array([camera.get(n, 0.0) for n in BROWN_PARAMETERS])
        obs = replace(obs, xy=obs.xy + brown_correction(obs.xy, values, obs.principal_distance))
    truth = sim.truth
    index, local = control_in_local(sim)
    kinds = np.array([k.value for k in sim.control.kind])
    blunder_obs = np.asarray(truth.blunder_observations if oracle else (), dtype=np.intp)
    bad_points = {sim.control.point_ids[r] for r in truth.blunder_control} if oracle else set()
    if blunder_obs.size:
        keep = np.ones(obs.photo.shape[0], dtype=bool)
        keep[blunder_obs] = False
        obs = type(obs)(
            photo_ids=obs.photo_ids,
            point_ids=obs.point_ids,
            photo=obs.photo[keep],
            point=obs.point[keep],
            xy=obs.xy[keep],
            sigma=obs.sigma[keep],
            principal_distance=obs.principal_distance,
        )
    n = obs.n_points
    control_xyz = np.full((n, 3), np.nan)
    control_sigma = np.full((n, 3), np.inf)
    use = (kinds != "check") & ~np.isin(np.asarray(sim.control.point_ids), list(bad_points))
    control_xyz[index[use]] = local[use]
    sig = np.column_stack([sim.control.sigma_xy, sim.control.sigma_xy, sim.control.sigma_h])
    control_sigma[index[use]] = sig[use]
    control_sigma[np.isnan(control_xyz)] = np.inf
    if oracle:
        res = bundle_adjust(
            obs,
            truth.photo_centres_local,
            truth.photo_rotations_local,
            truth.points_local,
            control_xyz=control_xyz,
            control_sigma=control_sigma,
            compute_precision=False,
        )
    else:
        res = refine_frame(
            obs,
            truth.photo_centres_local,
            truth.photo_rotations_local,
            truth.points_local,
            control_xyz=control_xyz,
            control_sigma=control_sigma,
        )
    check = index[kinds == "check"]
    return _rmse(truth.points_local[check] - res.points[check])


@dataclass
class Outcome:
    case: Case
    ok: bool = False
    error: str = ""
    strip: tuple[float, float] = (math.nan, math.nan)
    refined: tuple[float, float] = (math.nan, math.nan)
    reference: tuple[float, float] = (math.nan, math.nan)
    oracle: tuple[float, float] = (math.nan, math.nan)
    selfcal: tuple[float, float] = (math.nan, math.nan)  # refined, self_calibration "auto"
    true_camera: tuple[float, float] = (math.nan, math.nan)  # reference, the camera known
    seconds: float = math.nan

    @property
    def ratio(self) -> tuple[float, float]:
        return tuple(s / r for s, r in zip(self.strip, self.reference, strict=True))

    @property
    def oracle_ratio(self) -> tuple[float, float]:
        return tuple(s / r for s, r in zip(self.strip, self.oracle, strict=True))

    @property
    def refined_ratio(self) -> tuple[float, float]:
        return tuple(s / r for s, r in zip(self.refined, self.reference, strict=True))

    @property
    def selfcal_ratio(self) -> tuple[float, float]:
        return tuple(s / r for s, r in zip(self.selfcal, self.true_camera, strict=True))


def run_case(
    case: Case,
    *,
    refine: bool = True,
    models: str = "dependent",
    auto: bool = False,
    weights: str = "given",
) -> Outcome:
    """Strip method, its bundle refinement and the reference on one case
    (``weights = "estimated"``: the refinements estimate the groups' weights)."""
    vce = weights == "estimated"
    out = Outcome(case)
    sim = simulate(case)
    try:
        out.reference = reference_bundle(sim)
    except GeometryError:  # uncorrected camera errors may fail the reference's control
        if not case.camera_error_um:
            raise
    out.oracle = (
        reference_bundle(sim, oracle=True)
        if sim.truth.blunder_observations or sim.truth.blunder_control
        else out.reference
    )
    lines = [LineSpec(point_ids=tuple(ids), weight=w) for ids, w in sim.lines]
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = triangulate(
                sim.observations,
                sim.control,
                sim.crs,
                lines=lines,
                strip_options=StripOptions(models=models),
            )
            out.seconds = time.perf_counter() - t0
            out.strip = (result.check_statistics.rmse_plan, float(result.check_statistics.rmse[2]))
            errors = case.camera_errors()
            if refine:
                try:
                    refined = refine_bundle(result, variance_components=vce)  # as the run does
                    stats = refined.check_statistics
                    out.refined = (stats.rmse_plan, float(stats.rmse[2]))
                except GeometryError:  # its control tests may stop on camera errors
                    if errors is None:
                        raise
            if errors is not None or auto:
                out.true_camera = (
                    out.refined if errors is None else reference_bundle(sim, camera=errors)
                )
                calibrated = refine_bundle(
                    result, self_calibration=SelfCalibration("auto"), variance_components=vce
                )
                stats = calibrated.check_statistics
                out.selfcal = (stats.rmse_plan, stats.rmse[2])
        out.ok = True
    except Exception as exc:  # every failure is a result of the sweep
        out.error = f"{type(exc).__name__}: {exc}"
    return out


def cases(
    families: dict[str, int], max_tries: int = 5, offset: int = 0
) -> Iterator[tuple[Case, SimulatedStrip | None, str]]:
    """Valid cases of each family, invalid draws replaced by later seeds
    (``offset`` shifts every seed: another draw of the same envelope)."""
    seed = offset
    for family, count in families.items():
        made = 0
        tries = 0
        for case in _family_cases(family, count * max_tries, 100 * len(family) + seed):
            if made == count:
                break
            tries += 1
            try:
                sim = simulate(case)
            except ValueError as exc:
                yield case, None, f"simulation: {exc}"
                continue
            ok, why = valid(sim)
            if not ok:
                yield case, None, why
                continue
            made += 1
            yield case, sim, ""
        seed += 1000


def _f(values) -> str:
    return " ".join(f"{v:6.3f}" if np.isfinite(v) else "   n/a" for v in values)


def summarise(outcomes: list[Outcome]) -> None:
    fams = sorted({o.case.family for o in outcomes}, key=list(FAMILIES).index)
    print()
    blundered = [
        o for o in outcomes if o.ok and (o.case.image_blunders or o.case.control_blunders)
    ]
    if blundered:
        r = np.array([o.oracle_ratio for o in blundered])
        print(
            f"\nwith blunders, strip / oracle bundle (blunders removed, no tests): median "
            f"{np.median(r[:, 0]):.2f} {np.median(r[:, 1]):.2f}, largest {r[:, 0].max():.2f} "
            f"{r[:, 1].max():.2f} over {len(blundered)} cases"
        )
    print(
        f"{'family':14s} {'cases':>5s} {'ok':>4s}  strip/bundle plan, height: median  max"
        "   refined/bundle: median  max"
    )
    clean = [o for o in outcomes if o.ok and not o.case.camera_error_um and o.selfcal[0] > 0]
    if clean:
        r = np.array([o.selfcal_ratio for o in clean])
        print(
            f"without camera errors, refined with self_calibration = \"auto\" / without: "
            f"median {np.median(r[:, 0]):.3f} {np.median(r[:, 1]):.3f}, largest "
            f"{r[:, 0].max():.3f} {r[:, 1].max():.3f} over {len(clean)} cases"
        )
    cams = [o for o in outcomes if o.ok and o.case.camera_error_um]
    if cams:
        r = np.array([o.selfcal_ratio for o in cams])
        print(
            f"camera errors, refined with self_calibration = \"auto\" / bundle given the true "
            f"camera: median {np.median(r[:, 0]):.2f} {np.median(r[:, 1]):.2f}, largest "
            f"{r[:, 0].max():.2f} {r[:, 1].max():.2f} over {len(cams)} cases"
        )
    for fam in [*fams, "all"]:
        sel = [o for o in outcomes if fam in ("all", o.case.family)]
        ok = [o for o in sel if o.ok]
        r = np.array([o.ratio for o in ok]) if ok else np.full((1, 2), np.nan)
        rr = np.array([o.refined_ratio for o in ok]) if ok else np.full((1, 2), np.nan)
        with warnings.catch_warnings():  # a family may have no reference (camera errors)
            warnings.simplefilter("ignore", RuntimeWarning)
            print(
                f"{fam:14s} {len(sel):5d} {len(ok):4d}  "
                f"{np.nanmedian(r[:, 0]):5.2f} {np.nanmedian(r[:, 1]):5.2f}  "
                f"{np.nanmax(r[:, 0]):5.2f} {np.nanmax(r[:, 1]):5.2f}      "
                f"{np.nanmedian(rr[:, 0]):5.2f} {np.nanmedian(rr[:, 1]):5.2f}  "
                f"{np.nanmax(rr[:, 0]):5.2f} {np.nanmax(rr[:, 1]):5.2f}"
            )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the CI subset")
    parser.add_argument("--family", action="append", help="only these families")
    parser.add_argument("--no-refine", action="store_true", help="skip the bundle refinement")
    parser.add_argument(
        "--models",
        choices=["dependent", "independent"],
        default="dependent",
        help="how the strips are formed ([adjustment] models)",
    )
    parser.add_argument(
        "--offset", type=int, default=0, help="shift every seed (another draw of the envelope)"
    )
    parser.add_argument(
        "--scale", type=int, default=1, help="this many times the cases per family"
    )
    parser.add_argument(
        "--auto",
        action="store_true",
        help='also refine every case with self_calibration = "auto" (against without)',
    )
    parser.add_argument(
        "--weights",
        choices=["given", "estimated"],
        default="given",
        help="the refinements' observation weights ([adjustment] weights)",
    )
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="print invalid draws and tracebacks"
    )
    args = parser.parse_args(argv)
    families = dict(QUICK if args.quick else FAMILIES)
    if args.family:
        families = {f: FAMILIES[f] for f in args.family}
    families = {f: n * args.scale for f, n in families.items()}
    outcomes: list[Outcome] = []
    print(
        f"{'#':>3s} {'case':62s} {'strip plan/H':>13s} {'refined':>13s} {'bundle':>13s} "
        f"{'ratio':>11s} {'s':>5s}"
    )
    t0 = time.perf_counter()
    for case, sim, why in cases(families, offset=args.offset):
        if sim is None:
            if args.verbose:
                print(f"    invalid draw {case.label}: {why}")
            continue
        out = run_case(
            case,
            refine=not args.no_refine,
            models=args.models,
            auto=args.auto,
            weights=args.weights,
        )
        outcomes.append(out)
        status = _f(out.ratio) if out.ok else "FAILED"
        print(
            f"{len(outcomes):3d} {case.family + ' ' + case.label:62.62s} {_f(out.strip)} "
            f"{_f(out.refined)} {_f(out.reference)} {status:>11s} {out.seconds:5.2f}"
        )
        if not out.ok:
            print(f"      {out.error[:200]}")
        elif case.camera_error_um or args.auto:
            against = "bundle given the true camera" if case.camera_error_um else "without"
            print(
                f"      self_calibration auto {_f(out.selfcal)}, {against} "
                f"{_f(out.true_camera)}, ratio {_f(out.selfcal_ratio)}"
            )
    summarise(outcomes)
    print(f"\n{len(outcomes)} cases in {time.perf_counter() - t0:.0f} s")
    return 0 if all(o.ok for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
