"""Speed of strip formation and of the whole triangulation against strip size.

Run from the repository root::

    python benchmarks/bench_strip.py             # 10, 100, 1000, 5000 photos
    python benchmarks/bench_strip.py --quick     # 10, 100, 1000 photos
    python benchmarks/bench_strip.py --profile 1000x100

Strips are generated here by a vectorised generator (flat Cartesian world,
vertical photos with 1.5° tilts, 60 % forward overlap, evenly spread points
with relief, 5 µm image noise), because the package's simulator is built for realism
rather than for millions of observations.  For each size the script times
:func:`strip_aerotri.strip.chaining.form_strip` and the full
:func:`strip_aerotri.pipeline.triangulate` (strip formation plus the ground
stage on control every 10 photos, local Cartesian ground system, projected
route, polynomial type 3 over one section per ``--photos-per-section``
photos, 20 by default: two control stations a section, docs/ground.md
"Long strips"; 0 for J's single polynomial), the median of a few runs, and
prints:

* ``form wall`` / ``form cpu``: wall-clock and CPU seconds of ``form_strip``
  with its defaults (robust start and gross-error tests on); ``no tests``:
  wall-clock seconds with ``BlunderOptions(action="off")``; ``triangulate``: wall-clock
  seconds of the whole run (``n/a`` where the ground stage refuses, with
  its reason printed below the table);
* pair-points per second (million): rows of the relative orientation (a
  point measured on both photos of a pair) per wall-clock second of
  ``form_strip`` (``M/s form``) and of the whole ``triangulate``, the core
  without file I/O (``M/s core``);
* ``sec``: the sections of the polynomials; ``RMSE m``: root mean square
  3D error of the triangulated points against the generator's truth;
* log-log slopes of the time against the number of photos and against the
  points per pair.

``--profile PHOTOSxPOINTS`` prints the cProfile hotspots of one
``form_strip`` call instead.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import statistics
import time
import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from strip_aerotri.blunders import BlunderOptions
from strip_aerotri.errors import StripAerotriError, StripAerotriWarning
from strip_aerotri.ground.polynomials import GroundOptions
from strip_aerotri.observations import ControlPoints, ControlType, ImageObservations
from strip_aerotri.pipeline import triangulate
from strip_aerotri.strip.chaining import StripOptions, form_strip, pair_rows

C_MM = 152.0
HALF_FORMAT_MM = 115.0
HEIGHT_M = 1200.0
BASE_M = (1.0 - 0.6) * 2 * HALF_FORMAT_MM * HEIGHT_M / C_MM  # 60 % overlap: 726 m


def make_strip(n_photos: int, points_per_photo: int, seed: int = 0, noise_mm: float = 0.005):
    """Strip flown along +X; returns observations, control, truth points.

    Image coordinates carry N(0, ``noise_mm``) noise (5 µm by default: the
    robust start of the relative orientation iterates longer on noisy data
    than on exact data, so noise-free timings would flatter it).

    Points are spread evenly (jittered cells) over the strip with a density
    that puts about ``points_per_photo`` on each photo; with 60 % overlap a
    pair shares about 60 % of them and a triple overlap about 20 %.
    """
    rng = np.random.default_rng(seed)
    scale = HEIGHT_M / C_MM
    along_half = HALF_FORMAT_MM * scale  # footprint half-length (m)
    across_half = 0.9 * HALF_FORMAT_MM * scale
    centres = np.column_stack(
        [
            np.arange(n_photos) * BASE_M + rng.uniform(-5, 5, n_photos),
            rng.uniform(-5, 5, n_photos),
            HEIGHT_M + rng.uniform(-5, 5, n_photos),
        ]
    )
    tilts = np.clip(rng.normal(0.0, 1.5, (n_photos, 3)), -3.0, 3.0)
    rotations = Rotation.from_euler("XYZ", tilts, degrees=True).as_matrix()

    length = (n_photos - 1) * BASE_M + 2 * along_half
    density = points_per_photo / (2 * along_half)  # points per metre of strip
    n_pts = max(int(density * length), 8)
    # stratified along the strip (one point per cell, jittered): every triple
    # overlap gets its share of tie points, even in strips of thousands of photos
    cell = length / n_pts
    x = -along_half + cell * (np.arange(n_pts) + rng.uniform(0.0, 1.0, n_pts))
    ground = np.column_stack(
        [x, rng.uniform(-across_half, across_half, n_pts), rng.normal(0.0, 30.0, n_pts)]
    )

    # Candidate observations: for each photo the points within its footprint
    # along the strip (a contiguous range of the sorted x), then the format test.
    lo = np.searchsorted(x, centres[:, 0] - 1.2 * along_half)
    hi = np.searchsorted(x, centres[:, 0] + 1.2 * along_half)
    counts = hi - lo
    photo = np.repeat(np.arange(n_photos), counts)
    offset = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    point = np.repeat(lo, counts) + offset
    v = np.einsum("nji,nj->ni", rotations[photo], ground[point] - centres[photo])
    xy = -C_MM * v[:, :2] / v[:, 2:3]
    inside = (np.abs(xy) <= HALF_FORMAT_MM).all(axis=1) & (v[:, 2] < 0)
    photo, point, xy = photo[inside], point[inside], xy[inside]
    xy = xy + rng.normal(0.0, noise_mm, xy.shape)

    photo_ids = tuple(str(1000 + i) for i in range(n_photos))
    point_ids = tuple(f"P{i:08d}" for i in range(n_pts))
    k = photo.size
    obs = ImageObservations(
        photo_ids=photo_ids,
        point_ids=point_ids,
        photo=photo.astype(np.intp),
        point=point.astype(np.intp),
        xy=xy,
        sigma=np.full(k, 0.005),
        principal_distance=C_MM,
        source_line=np.zeros(k, dtype=np.intp),
    )

    # Full control: the points nearest to the strip's edges every 10 photos
    # and at the last photo (J: two full points and more).
    stations = np.unique(np.r_[np.arange(0, n_photos, 10), n_photos // 2, n_photos - 1])
    chosen = []
    for s in stations:  # a few dozen stations at most
        near = np.flatnonzero(np.abs(x - centres[s, 0]) < 0.3 * BASE_M)
        if near.size:
            chosen += [near[np.argmax(ground[near, 1])], near[np.argmin(ground[near, 1])]]
    chosen = np.unique(chosen)
    control = ControlPoints(
        point_ids=tuple(point_ids[i] for i in chosen),
        xyz=ground[chosen],
        kind=tuple(ControlType.FULL for _ in chosen),
        sigma_xy=np.full(chosen.size, 0.02),
        sigma_h=np.full(chosen.size, 0.02),
        source_line=np.zeros(chosen.size, dtype=np.intp),
    )
    return obs, control, ground


def median_time(func, repeats: int) -> tuple[float, float]:
    """Median wall-clock and CPU seconds of ``func()`` over ``repeats`` runs."""
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        func()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


def slope(x, y) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def run(
    sizes, points, repeats: int, noise_mm: float = 0.005, photos_per_section: int = 20
) -> None:
    options = StripOptions()
    no_tests = BlunderOptions(action="off")
    rows = []
    refused: set[str] = set()
    print(
        f"{'photos':>6} {'pts/photo':>9} {'pts/pair':>8} {'pair-pts':>10} {'generate':>9} "
        f"{'form wall':>10} {'form cpu':>9} {'no tests':>9} {'triangulate':>11} "
        f"{'M/s form':>9} {'M/s core':>9} {'sec':>4} {'RMSE m':>7}"
    )
    for n in sizes:
        for k in points:
            t0 = time.perf_counter()
            obs, control, truth = make_strip(n, k, noise_mm=noise_mm)
            sections = max(n // photos_per_section, 1) if photos_per_section else 1
            ground_options = GroundOptions(route="projected", polynomial=3, sections=sections)
            t_gen = time.perf_counter() - t0
            model, *_ = pair_rows(obs, np.arange(obs.n_photos))
            n_pair_points = model.size
            per_pair = n_pair_points / (n - 1)
            reps = repeats if n_pair_points < 500_000 else 1
            t_form, c_form = median_time(lambda obs=obs: form_strip(obs, options), reps)
            c_plain, _ = median_time(
                lambda obs=obs: form_strip(obs, options, blunders=no_tests), reps
            )
            results = []
            try:
                t_tri, _ = median_time(
                    lambda obs=obs, control=control, go=ground_options, out=results: out.append(
                        triangulate(obs, control, "local", ground_options=go)
                    ),
                    reps,
                )
            except StripAerotriError as exc:
                # The ground stage refuses (the reason is printed below).
                t_tri = float("nan")
                refused.add(f"{type(exc).__name__}: {str(exc).split(';')[0][:110]}")
            rows.append((n, k, per_pair, t_form, t_tri))
            if results:
                error = results[-1].ground.points - truth
                rmse = float(np.sqrt(np.nanmean(np.sum(error**2, axis=1))))
                rmse_text = f"{rmse:7.3f}"
            else:
                rmse_text = f"{'-':>7}"
            tri_text = f"{t_tri:10.3f}s" if np.isfinite(t_tri) else f"{'n/a':>11}"
            core_text = (
                f"{n_pair_points / t_tri / 1e6:9.3f}" if np.isfinite(t_tri) else f"{'n/a':>9}"
            )
            print(
                f"{n:6d} {k:9d} {per_pair:8.0f} {n_pair_points:10d} {t_gen:8.2f}s "
                f"{t_form:9.3f}s {c_form:8.3f}s {c_plain:8.3f}s {tri_text} "
                f"{n_pair_points / t_form / 1e6:9.3f} {core_text} {sections:4d} {rmse_text}",
                flush=True,
            )
    data = np.array(rows)
    print()
    for reason in sorted(refused):
        print(f"triangulate n/a: {reason}")
    for k in points:
        sel = (data[:, 1] == k) & (data[:, 0] >= 100)
        tri = sel & np.isfinite(data[:, 4])
        if sel.sum() >= 2:
            print(
                f"slope log(time) / log(photos), {k} pts/photo, >= 100 photos: "
                f"form_strip (wall) {slope(data[sel, 0], data[sel, 3]):.2f}"
                + (
                    f", triangulate {slope(data[tri, 0], data[tri, 4]):.2f}"
                    if tri.sum() >= 2
                    else ""
                )
            )
    for n in sizes:
        sel = (data[:, 0] == n) & np.isfinite(data[:, 4])
        if sel.sum() >= 2:
            print(
                f"slope log(time) / log(points per pair), {n} photos: "
                f"form_strip (wall) {slope(data[sel, 2], data[sel, 3]):.2f}, "
                f"triangulate {slope(data[sel, 2], data[sel, 4]):.2f}"
            )


def profile(spec: str, top: int) -> None:
    n, k = (int(v) for v in spec.lower().split("x"))
    obs, _, _ = make_strip(n, k)
    form_strip(obs)  # warm up
    prof = cProfile.Profile()
    prof.enable()
    form_strip(obs)
    prof.disable()
    out = io.StringIO()
    pstats.Stats(prof, stream=out).sort_stats("tottime").print_stats(top)
    print(out.getvalue())


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="up to 1000 photos only")
    parser.add_argument("--photos", help="comma-separated strip lengths")
    parser.add_argument("--points", default="30,100,300,500", help="points per photo")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--noise-um", type=float, default=5.0, help="image noise, µm")
    parser.add_argument(
        "--photos-per-section",
        type=int,
        default=20,
        help="photos per section of the polynomials (0: one polynomial)",
    )
    parser.add_argument("--profile", metavar="PHOTOSxPOINTS")
    parser.add_argument("--top", type=int, default=25, help="lines of the profile")
    args = parser.parse_args(argv)
    if args.profile:
        profile(args.profile, args.top)
        return
    sizes = (
        [int(v) for v in args.photos.split(",")]
        if args.photos
        else [10, 100, 1000] + ([] if args.quick else [5000])
    )
    points = [int(v) for v in args.points.split(",")]
    # Strips of hundreds of kilometres on a 1.6 km wide band of control: the
    # ground stage rightly warns that the cross tilt is weak; not the subject here.
    warnings.simplefilter("ignore", StripAerotriWarning)
    run(sizes, points, args.repeats, args.noise_um / 1000.0, args.photos_per_section)


if __name__ == "__main__":
    main()
