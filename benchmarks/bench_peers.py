"""The strip method against the bundle adjusters users would pick, side by side.

Run from the repository root (the peers are optional benchmark dependencies,
``pip install -r benchmarks/requirements-peers.txt``)::

    python benchmarks/bench_peers.py               # every case and both cost curves
    python benchmarks/bench_peers.py --quick       # small cases and short curves, minutes
    python benchmarks/bench_peers.py --cases film-12 drone-300
    python benchmarks/bench_peers.py --no-curves   # the table only

One seeded set of strips and blocks, each in ``crs = "local"`` (every solver
works in the same Cartesian site system):

* **film-M** - film strips of :func:`strip_aerotri.simulate_strip` (152 mm
  on 230 mm at 1:8000, 60 % overlap, the preset's ~30 points per photo),
  full control every 5 models;
* **drone-M** - drone strips (1-inch camera at 120 m, 80 % overlap, about
  100 points measured per photo), full control every 10 models;
* **block-SxM** - a drone block of :func:`strip_aerotri.simulate_block`
  (S strips of M photos, 30 % side overlap, serpentine flight, perimeter
  control; the simulator's ~70 points per photo).

Each is solved on the same image observations and control by:

* **strip** - the strip method, the library call without file I/O
  (:func:`strip_aerotri.triangulate` / :func:`strip_aerotri.triangulate_block`);
* **cli** - ``stripaero run`` in a subprocess, report included;
* **strip+bundle** - the strip method with ``refine = "bundle"``, and the
  refinement alone (``timings_s.bundle`` of its result: the bundle with its
  blunder tests and cofactors, from the strip method's start);
* **ceres/strip**, **ceres/gnss** - Ceres through pycolmap's bundle adjuster,
  started from the strip method's result or from GNSS-like centres (the
  truth plus 3 cm, near-vertical attitudes along the heading with 2 degrees
  of noise, points intersected from those), the full control points held
  constant at their given coordinates, the intrinsics fixed; the solve
  alone is timed;
* **ceres tuned/strip**, **ceres tuned/gnss** - the same with the settings
  a user who knows Ceres would choose: world coordinates centred on the
  photo centres, ``function_tolerance`` 1e-10 and an initial trust region
  radius of 1e8 (pycolmap's defaults: 0 and 1e4);
* **scipy/strip**, **scipy/gnss** - :func:`scipy.optimize.least_squares`
  (``method="trf"``, ``tr_solver="lsmr"``, ``x_scale="jac"``, the
  scipy-cookbook's large-scale bundle adjustment) with an analytic sparse
  Jacobian, on the same observations, the same fixed points and the same
  starts as Ceres; the solve alone is timed.

Printed per case: wall time (median, or with ``--stat min`` the least, of
``--repeat`` runs; a solver whose first run takes over 10 s runs once) and
the load average of the machine, check-point RMSE in plan and height
against the simulator's truth, and the time ratio to the fastest solver
whose accuracy is within 5 % of the best (plan and height).  Then the cost
curves: time of the strip method, Ceres and scipy (from the strip method's
start) against the photos of a drone strip at 100 points per photo and
against the points per photo of a 300-photo drone strip, with the log-log
slopes.  The machine is shared: run it when nothing else runs.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from strip_aerotri import StripAerotriWarning, simulate_block, simulate_strip, triangulate
from strip_aerotri.geometry.rotation import matrix_from_opk, opk_from_matrix
from strip_aerotri.observations import ControlType

#: A solver whose first run takes longer than this runs once.
SLOW_S = 10.0
#: scipy from the strip method's start / from GNSS is not run on cases with
#: more observations than this (``--scipy-max-obs``): its LSMR inner
#: iterations grow with the strip, and the larger cases would take beyond
#: ten minutes each on two cores.
SCIPY_MAX_OBS = {"strip": 250_000, "gnss": 120_000}
#: How the repeated runs of a solver are summarised (``--stat``).
STAT = {"median": statistics.median, "min": min}
SUMMARY = ["median"]
#: Times already measured, (case, solver) -> seconds, reused by the cost curves.
MEASURED: dict[tuple[str, str], float] = {}


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
    """The last result and the median wall time of ``repeat`` calls (one
    call if the first takes longer than ``SLOW_S``)."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = func()
        times.append(time.perf_counter() - t0)
        if times[0] > SLOW_S:
            break
    return out, STAT[SUMMARY[0]](times)


def repeat_solve(func, repeat: int):
    """As :func:`timed` for a solver that returns (result, seconds of its solve)."""
    seconds, out = [], None
    for _ in range(repeat):
        out = func()
        seconds.append(out[1])
        if seconds[0] > SLOW_S:
            break
    return out, STAT[SUMMARY[0]](seconds)


@dataclass(frozen=True)
class PeerProblem:
    """The bundle problem every peer solves: which points enter, their start
    and which are held constant (the full control at its given coordinates).

    ``keep``: points seen on at least two photos with a finite start;
    ``fixed``: kept full control points; ``start``: (P, 3) start of every
    point, the given coordinates for the full control.
    """

    keep: np.ndarray
    fixed: np.ndarray
    start: np.ndarray


def peer_problem(sim, points: np.ndarray) -> PeerProblem:
    """The points and the constant control of the peers' bundle (shared by
    the Ceres and scipy peers)."""
    obs = sim.observations
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    full = [
        (lookup[p], i)
        for i, (p, k) in enumerate(zip(sim.control.point_ids, sim.control.kind, strict=True))
        if k is ControlType.FULL and p in lookup
    ]
    start = np.array(points, dtype=np.float64, copy=True)
    fixed = np.zeros(obs.n_points, dtype=bool)
    if full:
        pts, rows = np.array(full).T
        start[pts] = sim.control.xyz[rows]
        fixed[pts] = True
    counts = np.bincount(obs.point, minlength=obs.n_points)
    keep = (counts >= 2) & np.isfinite(start).all(axis=1)
    return PeerProblem(keep=keep, fixed=fixed & keep, start=start)


#: Ceres "tuned": the settings a user who knows Ceres would set for aerial
#: blocks, beside pycolmap's defaults (function_tolerance 0, initial trust
#: region radius 1e4, world coordinates as given).
CERES_TUNED = {"function_tolerance": 1e-10, "initial_trust_region_radius": 1e8}


def ceres(
    sim, centres: np.ndarray, rotations: np.ndarray, points: np.ndarray, tuned: bool = False
):
    """pycolmap's Ceres bundle adjuster from the given start; returns the
    adjusted points (site system) and the seconds of the solve alone.

    ``tuned``: world coordinates centred on the photo centres' mean (large
    map coordinates cost Ceres digits and steps) and :data:`CERES_TUNED`.
    """
    import pycolmap

    pycolmap.logging.minloglevel = 3
    obs = sim.observations
    problem = peer_problem(sim, points)
    origin = np.zeros(3)
    if tuned:
        origin = np.nanmean(np.asarray(centres, dtype=np.float64), axis=0)
        centres = centres - origin
        problem = PeerProblem(problem.keep, problem.fixed, problem.start - origin)
    flip = np.diag([1.0, -1.0, -1.0])  # COLMAP's camera looks along +z, image y down
    rec = pycolmap.Reconstruction()
    half = max(10.0, 1.1 * float(np.abs(obs.xy).max()))  # keeps image coordinates positive
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
    order = np.argsort(obs.point, kind="stable")
    bounds = np.searchsorted(obs.point[order], np.arange(obs.n_points + 1))
    config = pycolmap.BundleAdjustmentConfig()
    for j in range(obs.n_photos):
        config.add_image(j + 1)
    ids = np.full(obs.n_points, -1)
    for i in np.flatnonzero(problem.keep):
        track = pycolmap.Track()
        for k in order[bounds[i] : bounds[i + 1]]:
            track.add_element(int(obs.photo[k]) + 1, int(slot[k]))
        ids[i] = rec.add_point3D(problem.start[i], track)
        if problem.fixed[i]:
            config.add_constant_point(int(ids[i]))
    config.set_constant_cam_intrinsics(1)
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = False
    options.refine_principal_point = False
    options.refine_extra_params = False
    options.print_summary = False
    if tuned:
        for key, value in CERES_TUNED.items():
            setattr(options.ceres.solver_options, key, value)
    adjuster = pycolmap.create_default_bundle_adjuster(options, config, rec)
    t0 = time.perf_counter()
    adjuster.solve()
    seconds = time.perf_counter() - t0
    out = np.full((obs.n_points, 3), np.nan)
    for i in np.flatnonzero(ids >= 0):
        out[i] = rec.points3D[int(ids[i])].xyz + origin
    return out, seconds


# --- scipy.optimize.least_squares with an analytic sparse Jacobian -----------


def _rotations_and_derivatives(opk: np.ndarray) -> np.ndarray:
    """R = Rx(omega) Ry(phi) Rz(kappa) (image -> object, radians) and its
    derivatives by omega, phi and kappa: shape (4, M, 3, 3)."""
    m = opk.shape[0]
    c, s = np.cos(opk), np.sin(opk)
    rot = np.zeros((2, 3, m, 3, 3))  # [value / derivative, axis]
    z, o = np.zeros(m), np.ones(m)
    cw, cp, ck = c.T
    sw, sp, sk = s.T
    rot[0, 0] = np.stack([o, z, z, z, cw, -sw, z, sw, cw], axis=-1).reshape(m, 3, 3)
    rot[1, 0] = np.stack([z, z, z, z, -sw, -cw, z, cw, -sw], axis=-1).reshape(m, 3, 3)
    rot[0, 1] = np.stack([cp, z, sp, z, o, z, -sp, z, cp], axis=-1).reshape(m, 3, 3)
    rot[1, 1] = np.stack([-sp, z, cp, z, z, z, -cp, z, -sp], axis=-1).reshape(m, 3, 3)
    rot[0, 2] = np.stack([ck, -sk, z, sk, ck, z, z, z, o], axis=-1).reshape(m, 3, 3)
    rot[1, 2] = np.stack([-sk, -ck, z, ck, -sk, z, z, z, z], axis=-1).reshape(m, 3, 3)
    rx, ry, rz = rot[0]
    drx, dry, drz = rot[1]
    return np.stack([rx @ ry @ rz, drx @ ry @ rz, rx @ dry @ rz, rx @ ry @ drz])


class ScipyBundle:
    """The peers' bundle as residuals and an analytic sparse Jacobian for
    :func:`scipy.optimize.least_squares`.

    Unknowns: omega, phi, kappa (radians, ``R = Rx Ry Rz``, image -> site)
    and the centre (metres) of every photo, then X, Y, Z of every free point
    (kept, not fixed); residuals: computed minus measured image coordinates
    in mm, ``(x, y) = -c (p_x, p_y) / p_z`` with ``p = R^T (X - C)``,
    unweighted (one sigma for all, as for Ceres).
    """

    def __init__(self, sim, problem: PeerProblem):
        obs = sim.observations
        use = problem.keep[obs.point]
        self.photo = obs.photo[use]
        self.point = obs.point[use]
        self.xy = obs.xy[use]
        self.c = float(obs.principal_distance)
        self.n_photos = obs.n_photos
        self.problem = problem
        free = problem.keep & ~problem.fixed
        self.free_points = np.flatnonzero(free)
        index = np.full(obs.n_points, -1)
        index[self.free_points] = np.arange(self.free_points.size)
        fi = index[self.point]
        self.is_free = fi >= 0
        self.free_obs = np.flatnonzero(self.is_free)
        self.free_index = fi[self.is_free]
        self.n_obs = self.point.size
        n_cam = 6 * self.n_photos
        self.n_params = n_cam + 3 * self.free_points.size
        # CSR structure, fixed: each of the two rows of an observation holds
        # its photo's 6 columns, then its point's 3 if the point is free.
        cols = np.empty((self.n_obs, 9), dtype=np.intp)
        cols[:, :6] = 6 * self.photo[:, None] + np.arange(6)
        cols[:, 6:] = n_cam + 3 * np.maximum(fi, 0)[:, None] + np.arange(3)
        mask = np.ones((self.n_obs, 2, 9), dtype=bool)
        mask[~self.is_free, :, 6:] = False
        self.mask = mask
        self.indices = np.broadcast_to(cols[:, None, :], mask.shape)[mask]
        nnz = mask.sum(axis=2).ravel()
        self.indptr = np.concatenate([[0], np.cumsum(nnz)])

    def x0(self, centres: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opk = opk_from_matrix(rotations)
        cams = np.column_stack([opk, centres]).ravel()
        return np.concatenate([cams, self.problem.start[self.free_points].ravel()])

    def unpack(self, x: np.ndarray):
        cams = x[: 6 * self.n_photos].reshape(-1, 6)
        points = self.problem.start.copy()
        points[self.free_points] = x[6 * self.n_photos :].reshape(-1, 3)
        return cams[:, :3], cams[:, 3:], points

    def _camera_frame(self, x: np.ndarray, derivatives: bool):
        opk, centres, points = self.unpack(x)
        rd = _rotations_and_derivatives(opk)
        if not derivatives:
            rd = rd[:1]
        d = points[self.point] - centres[self.photo]
        r = rd[:, self.photo]  # (k, n, 3, 3)
        p = np.einsum("knji,nj->kni", r, d)  # R^T d and its derivatives
        return r, p

    def residuals(self, x: np.ndarray) -> np.ndarray:
        _, p = self._camera_frame(x, derivatives=False)
        p = p[0]
        proj = -self.c * p[:, :2] / p[:, 2:3]
        return (proj - self.xy).ravel()

    def jacobian(self, x: np.ndarray):
        from scipy.sparse import csr_matrix

        r, p = self._camera_frame(x, derivatives=True)
        p0 = p[0]
        q = -self.c / p0[:, 2]
        jp = np.zeros((self.n_obs, 2, 3))  # d(x, y) / dp
        jp[:, 0, 0] = q
        jp[:, 1, 1] = q
        jp[:, 0, 2] = -q * p0[:, 0] / p0[:, 2]
        jp[:, 1, 2] = -q * p0[:, 1] / p0[:, 2]
        data = np.empty((self.n_obs, 2, 9))
        data[:, :, :3] = np.einsum("nak,mnk->nam", jp, p[1:])  # by omega, phi, kappa
        jx = np.einsum("nak,njk->naj", jp, r[0])  # d(x, y) / dX = jp R^T
        data[:, :, 3:6] = -jx
        data[:, :, 6:] = jx
        return csr_matrix(
            (data[self.mask], self.indices, self.indptr), shape=(2 * self.n_obs, self.n_params)
        )


def scipy_bundle(
    sim,
    centres: np.ndarray,
    rotations: np.ndarray,
    points: np.ndarray,
    *,
    ftol: float = 1e-6,
):
    """``scipy.optimize.least_squares`` from the given start; returns (the
    adjusted points, site system; seconds of the solve alone; the result)."""
    from scipy.optimize import least_squares

    bundle = ScipyBundle(sim, peer_problem(sim, points))
    x0 = bundle.x0(centres, rotations)
    t0 = time.perf_counter()
    res = least_squares(
        bundle.residuals,
        x0,
        jac=bundle.jacobian,
        method="trf",
        tr_solver="lsmr",
        x_scale="jac",
        ftol=ftol,
        xtol=1e-10,
        gtol=1e-10,
    )
    seconds = time.perf_counter() - t0
    _, _, out = bundle.unpack(res.x)
    out[~bundle.problem.keep] = np.nan
    res.n_obs = bundle.n_obs
    return out, seconds, res


def gnss_start(sim, rng: np.random.Generator):
    """Centres from GNSS (truth + 3 cm), near-vertical attitudes along each
    photo's heading with 2 degrees of noise, points intersected from them
    (least-squares intersection of all of each point's rays)."""
    truth = sim.truth
    obs = sim.observations
    if hasattr(sim, "strips"):  # a block: every strip its own heading
        heading = np.concatenate([np.full(len(s.photo_ids), s.heading_deg) for s in sim.strips])
    else:
        heading = np.full(obs.n_photos, truth.heading_deg)
    centres = truth.photo_centres_local + rng.normal(0.0, 0.03, truth.photo_centres_local.shape)
    opk = np.column_stack(
        [
            rng.normal(0.0, np.radians(2.0), obs.n_photos),
            rng.normal(0.0, np.radians(2.0), obs.n_photos),
            np.radians(90.0 - heading),
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


# --- the cases ---------------------------------------------------------------


#: Observations per photo of simulate_strip(preset="drone") ~ 16 + 4.74 x
#: extra_points_per_photo (measured, seeds 1-3).
def drone_extra_points(points_per_photo: float) -> int:
    """``extra_points_per_photo`` giving about this many points measured per
    drone photo."""
    return max(0, round((points_per_photo - 16.0) / 4.74))


def simulate_case(name: str, seed: int):
    """The seeded simulation of a case named ``film-M``, ``drone-M``,
    ``drone-MxK`` (K points per photo) or ``block-SxM``."""
    kind, _, size = name.partition("-")
    if kind == "film":
        return simulate_strip(
            int(size),
            preset="film",
            crs="local",
            seed=seed,
            control="every_k_models",
            control_every=5,
        )
    if kind == "drone":
        photos, _, per_photo = size.partition("x")
        return simulate_strip(
            int(photos),
            preset="drone",
            crs="local",
            seed=seed,
            control="every_k_models",
            control_every=10,
            extra_points_per_photo=drone_extra_points(float(per_photo or 100)),
        )
    if kind == "block":
        strips, _, photos = size.partition("x")
        return simulate_block(
            int(strips),
            int(photos),
            preset="drone",
            crs="local",
            seed=seed,
        )
    raise ValueError(f"Expected a case film-M, drone-M, drone-MxK or block-SxM, got {name!r}")


def strip_method(sim, refine: str = "none"):
    """The strip method's library call on ``sim``: (points, centres, rotations)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        if hasattr(sim, "strips"):
            from strip_aerotri.observations import StripSpec
            from strip_aerotri.pipeline import triangulate_block

            specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
            res = triangulate_block(sim.observations, sim.control, sim.crs, specs, refine=refine)
        else:
            res = triangulate(sim.observations, sim.control, sim.crs, refine=refine)
    timings = getattr(res, "timings", None) or {}
    if "bundle" in timings:
        BUNDLE_S.append(float(timings["bundle"]))
    return res.points, res.photo_centres, matrix_from_opk(res.photo_opk)


#: report.json's ``timings_s.bundle`` of every refined library call, in order.
BUNDLE_S: list[float] = []


def run_cli(sim, repeat: int) -> float:
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
    return t


@dataclass
class Row:
    solver: str
    seconds: float
    plan: float
    height: float
    note: str = ""


def run_case(name: str, repeat: int, seed: int, scipy_max_obs: dict | None = None) -> tuple:
    """Every solver on the case ``name``: (simulation, rows)."""
    scipy_max_obs = scipy_max_obs or SCIPY_MAX_OBS
    sim = simulate_case(name, seed)
    rows = []
    strip, t = timed(lambda: strip_method(sim), repeat)
    MEASURED[name, "strip"] = t
    rows.append(Row("strip", t, *check_rmse(strip[0], sim)))
    BUNDLE_S.clear()
    refined, t = timed(lambda: strip_method(sim, "bundle"), repeat)
    rows.append(Row("strip+bundle", t, *check_rmse(refined[0], sim)))
    if BUNDLE_S:  # the refinement alone, its blunder tests and cofactors included
        bundle_s = STAT[SUMMARY[0]](BUNDLE_S)
        rows.append(Row("bundle (timings_s.bundle)", bundle_s, *check_rmse(refined[0], sim)))
    rows.append(Row("cli (report included)", run_cli(sim, repeat), rows[0].plan, rows[0].height))
    starts = {
        "strip": (strip[1], strip[2], strip[0]),
        "gnss": gnss_start(sim, np.random.default_rng(seed)),
    }
    try:
        import pycolmap  # noqa: F401
    except ImportError:
        print("pycolmap not importable: the Ceres rows are left out")
    else:
        for tuned, label in ((False, "ceres"), (True, "ceres tuned")):
            for key, start in starts.items():
                out, t = repeat_solve(
                    lambda start=start, tuned=tuned: ceres(sim, *start, tuned=tuned), repeat
                )
                rows.append(Row(f"{label}/{key} (solve only)", t, *check_rmse(out[0], sim)))
                MEASURED[name, f"{label}/{key}"] = t
    n_obs = sim.observations.photo.size
    for key, start in starts.items():
        if n_obs > scipy_max_obs[key]:
            rows.append(
                Row(
                    f"scipy/{key} (solve only)",
                    math.nan,
                    math.nan,
                    math.nan,
                    f"not run: {n_obs} observations > {scipy_max_obs[key]}",
                )
            )
            continue
        out, t = repeat_solve(lambda start=start: scipy_bundle(sim, *start), repeat)
        res = out[2]
        per = 1e6 * out[1] / (res.n_obs * max(res.njev, 1))
        note = f"{res.nfev} evaluations, {res.njev} Jacobians, {per:.1f} us/obs/Jacobian"
        rows.append(Row(f"scipy/{key} (solve only)", t, *check_rmse(out[0], sim), note))
        MEASURED[name, f"scipy/{key}"] = t
    return sim, rows


def print_case(name: str, sim, rows: list[Row]) -> None:
    obs = sim.observations
    ok = [r for r in rows if math.isfinite(r.plan)]
    best_plan = min(r.plan for r in ok)
    best_height = min(r.height for r in ok)

    def equal(r: Row) -> bool:
        return r.plan <= 1.05 * best_plan and r.height <= 1.05 * best_height

    fastest = min((r.seconds for r in ok if equal(r)), default=math.nan)
    print(
        f"\n{name}: {obs.n_photos} photos, {obs.photo.size} observations "
        f"({obs.photo.size / obs.n_photos:.0f} per photo), {obs.n_points} points; "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    print(f"{'solver':31s} {'time s':>8s} {'plan m':>8s} {'height m':>8s} {'t / fastest':>12s}")
    for r in rows:
        if not math.isfinite(r.plan):
            print(f"{r.solver:31s} {'-':>8s} {'-':>8s} {'-':>8s} {'-':>12s}  {r.note}")
            continue
        mark = "" if equal(r) else " *"
        note = f"  {r.note}" if r.note else ""
        print(
            f"{r.solver:31s} {r.seconds:8.3f} {r.plan:8.3f} {r.height:8.3f} "
            f"{r.seconds / fastest:12.1f}{mark:2s}{note}"
        )
    print("(* not within 5 % of the best accuracy in plan and height)")
    sys.stdout.flush()


# --- the cost curves ----------------------------------------------------------


def slope(x, y) -> float:
    """Least-squares slope of log(y) against log(x)."""
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def cost_curve(
    names: list[str], x_of, label: str, repeat: int, seed: int, scipy_max_obs: int
) -> None:
    """Time of the strip method, Ceres and scipy (from the strip's start)
    over ``names``, and the log-log slopes against ``x_of(sim)``."""
    print(f"\ncost against {label}")
    print(
        f"{'case':14s} {'x':>7s} {'obs':>8s} {'strip s':>9s} {'ceres s':>9s} "
        f"{'tuned s':>9s} {'scipy s':>9s}"
    )
    xs, times = [], {"strip": [], "ceres": [], "ceres tuned": [], "scipy": []}
    for name in names:
        sim = simulate_case(name, seed)
        runs = 1 if (name, "strip") in MEASURED else repeat  # only the start is needed then
        strip, t = timed(lambda sim=sim: strip_method(sim), runs)
        times["strip"].append(MEASURED.get((name, "strip"), t))
        start = (strip[1], strip[2], strip[0])
        for key, tuned in (("ceres", False), ("ceres tuned", True)):
            t = MEASURED.get((name, f"{key}/strip"))
            if t is None:
                try:
                    _, t = repeat_solve(
                        lambda sim=sim, start=start, tuned=tuned: ceres(sim, *start, tuned=tuned),
                        repeat,
                    )
                except ImportError:
                    t = math.nan
            times[key].append(t)
        t = MEASURED.get((name, "scipy/strip"))
        if t is None:
            t = math.nan
            if sim.observations.photo.size <= scipy_max_obs:
                _, t = repeat_solve(lambda sim=sim, start=start: scipy_bundle(sim, *start), repeat)
        times["scipy"].append(t)
        xs.append(x_of(sim))
        print(
            f"{name:14s} {xs[-1]:7.0f} {sim.observations.photo.size:8d} "
            f"{times['strip'][-1]:9.3f} {times['ceres'][-1]:9.3f} "
            f"{times['ceres tuned'][-1]:9.3f} {times['scipy'][-1]:9.3f}"
            f"   load {os.getloadavg()[0]:.1f}"
        )
        sys.stdout.flush()
    for key, t in times.items():
        ok = np.isfinite(t)
        if ok.sum() < 2:
            continue
        x = np.array(xs)[ok]
        tt = np.array(t)[ok]
        upper = x >= np.median(x)
        print(
            f"slope log(time) / log({label}), {key}: {slope(x, tt):.2f} over "
            f"{x.min():.0f}-{x.max():.0f}, {slope(x[upper], tt[upper]):.2f} over "
            f"{x[upper].min():.0f}-{x.max():.0f}"
        )


def per_photo(sim) -> float:
    return sim.observations.photo.size / sim.observations.n_photos


FULL_CASES = [
    "film-12",
    "film-60",
    "film-120",
    "drone-60",
    "drone-300",
    "drone-1000",
    "drone-2000",
    "block-10x100",
]
QUICK_CASES = ["film-12", "drone-60", "block-3x20"]
FULL_PHOTOS = [12, 30, 60, 120, 300, 1000, 2000]
QUICK_PHOTOS = [12, 30, 60, 120]
FULL_PER_PHOTO = [30, 60, 100, 200, 300]
QUICK_PER_PHOTO = [30, 100, 300]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small cases and short curves")
    parser.add_argument(
        "--cases", nargs="+", default=None, help="e.g. film-12 drone-300 block-10x100"
    )
    parser.add_argument("--no-curves", action="store_true", help="the table only")
    parser.add_argument("--curves-only", action="store_true", help="the cost curves only")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--stat",
        choices=sorted(STAT),
        default="median",
        help="summary of the repeated runs (min resists a busy machine)",
    )
    parser.add_argument(
        "--scipy-max-obs",
        type=int,
        nargs=2,
        metavar=("STRIP", "GNSS"),
        default=[SCIPY_MAX_OBS["strip"], SCIPY_MAX_OBS["gnss"]],
        help="largest case (observations) scipy solves from the strip / GNSS start",
    )
    args = parser.parse_args()
    cases = args.cases or (QUICK_CASES if args.quick else FULL_CASES)
    SUMMARY[0] = args.stat
    max_obs = dict(zip(("strip", "gnss"), args.scipy_max_obs, strict=True))
    t_all = time.perf_counter()
    if not args.curves_only:
        for name in cases:
            sim, rows = run_case(name, args.repeat, args.seed, max_obs)
            print_case(name, sim, rows)
    if not args.no_curves:
        photos = QUICK_PHOTOS if args.quick else FULL_PHOTOS
        cost_curve(
            [f"drone-{n}" for n in photos],
            lambda s: s.observations.n_photos,
            "photos",
            args.repeat,
            args.seed,
            max_obs["strip"],
        )
        per = QUICK_PER_PHOTO if args.quick else FULL_PER_PHOTO
        cost_curve(
            [f"drone-{'120' if args.quick else '300'}x{k}" for k in per],
            per_photo,
            "points per photo",
            args.repeat,
            args.seed,
            max_obs["strip"],
        )
    print(f"\n{time.perf_counter() - t_all:.0f} s in all")


if __name__ == "__main__":
    main()
