"""The strip method against the bundle adjusters users would pick, side by side.

Run from the repository root (the peers are optional benchmark dependencies,
``pip install -r benchmarks/requirements-peers.txt``)::

    python benchmarks/bench_peers.py            # drone strips of 60, 300 and 1000 photos
    python benchmarks/bench_peers.py --quick    # 60 photos only
    python benchmarks/bench_peers.py --photos 60 300 1000 2000

Each case is a drone strip of :func:`strip_aerotri.simulate_strip` (1-inch
camera, 80 % overlap, about 100 points per photo, full control every 10
models, ``crs = "local"``: every
solver works in the same Cartesian site system), solved on the same image
observations and control by:

* **strip** - the strip method, the library call without file I/O
  (:func:`strip_aerotri.triangulate`);
* **cli** - ``stripaero run`` in a subprocess, report included;
* **strip+bundle** - the strip method with ``refine = "bundle"``;
* **ceres/strip** - Ceres through pycolmap's bundle adjuster, started from
  the strip method's result, the full control points held constant at their
  given coordinates (what a user of COLMAP does with ground control), the
  intrinsics fixed;
* **ceres/gnss** - the same started from GNSS-like centres (the truth plus
  3 cm), near-vertical attitudes (the heading plus 2 degrees of noise) and
  points intersected from those.

Printed per case: wall time (median of ``--repeat`` runs), check-point RMSE
in plan and height against the simulator's truth, and the time ratio to
the fastest solver whose accuracy is within 5 % of the best (plan and
height).  The machine is shared: run it when nothing else runs.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from strip_aerotri import StripAerotriWarning, simulate_strip, triangulate
from strip_aerotri.geometry.rotation import matrix_from_opk
from strip_aerotri.observations import ControlType


def check_rmse(points: np.ndarray, sim) -> tuple[float, float]:
    """Check-point RMSE (plan, height) of ``points`` (site system, P x 3)."""
    lookup = {pid: i for i, pid in enumerate(sim.observations.point_ids)}
    rows = [i for i, k in enumerate(sim.control.kind) if k is ControlType.CHECK]
    idx = np.array([lookup[sim.control.point_ids[i]] for i in rows])
    d = sim.control.xyz[rows] - points[idx]
    ok = np.isfinite(d).all(axis=1)
    d = d[ok]
    return float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))), float(
        np.sqrt(np.mean(d[:, 2] ** 2))
    )


def timed(func, repeat: int):
    """The last result and the median wall time of ``repeat`` calls."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = func()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def ceres(sim, centres: np.ndarray, rotations: np.ndarray, points: np.ndarray):
    """pycolmap's Ceres bundle adjuster from the given start; returns the
    adjusted points (site system) and the seconds of the solve alone."""
    import pycolmap

    pycolmap.logging.minloglevel = 3
    obs = sim.observations
    flip = np.diag([1.0, -1.0, -1.0])  # COLMAP's camera looks along +z, image y down
    rec = pycolmap.Reconstruction()
    half = 10.0  # image coordinates are mm; a principal point keeps them positive
    rec.add_camera_with_trivial_rig(
        pycolmap.Camera(
            model="SIMPLE_PINHOLE",
            width=int(2 * half),
            height=int(2 * half),
            params=[obs.principal_distance, half, half],
            camera_id=1,
        )
    )
    uv = np.column_stack([obs.xy[:, 0] + half, -obs.xy[:, 1] + half])
    starts = obs.photo_slices()
    slot = np.arange(obs.photo.size) - starts[obs.photo]
    for j in range(obs.n_photos):
        r_cw = flip @ rotations[j].T
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(r_cw), -r_cw @ centres[j])
        image = pycolmap.Image(
            name=obs.photo_ids[j],
            points2D=[pycolmap.Point2D(xy) for xy in uv[starts[j] : starts[j + 1]]],
            camera_id=1,
            image_id=j + 1,
        )
        rec.add_image_with_trivial_frame(image, pose)
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    given = {
        lookup[p]: sim.control.xyz[i]
        for i, (p, k) in enumerate(zip(sim.control.point_ids, sim.control.kind, strict=True))
        if k is ControlType.FULL and p in lookup
    }
    order = np.argsort(obs.point, kind="stable")
    bounds = np.searchsorted(obs.point[order], np.arange(obs.n_points + 1))
    config = pycolmap.BundleAdjustmentConfig()
    for j in range(obs.n_photos):
        config.add_image(j + 1)
    ids = np.full(obs.n_points, -1)
    for i in range(obs.n_points):
        rows = order[bounds[i] : bounds[i + 1]]
        start = given.get(i, points[i])
        if rows.size < 2 or not np.all(np.isfinite(start)):
            continue
        track = pycolmap.Track()
        for k in rows:
            track.add_element(int(obs.photo[k]) + 1, int(slot[k]))
        ids[i] = rec.add_point3D(np.asarray(start, dtype=float), track)
        if i in given:
            config.add_constant_point(int(ids[i]))
    config.set_constant_cam_intrinsics(1)
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = False
    options.refine_principal_point = False
    options.refine_extra_params = False
    options.print_summary = False
    adjuster = pycolmap.create_default_bundle_adjuster(options, config, rec)
    t0 = time.perf_counter()
    adjuster.solve()
    seconds = time.perf_counter() - t0
    out = np.full((obs.n_points, 3), np.nan)
    for i in np.flatnonzero(ids >= 0):
        out[i] = rec.points3D[int(ids[i])].xyz
    return out, seconds


def gnss_start(sim, rng: np.random.Generator):
    """Centres from GNSS (truth + 3 cm), near-vertical attitudes along the
    heading with 2 degrees of noise, points intersected from them (midpoint
    of the rays of each point's first and last photo)."""
    truth = sim.truth
    obs = sim.observations
    centres = truth.photo_centres_local + rng.normal(0.0, 0.03, truth.photo_centres_local.shape)
    opk = np.column_stack(
        [
            rng.normal(0.0, np.radians(2.0), obs.n_photos),
            rng.normal(0.0, np.radians(2.0), obs.n_photos),
            np.full(obs.n_photos, np.radians(90.0 - truth.heading_deg)),
        ]
    )
    rotations = matrix_from_opk(opk)
    rays = np.einsum(
        "nij,nj->ni",
        rotations[obs.photo],
        np.column_stack([obs.xy, np.full(obs.photo.size, -obs.principal_distance)]),
    )
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    a = np.zeros((obs.n_points, 3, 3))
    b = np.zeros((obs.n_points, 3))
    proj = np.eye(3) - rays[:, :, None] * rays[:, None, :]
    np.add.at(a, obs.point, proj)
    np.add.at(b, obs.point, np.einsum("nij,nj->ni", proj, centres[obs.photo]))
    points = np.linalg.solve(a + 1e-9 * np.eye(3), b[:, :, None])[:, :, 0]
    return centres, rotations, points


def run_case(n_photos: int, repeat: int, seed: int) -> list[tuple[str, float, float, float]]:
    sim = simulate_strip(
        n_photos,
        preset="drone",
        crs="local",
        seed=seed,
        control="every_k_models",
        control_every=10,
    )
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        strip, t = timed(lambda: triangulate(sim.observations, sim.control, sim.crs), repeat)
        rows.append(("strip", t, *check_rmse(strip.points, sim)))
        refined, t = timed(
            lambda: triangulate(sim.observations, sim.control, sim.crs, refine="bundle"), repeat
        )
        rows.append(("strip+bundle", t, *check_rmse(refined.points, sim)))
    with tempfile.TemporaryDirectory() as tmp:
        toml = sim.write_project(Path(tmp) / "p")
        code = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"
        _, t = timed(
            lambda: subprocess.run(
                [
                    sys.executable,
                    "-c",
                    code,
                    "-q",
                    "run",
                    str(toml),
                    "--out",
                    str(Path(tmp) / "o"),
                ],
                check=True,
                capture_output=True,
            ),
            repeat,
        )
        rows.append(("cli (report included)", t, *rows[0][2:]))
    try:
        import pycolmap  # noqa: F401
    except ImportError:
        print("pycolmap not importable: the Ceres rows are left out")
        return rows
    rot = strip.ground.photo_rotations_enu
    solved, t = timed(lambda: ceres(sim, strip.photo_centres, rot, strip.points), repeat)
    rows.append(("ceres/strip (solve only)", solved[1], *check_rmse(solved[0], sim)))
    start = gnss_start(sim, np.random.default_rng(seed))
    solved, _ = timed(lambda: ceres(sim, *start), 1)
    rows.append(("ceres/gnss (solve only)", solved[1], *check_rmse(solved[0], sim)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, nargs="+", default=[60, 300, 1000])
    parser.add_argument("--quick", action="store_true", help="60 photos only")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    photos = [60] if args.quick else args.photos
    for n in photos:
        rows = run_case(n, args.repeat, args.seed)
        best_plan = min(r[2] for r in rows)
        best_height = min(r[3] for r in rows)
        equal = [r for r in rows if r[2] <= 1.05 * best_plan and r[3] <= 1.05 * best_height]
        fastest = min(r[1] for r in equal) if equal else float("nan")
        print(f"\ndrone strip, {n} photos, 80 % overlap (check RMSE against the truth)")
        print(
            f"{'solver':26s} {'time s':>8s} {'plan m':>8s} {'height m':>8s} {'t / fastest':>12s}"
        )
        for name, t, plan, height in rows:
            mark = "" if (plan <= 1.05 * best_plan and height <= 1.05 * best_height) else " *"
            print(f"{name:26s} {t:8.3f} {plan:8.3f} {height:8.3f} {t / fastest:12.1f}{mark}")
        print("(* not within 5 % of the best accuracy)")


if __name__ == "__main__":
    main()
