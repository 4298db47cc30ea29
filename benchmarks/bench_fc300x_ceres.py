"""Ceres (through pycolmap) on the FC300X block's own observations: does an
independent rigorous bundle reach the strips' check heights?

Run from the repository root (``pip install -r benchmarks/requirements-peers.txt``)::

    python benchmarks/bench_fc300x_ceres.py ../shared/data/uav-block-fc300x

It imports the block (the importer's split: 16 full control, the rest check
points), runs ``refine = "bundle"`` and takes from that run the image
observations the refinement kept (its bundle rejections left out), its
photos and points as the start, and the full control with its sigmas.  The
same problem then goes to pycolmap's Ceres bundle adjuster:

* the camera: the data's calibration, as the project applies it (the
  reduced image coordinates, principal point and ``[distortion]`` already
  taken out), a PINHOLE camera of ``c`` / pixel held constant; or an OPENCV
  camera with k1, k2, p1, p2 free from zero (COLMAP's distortion of the
  normalised projection, on top of the data's calibration);
* the image observations in pixels, one sigma for all (the project's: one
  pixel, so Ceres's squared pixel residuals are the weighted ones);
* the control, weighted: COLMAP has no prior on a 3D point, so each full
  control point is observed by two virtual cameras of constant pose and
  intrinsics at D = 1 km from its given position, one looking down the
  site's Z axis with ``f = D / sigma_xy`` pixels (its two residuals are
  ``dX / sigma_xy``, ``dY / sigma_xy``), one looking along X with
  ``f_x`` = 1e-9 D, ``f_y = D / sigma_h`` (its residuals ``~0`` and
  ``dZ / sigma_h``): the weighted control observations of our adjustment,
  linear to 1e-4 relative over the centimetres the points move; or fixed at
  their given coordinates (``bench_peers.py``'s way), for comparison.

Printed: sigma0 (sqrt of the sum of squares over the redundancy), the check
RMSE plan / height (m) without the weakly determined check points (those of
the project's statistics) and with all, for our refinement, the scipy
reference of ``bench_reference_bundle.py`` and each Ceres variant, and the
largest difference of the Ceres points from the reference's on the same
camera (the two optimise the same sum of squares, so they should agree to
well under a millimetre).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_reference_bundle as reference  # noqa: E402

#: Distance (m) of the virtual cameras that observe the control.
VIRTUAL_DISTANCE_M = 1000.0
#: Ceres settings: run to convergence (pycolmap's defaults stop at a
#: gradient tolerance of 1e-4 and a function tolerance of 0).
SOLVER = {
    "function_tolerance": 1e-14,
    "gradient_tolerance": 1e-14,
    "parameter_tolerance": 1e-14,
    "max_num_iterations": 500,
    "initial_trust_region_radius": 1e8,
}


#: (the reference's camera terms, the Ceres camera of the same model or "").
VARIANTS: tuple[tuple[tuple[str, ...], str], ...] = (
    ((), "fixed"),
    (("k1", "k2", "p1", "p2"), "distortion"),
    (("c", "x0", "y0", "k1", "k2", "p1", "p2", "b1"), "all"),
    (reference.CAMERA_TERMS, ""),
)
CERES_LABEL = {"fixed": "camera fixed", "distortion": "k1 k2 p1 p2 free",
               "all": "fx fy cx cy k1 k2 p1 p2 free"}  # fmt: skip


@dataclass(frozen=True)
class CeresOutcome:
    """A Ceres solution: ``points`` (P, 3) site system (NaN where not
    adjusted), ``sigma0``, ``redundancy``, ``distortion`` (the change of the
    camera's parameters: fx, fy, cx, cy in pixels (sigmas), then k1, k2, p1,
    p2 of COLMAP's OPENCV model), ``iterations``, ``termination``."""

    points: np.ndarray
    sigma0: float
    redundancy: int
    distortion: np.ndarray
    iterations: int
    termination: str


def _virtual_views(given: np.ndarray, sigma: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, list[float]]]:
    """(rotation world -> camera, camera centre, PINHOLE fx fy cx cy) of the
    virtual cameras observing one control point ``given`` (3,) with sigmas
    ``sigma`` (sigma_xy, sigma_h), for the components given."""
    d = VIRTUAL_DISTANCE_M
    views = []
    if np.all(np.isfinite(given[:2])):  # looking up the Z axis: camera x, y = site X, Y
        views.append((np.eye(3), given - d * np.array([0.0, 0.0, 1.0]), [d / sigma[0], d / sigma[0]]))
    if np.isfinite(given[2]):  # looking along X: camera x = Y (weight ~0), camera y = Z
        rot = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
        centre = np.where(np.isfinite(given), given, 0.0) - d * np.array([1.0, 0.0, 0.0])
        views.append((rot, centre, [1e-9 * d, d / sigma[1]]))
    return [(r, c, [fx, fy, 1000.0, 1000.0]) for r, c, (fx, fy) in views]


def ceres_block(
    ref: reference.ReferenceBundle, *, intrinsics: str, weighted_control: bool
) -> CeresOutcome:
    """Ceres on the reference's problem (its rays, start, control and
    sigmas; site system centred as the reference's); ``intrinsics``: "fixed"
    (PINHOLE, constant), "distortion" (OPENCV, k1 k2 p1 p2 free) or "all"
    (OPENCV, fx, fy, cx, cy free too: c, the principal point and an
    affinity, COLMAP has no shear).  Length: one
    reconstruction built and solved, its parts in the order COLMAP asks."""
    import pycolmap

    pycolmap.logging.minloglevel = 3
    pixel_mm = float(ref.sigma[0])  # Ceres's unit: the image sigma, the same for all
    if np.ptp(ref.sigma) > 1e-12 * pixel_mm:
        raise SystemExit("the image sigmas differ: Ceres weights all rays alike")
    rec = pycolmap.Reconstruction()
    half = 2500.0
    f = ref.c / pixel_mm
    free_distortion = intrinsics != "fixed"
    model = "OPENCV" if free_distortion else "PINHOLE"
    params = [f, f, half, half] + ([0.0, 0.0, 0.0, 0.0] if free_distortion else [])
    rec.add_camera_with_trivial_rig(
        pycolmap.Camera(model=model, width=int(2 * half), height=int(2 * half), params=params,
                        camera_id=1)  # fmt: skip
    )
    flip = np.diag([1.0, -1.0, -1.0])  # COLMAP looks along +z, image y down
    uv = np.column_stack([ref.xy[:, 0] / pixel_mm + half, -ref.xy[:, 1] / pixel_mm + half])
    order = np.argsort(ref.photo, kind="stable")
    n_photos = len(ref.centres0)
    slots = np.empty(ref.photo.size, dtype=np.intp)
    config = pycolmap.BundleAdjustmentConfig()
    for j in range(n_photos):
        rows = order[ref.photo[order] == j]
        slots[rows] = np.arange(rows.size)
        r_cw = flip @ ref.rotations0[j].T
        image = pycolmap.Image(name=f"photo{j}", points2D=[pycolmap.Point2D(p) for p in uv[rows]],
                               camera_id=1, image_id=j + 1)  # fmt: skip
        rec.add_image_with_trivial_frame(image, pycolmap.Rigid3d(pycolmap.Rotation3d(r_cw), -r_cw @ ref.centres0[j]))
        config.add_image(j + 1)
    if not free_distortion:
        config.set_constant_cam_intrinsics(1)
    # the virtual cameras of the weighted control, one image and camera each
    extra: dict[int, list[tuple[int, int]]] = {}
    next_id = n_photos + 1
    if weighted_control:
        csig = ref.control_sigma
        for n, point in enumerate(ref.control_point):
            sig = np.array([csig[n, 0], csig[n, 2]])
            for rot, centre, cam in _virtual_views(ref.control_xyz[n], sig):
                rec.add_camera_with_trivial_rig(
                    pycolmap.Camera(model="PINHOLE", width=2000, height=2000, params=cam,
                                    camera_id=next_id)  # fmt: skip
                )
                image = pycolmap.Image(name=f"control{next_id}", points2D=[pycolmap.Point2D([1000.0, 1000.0])],
                                       camera_id=next_id, image_id=next_id)  # fmt: skip
                rec.add_image_with_trivial_frame(image, pycolmap.Rigid3d(pycolmap.Rotation3d(rot), -rot @ centre))
                config.add_image(next_id)
                config.set_constant_cam_intrinsics(next_id)
                config.set_constant_rig_from_world_pose(next_id)
                extra.setdefault(int(point), []).append((next_id, 0))
                next_id += 1
    start = ref.points0.copy()
    if not weighted_control:
        start[ref.control_point] = np.where(np.isfinite(ref.control_xyz), ref.control_xyz,
                                            start[ref.control_point])  # fmt: skip
    ids = np.full(len(start), -1)
    by_point = np.argsort(ref.point, kind="stable")
    bounds = np.searchsorted(ref.point[by_point], np.arange(len(start) + 1))
    fixed = set(ref.control_point.tolist()) if not weighted_control else set()
    for i in np.flatnonzero(np.diff(bounds) >= 1):
        track = pycolmap.Track()
        for k in by_point[bounds[i] : bounds[i + 1]]:
            track.add_element(int(ref.photo[k]) + 1, int(slots[k]))
        for image_id, slot in extra.get(int(i), []):
            track.add_element(image_id, slot)
        ids[i] = rec.add_point3D(start[i], track)
        if int(i) in fixed:
            config.add_constant_point(int(ids[i]))
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = intrinsics == "all"
    options.refine_principal_point = intrinsics == "all"
    options.refine_extra_params = free_distortion
    options.print_summary = False
    for key, value in SOLVER.items():
        setattr(options.ceres.solver_options, key, value)
    adjuster = pycolmap.create_default_bundle_adjuster(options, config, rec)
    summary = adjuster.solve()
    ceres_summary = summary.ceres_summary
    points = np.full(start.shape, np.nan)
    for i in np.flatnonzero(ids >= 0):
        points[i] = rec.points3D[int(ids[i])].xyz
    n_res = int(ceres_summary.num_residuals_reduced)
    n_par = int(ceres_summary.num_effective_parameters_reduced)
    cost = float(ceres_summary.final_cost)  # half the sum of squares
    # the virtual cameras looking along X give a residual of weight ~0 in Y each
    redundancy = n_res - n_par - sum(np.isfinite(ref.control_xyz[:, 2])) * int(weighted_control)
    dist = np.array(rec.cameras[1].params) - np.array(params)
    return CeresOutcome(points, float(np.sqrt(2.0 * cost / redundancy)), redundancy, dist,
                        int(ceres_summary.num_successful_steps + ceres_summary.num_unsuccessful_steps),
                        str(summary.termination_type))  # fmt: skip


def check_errors(points: np.ndarray, ref: reference.ReferenceBundle, result: Any) -> dict[str, np.ndarray]:
    """Given minus adjusted (m) at each check point ``points`` (reference's
    centred system) determines."""
    v = ref.solution.copy() if ref.solution.size else np.zeros(ref.n_unknowns)
    m = len(ref.centres0)
    v[6 * m : 6 * m + points.size] = np.nan_to_num(points - ref.points0).ravel()
    shadow = reference.ReferenceBundle(**{k: getattr(ref, k) for k in (
        "xy", "sigma", "photo", "point", "c", "centres0", "rotations0", "points0",
        "control_point", "control_xyz", "control_sigma", "camera")})  # fmt: skip
    shadow.solution = v
    return reference.check_errors(shadow, result)


def _line(label: str, errors: dict[str, np.ndarray], weak: tuple[str, ...], extra: str) -> None:
    strong, every = reference.rmse(errors, weak), reference.rmse(errors)
    print(f"{label:44s} {strong[0]:.4f} / {strong[1]:.4f}   {every[0]:.4f} / {every[1]:.4f}   {extra}")


def main(argv: list[str] | None = None) -> None:
    from strip_aerotri.importers.uav_fc300x import import_uav_fc300x
    from strip_aerotri.importers.writer import write_project
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path, help="the FC300X data folder")
    parser.add_argument("--settings", default='refine = "bundle"', help="[adjustment] lines of our run")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        write_project(import_uav_fc300x(args.data), tmp, force=True)
        toml = Path(tmp) / "strip.toml"
        toml.write_text(toml.read_text() + f"\n[adjustment]\n{args.settings}\n")
        project = load_project(toml)
        result = run_project(project)
    weak = tuple(getattr(result, "weak_checks", ()))
    used = reference._used_rays(result)
    names = np.array(result.control.point_ids)[result.control_index]
    engine = dict(zip(names[result.is_check], result.control_residuals[result.is_check], strict=True))
    print(f"importer's split, {int(used.sum())} of {used.size} rays kept by our refinement "
          f"({args.settings}); weakly determined check points left out: {', '.join(weak)}")  # fmt: skip
    print(f"{'':44s} {'RMSE plan / height (m)':22s} {'with the weak ones':18s}")
    _line("ours", engine, weak, f"sigma0 {result.refined_sigma0:.4f}")
    for camera, intrinsics in VARIANTS:
        ref = reference.from_block(result, used=used, camera=camera).solve(iterations=20, tolerance=1e-11)
        _, _, ref_points, q = ref.unpack(ref.solution)
        label = "scipy reference, " + (" ".join(camera) if camera else "camera fixed")
        extra = f"sigma0 {ref.sigma0:.4f}, redundancy {ref.redundancy}"
        if camera:
            extra += "; " + " ".join(f"{k} {v:.3g}" for k, v in q.items())
        _line(label, reference.check_errors(ref, result), weak, extra)
        for weighted in (True, False) if intrinsics == "fixed" else (True,) if intrinsics else ():
            out = ceres_block(ref, intrinsics=intrinsics, weighted_control=weighted)
            seen = np.isfinite(out.points).all(axis=1) & np.isin(np.arange(len(out.points)), ref.point)
            diff = np.max(np.abs(out.points[seen] - ref_points[seen]))
            label = f"ceres, {CERES_LABEL[intrinsics]}" + (
                ", control weighted" if weighted else ", control fixed")
            extra = (f"sigma0 {out.sigma0:.4f}, redundancy {out.redundancy}, {out.iterations} steps, "
                     f"{out.termination.split('.')[-1]}; points - reference's: largest {diff * 1000:.2f} mm")  # fmt: skip
            if intrinsics != "fixed":
                extra += f"; d(fx fy cx cy) px, k1 k2 p1 p2: {np.array2string(out.distortion, precision=4)}"
            _line(label, check_errors(out.points, ref, result), weak, extra)
        sys.stdout.flush()


if __name__ == "__main__":
    main()
