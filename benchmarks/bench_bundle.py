"""Strip method versus bundle refinement: time, memory and accuracy.

Run from the repository root::

    python benchmarks/bench_bundle.py              # the full grid (about 10 minutes)
    python benchmarks/bench_bundle.py --quick      # 12 and 100 photos only
    python benchmarks/bench_bundle.py --photos 12 100 --points 30 100

For every strip (M photos, n points per photo) a synthetic strip with a
known truth is generated (vectorised, ``crs = "local"``; film camera
c = 152.87 mm at 1:8000, 60 % overlap, 5 µm image noise, full control of
2 cm on both sides every 4 models, check points with exact coordinates),
then, in this one process and on the same data:

* the strip method, :func:`strip_aerotri.pipeline.triangulate` (projected
  route, polynomial type 3 over one section per ``--models-per-section``
  models, 6 by default: about 1.5 control stations a section, so that a
  long strip's bend is followed, docs/ground.md "Long strips"; 0: J's
  single polynomial; blunder tests in "report" mode);
* the bundle refinement of its result, :func:`strip_aerotri.bundle.refine.refine_bundle`
  (also in "report" mode), with and without the precision (the selected
  inverse of the banded normal matrix for the standard deviations);

and prints wall time, peak traced memory (``tracemalloc``, numpy buffers
included), their ratio, observations per second, and the check-point RMSE
of both against the truth.  Log-log slopes of time against photos and against
points per photo follow.  pycolmap's bundle adjuster is timed on the same
problem when it can be imported (optional, never a dependency).
"""

from __future__ import annotations

import argparse
import gc
import math
import platform
import sys
import time
import tracemalloc
from dataclasses import dataclass

import numpy as np

from strip_aerotri.blunders import BlunderOptions
from strip_aerotri.bundle.refine import refine_bundle
from strip_aerotri.errors import StripAerotriError
from strip_aerotri.geometry.rotation import matrix_from_opk
from strip_aerotri.ground.polynomials import GroundOptions
from strip_aerotri.observations import ControlPoints, ControlType, ImageObservations
from strip_aerotri.pipeline import triangulate
from strip_aerotri.results import AccuracyStatistics

C_MM = 152.87
SCALE = 8000.0  # 1:8000
HALF_FORMAT_MM = 115.0
HEIGHT_M = C_MM * SCALE / 1000.0  # 1222.96 m above the terrain
BASE_M = 0.4 * 2 * HALF_FORMAT_MM * SCALE / 1000.0  # 60 % overlap: 736 m
FOOT_M = 2 * HALF_FORMAT_MM * SCALE / 1000.0  # 1840 m
TERRAIN_M = 150.0
RELIEF_M = 60.0
IMAGE_NOISE_MM = 0.005
CONTROL_NOISE_M = 0.02
CONTROL_EVERY = 4  # models between full control pairs
#: Default grid; ``--with-5000`` adds 5000 photos (docs/bundle.md).
GRID = [(12, 30), (12, 100), (12, 300), (12, 2000), (100, 30), (100, 100), (100, 300)]
GRID += [(1000, 30), (1000, 100), (1000, 300)]


@dataclass
class Synthetic:
    observations: ImageObservations
    control: ControlPoints
    points_truth: np.ndarray  # (P, 3) in the order of observations.point_ids
    centres_truth: np.ndarray
    rotations_truth: np.ndarray


def _terrain(xy: np.ndarray, phase: np.ndarray) -> np.ndarray:
    x, y = xy[:, 0], xy[:, 1]
    return TERRAIN_M + RELIEF_M * (
        0.5 * np.sin(2 * np.pi * x / 2500.0 + phase[0])
        + 0.3 * np.sin(2 * np.pi * y / 1800.0 + phase[1])
        + 0.2 * np.sin(2 * np.pi * (x + y) / 3100.0 + phase[2])
    )


def make_strip(n_photos: int, points_per_photo: int, seed: int = 0) -> Synthetic:
    """A straight strip along +X of a local site system, vectorised.

    Points are spread uniformly over the strip's area at a density that puts
    ``points_per_photo`` on each photo on average (each point is on 2-3
    photos); the observations are the collinearity equations plus noise.
    """
    rng = np.random.default_rng(seed)
    m = n_photos
    phase = rng.uniform(0, 2 * np.pi, 3)
    centres = np.column_stack(
        [
            np.arange(m) * BASE_M + rng.uniform(-10, 10, m),
            rng.uniform(-10, 10, m),
            TERRAIN_M + HEIGHT_M + rng.uniform(-10, 10, m),
        ]
    )
    opk = np.clip(rng.normal(0, 1, (m, 3)), -2, 2) * np.radians([1.5, 1.5, 2.0])
    rotations = matrix_from_opk(opk)
    half_y = 0.47 * FOOT_M
    length = (m - 1) * BASE_M + FOOT_M
    # Tie points: six per nadir in the triple overlap (Gruber positions, y =
    # +-0.35 F and 0, two each), each seen on three photos; the rest uniform.
    nadir = np.repeat(np.arange(m), 6) * BASE_M
    gruber = np.column_stack(
        [
            nadir + rng.uniform(-40, 40, nadir.size),
            np.tile([0.35, 0.35, 0.0, 0.0, -0.35, -0.35], m) * FOOT_M
            + rng.uniform(-40, 40, nadir.size),
        ]
    )
    density = max(points_per_photo - 18, 4) / (FOOT_M * 2 * half_y)
    n_pts = round(density * length * 2 * half_y)
    xy = np.vstack(
        [
            gruber,
            np.column_stack(
                [
                    rng.uniform(-FOOT_M / 2, (m - 1) * BASE_M + FOOT_M / 2, n_pts),
                    rng.uniform(-half_y, half_y, n_pts),
                ]
            ),
        ]
    )
    xy = xy[np.argsort(xy[:, 0], kind="stable")]
    points = np.column_stack([xy, _terrain(xy, phase)])
    # Candidate photos of each point: the ones whose nadir is within a footprint.
    first = np.floor((points[:, 0] - FOOT_M / 2 - 20.0) / BASE_M).astype(np.intp)
    cand = first[:, None] + np.arange(4)[None, :]
    ok = (cand >= 0) & (cand < m)
    cand_c = np.clip(cand, 0, m - 1)
    v = np.einsum("pkji,pkj->pki", rotations[cand_c], points[:, None, :] - centres[cand_c])
    img = -C_MM * v[..., :2] / v[..., 2:3]
    ok &= np.all(np.abs(img) < HALF_FORMAT_MM - 2.0, axis=2) & (v[..., 2] < 0)
    rays = ok.sum(axis=1)
    keep_pt = rays >= 2
    points, ok, img, cand = points[keep_pt], ok[keep_pt], img[keep_pt], cand[keep_pt]
    p_idx, slot = np.nonzero(ok)
    photo = cand[p_idx, slot]
    xy_obs = img[p_idx, slot] + rng.normal(0, IMAGE_NOISE_MM, (p_idx.size, 2))
    order = np.lexsort((p_idx, photo))
    photo_ids = tuple(f"{j + 1:06d}" for j in range(m))
    point_ids = tuple(f"P{i + 1:07d}" for i in range(points.shape[0]))
    obs = ImageObservations(
        photo_ids=photo_ids,
        point_ids=point_ids,
        photo=photo[order].astype(np.intp),
        point=p_idx[order].astype(np.intp),
        xy=xy_obs[order],
        sigma=np.full(order.size, 0.005),
        principal_distance=C_MM,
    )
    # Control: nearest point seen on >= 2 photos to (j B, +-0.35 FOOT) every
    # CONTROL_EVERY models and at the last photo; check points: 2 per model.
    targets = [*range(0, m, CONTROL_EVERY)]
    if targets[-1] != m - 1:
        targets.append(m - 1)
    target_xy = np.array(
        [(j * BASE_M, side * 0.35 * FOOT_M) for j in targets for side in (1.0, -1.0)]
    )
    control_idx = np.unique(_nearest(points[:, :2], target_xy))
    rest = np.setdiff1d(np.arange(points.shape[0]), control_idx)
    check_idx = np.sort(rng.choice(rest, size=min(rest.size, max(50, 2 * (m - 1))), replace=False))
    ids = [point_ids[i] for i in control_idx] + [point_ids[i] for i in check_idx]
    xyz = np.vstack(
        [
            points[control_idx] + rng.normal(0, CONTROL_NOISE_M, (control_idx.size, 3)),
            points[check_idx],
        ]
    )
    kinds = (ControlType.FULL,) * control_idx.size + (ControlType.CHECK,) * check_idx.size
    n_c = len(ids)
    control = ControlPoints(
        tuple(ids), xyz, kinds, np.full(n_c, CONTROL_NOISE_M), np.full(n_c, CONTROL_NOISE_M)
    )
    return Synthetic(obs, control, points, centres, rotations)


def _nearest(xy: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Index of the point nearest each target (points sorted by X)."""
    out = np.empty(len(targets), dtype=np.intp)
    for t, (x, y) in enumerate(targets):
        lo, hi = np.searchsorted(xy[:, 0], [x - 300.0, x + 300.0])
        d = np.hypot(xy[lo:hi, 0] - x, xy[lo:hi, 1] - y)
        out[t] = lo + int(np.argmin(d))
    return out


def check_rmse(points: np.ndarray, syn: Synthetic) -> AccuracyStatistics:
    lookup = {pid: i for i, pid in enumerate(syn.observations.point_ids)}
    is_check = np.array([k is ControlType.CHECK for k in syn.control.kind])
    idx = np.array([lookup[pid] for pid in np.asarray(syn.control.point_ids)[is_check]])
    return AccuracyStatistics.from_residuals(syn.points_truth[idx] - points[idx])


def measure(func, *, memory: bool):
    """Run ``func()``: result, wall time (s) and, with ``memory``, peak traced MB.

    Times are the best of up to three runs (fewer once 3 s are spent), taken
    without tracemalloc (it slows allocation-heavy code); with ``memory`` the
    function runs once more under tracemalloc.
    """
    elapsed = math.inf
    spent = 0.0
    for _ in range(3):  # best of up to three runs while they are short
        gc.collect()
        t0 = time.perf_counter()
        out = func()
        took = time.perf_counter() - t0
        elapsed = min(elapsed, took)
        spent += took
        if spent > 3.0:
            break
    peak = float("nan")
    if memory:
        del out
        gc.collect()
        tracemalloc.start()
        out = func()
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return out, elapsed, peak


def pycolmap_time(syn: Synthetic, result) -> float | None:
    """Seconds of pycolmap's bundle adjuster on the same image observations.

    The strip result (site system) gives the initial values.  COLMAP's camera
    looks along +z with image y down: ``cam_from_world`` rotation is
    ``diag(1, -1, -1) @ R.T`` and the image coordinates are ``(x, -y)`` plus a
    principal point of 115 (mm used as pixel units).  Intrinsics are held
    fixed, there is no ground control (COLMAP fixes the gauge itself) and no
    precision is computed, so the figure is a lower bound of what the same
    adjustment costs in a compiled, multi-threaded solver.  None when pycolmap
    cannot be imported.
    """
    try:
        import pycolmap
    except ImportError:
        return None
    pycolmap.logging.minloglevel = 2  # errors only
    obs = syn.observations
    flip = np.diag([1.0, -1.0, -1.0])
    rec = pycolmap.Reconstruction()
    camera = pycolmap.Camera(
        model="SIMPLE_PINHOLE",
        width=230,
        height=230,
        params=[obs.principal_distance, 115.0, 115.0],
        camera_id=1,
    )
    rec.add_camera_with_trivial_rig(camera)
    rot = result.ground.photo_rotations_enu
    centres = result.photo_centres
    uv = np.column_stack([obs.xy[:, 0] + 115.0, -obs.xy[:, 1] + 115.0])
    starts = obs.photo_slices()
    slot = np.arange(obs.photo.size) - starts[obs.photo]
    for j in range(obs.n_photos):
        r_cw = flip @ rot[j].T
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(r_cw), -r_cw @ centres[j])
        points2d = [pycolmap.Point2D(xy) for xy in uv[starts[j] : starts[j + 1]]]
        image = pycolmap.Image(
            name=obs.photo_ids[j], points2D=points2d, camera_id=1, image_id=j + 1
        )
        rec.add_image_with_trivial_frame(image, pose)
    order = np.argsort(obs.point, kind="stable")
    bounds = np.searchsorted(obs.point[order], np.arange(obs.n_points + 1))
    pts = result.points
    for i in range(obs.n_points):
        rows = order[bounds[i] : bounds[i + 1]]
        if rows.size < 2 or not np.all(np.isfinite(pts[i])):
            continue
        track = pycolmap.Track()
        for k in rows:
            track.add_element(int(obs.photo[k]) + 1, int(slot[k]))
        rec.add_point3D(pts[i], track)
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = False
    options.refine_principal_point = False
    options.refine_extra_params = False
    options.print_summary = False
    t0 = time.perf_counter()
    pycolmap.bundle_adjustment(rec, options)
    return time.perf_counter() - t0


def run(
    cases, *, memory: bool, precision_limit: int, seed: int, models_per_section: int = 6
) -> list[dict]:
    rows = []
    report = BlunderOptions(action="report")
    for m, n in cases:
        t0 = time.perf_counter()
        syn = make_strip(m, n, seed)
        t_gen = time.perf_counter() - t0
        obs = syn.observations
        k = obs.photo.size
        strip = None
        sections = max(1, (m - 1) // models_per_section) if models_per_section > 0 else 1
        for poly in (3, 1, 0):  # a lower type where the control cannot carry type 3
            try:
                strip, t_strip, mem_strip = measure(
                    lambda syn=syn, poly=poly, sections=sections: triangulate(
                        syn.observations,
                        syn.control,
                        "local",
                        ground_options=GroundOptions(
                            route="projected",
                            polynomial=poly,
                            sections=sections if poly > 0 else 1,
                        ),
                        blunders=report,
                    ),
                    memory=memory,
                )
                break
            except StripAerotriError as exc:
                print(f"  ({m} x {n}: polynomial type {poly} refused: {exc})")
        if strip is None:
            print(f"  ({m} x {n}: the strip method fails; no initial values, row skipped)")
            continue
        refined, t_bundle, mem_bundle = measure(
            lambda strip=strip: refine_bundle(strip, blunders=report, compute_precision=False),
            memory=memory,
        )
        precision = m <= precision_limit
        t_precision = float("nan")
        if precision:
            refined_p, t_precision, _ = measure(
                lambda strip=strip: refine_bundle(strip, blunders=report), memory=False
            )
            # the precision changes nothing else
            assert np.array_equal(refined_p.points, refined.points, equal_nan=True)
        s_strip = check_rmse(strip.points, syn)
        s_bundle = check_rmse(refined.points, syn)
        row = {
            "photos": m,
            "per_photo": round(k / m),
            "points": obs.n_points,
            "obs": k,
            "scalar_obs": refined.n_observations,
            "gen": t_gen,
            "t_strip": t_strip,
            "t_bundle": t_bundle,
            "t_precision": t_precision,
            "poly": poly,
            "sections": sections if poly > 0 else 1,
            "iterations": refined.iterations,
            "mem_strip": mem_strip,
            "mem_bundle": mem_bundle,
            "strip_plan": s_strip.rmse_plan,
            "strip_h": s_strip.rmse[2],
            "bundle_plan": s_bundle.rmse_plan,
            "bundle_h": s_bundle.rmse[2],
            "sigma0": refined.sigma0,
            "colmap": pycolmap_time(syn, strip),
        }
        rows.append(row)
        print_row(row)
        sys.stdout.flush()
    return rows


HEADER = (
    f"{'M':>5} {'pts/ph':>6} {'obs K':>7} {'strip s':>7} {'bundle s':>8} {'ratio':>5} "
    f"{'+prec s':>7} {'ratio':>5} {'strip obs/s':>11} {'bund obs/s':>10} "
    f"{'strip MB':>8} {'bund MB':>7} {'poly':>4} {'sec':>3} {'strip plan/h m':>15} "
    f"{'bundle plan/h m':>15} {'it':>2} {'colmap s':>8}"
)


def _f(value, fmt: str, width: int) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return f"{'-':>{width}}"
    return f"{value:>{width}{fmt}}"


def print_row(r: dict) -> None:
    print(
        f"{r['photos']:>5} {r['per_photo']:>6} {r['obs']:>7} {r['t_strip']:>7.2f} "
        f"{r['t_bundle']:>8.2f} {r['t_bundle'] / r['t_strip']:>5.1f} "
        f"{_f(r['t_precision'], '.2f', 7)} {_f(r['t_precision'] / r['t_strip'], '.1f', 5)} "
        f"{r['obs'] / r['t_strip']:>11.0f} {r['obs'] / r['t_bundle']:>10.0f} "
        f"{_f(r['mem_strip'], '.0f', 8)} {_f(r['mem_bundle'], '.0f', 7)} {r['poly']:>4} "
        f"{r['sections']:>3} {r['strip_plan']:>7.3f}/{r['strip_h']:<7.3f} "
        f"{r['bundle_plan']:>7.3f}/{r['bundle_h']:<7.3f} {r['iterations']:>2} "
        f"{_f(r['colmap'], '.2f', 8)}"
    )


def slopes(rows: list[dict]) -> None:
    """Log-log slopes of time against photos (fixed points per photo) and
    against points per photo (fixed photos)."""
    print("\nlog-log slopes of time (d log t / d log x):")
    keys = (
        ("t_strip", "strip method"),
        ("t_bundle", "bundle refinement"),
        ("t_precision", "bundle + precision"),
    )
    for key, label in keys:
        for n in sorted({r["per_photo"] for r in rows}):
            sel = [r for r in rows if r["per_photo"] == n and math.isfinite(r[key])]
            if len({r["photos"] for r in sel}) >= 2:
                x = np.log([r["photos"] for r in sel])
                y = np.log([r[key] for r in sel])
                print(f"  {label:<18} vs photos, ~{n:>4} pts/photo: {np.polyfit(x, y, 1)[0]:.2f}")
        for m in sorted({r["photos"] for r in rows}):
            sel = [r for r in rows if r["photos"] == m and math.isfinite(r[key])]
            if len({r["per_photo"] for r in sel}) >= 2:
                x = np.log([r["per_photo"] for r in sel])
                y = np.log([r[key] for r in sel])
                print(f"  {label:<18} vs pts/photo, {m:>5} photos: {np.polyfit(x, y, 1)[0]:.2f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="12 and 100 photos only")
    ap.add_argument("--photos", type=int, nargs="*", help="photo counts (with --points)")
    ap.add_argument("--points", type=int, nargs="*", help="points per photo")
    ap.add_argument(
        "--with-5000", action="store_true", help="add 5000 photos x 30 and x 100 points"
    )
    ap.add_argument(
        "--no-memory", action="store_true", help="skip tracemalloc (it slows numpy-light code)"
    )
    ap.add_argument(
        "--precision-limit",
        type=int,
        default=100_000,
        help="compute the bundle's standard deviations up to this many photos",
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--models-per-section",
        type=int,
        default=6,
        help="models per section of the strip method's polynomials (0: one polynomial)",
    )
    args = ap.parse_args(argv)
    if args.photos:
        cases = [(m, n) for m in args.photos for n in (args.points or [30])]
    elif args.quick:
        cases = [c for c in GRID if c[0] <= 100]
    else:
        cases = list(GRID)
    if args.with_5000:
        cases += [(5000, 30), (5000, 100)]
    print(
        f"python {platform.python_version()}, numpy {np.__version__}, "
        f"{platform.machine()}, {platform.processor() or platform.system()}"
    )
    try:
        import pycolmap

        print(f"pycolmap {pycolmap.__version__}: timed as an optional peer")
    except ImportError:
        print("pycolmap: not importable, skipped")
    print(
        "times in s; bundle = refinement without standard deviations, +prec = with them; "
        "ratio = that / strip;\nMB = peak traced memory; poly = polynomial type of the strip "
        "method, sec = its sections; plan/h = check-point RMSE vs truth (m);\n"
        "it = bundle iterations; colmap = "
        "pycolmap bundle_adjustment on the same observations (free network)\n"
    )
    print(HEADER)
    rows = run(
        cases,
        memory=not args.no_memory,
        precision_limit=args.precision_limit,
        seed=args.seed,
        models_per_section=args.models_per_section,
    )
    slopes(rows)
    big = [r for r in rows if r["obs"] >= 25_000]
    if big:
        worst = min(r["t_bundle"] / r["t_strip"] for r in big)
        print(f"\nsmallest bundle/strip time ratio at >= 25 000 observations: {worst:.1f}")
        with_p = [r["t_precision"] / r["t_strip"] for r in big if math.isfinite(r["t_precision"])]
        if with_p:
            print(f"the same with the bundle's precision: {min(with_p):.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
