"""Strip 1 of a real UAV block (DJI Phantom 3, FC300X) through strip_aerotri.

The data (``rashidyreza/Strip-Adjustment-with-Matlab``, see its README.md)
are read from ``../shared/data/uav-block-fc300x`` next to the repository, or
from a folder given on the command line; they are never copied into the
repository.  The script writes a project (``strip.toml`` and CSV files) into
an output folder (default ``examples/uav-out/``), runs it and prints the
check-point RMSE.  See ``docs/uav.md`` for the choices made here.

Usage::

    python examples/uav_fc300x.py [DATA_DIR] [--out OUT_DIR] [--step K|auto]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import strip_aerotri as sa
from strip_aerotri.project import Project, load_project

REPO = Path(__file__).resolve().parents[1]
DATA_DIR = REPO.parent / "shared" / "data" / "uav-block-fc300x"
OUT_DIR = REPO / "examples" / "uav-out"

#: Camera of ``src/STRIP.m``: pixel size and principal distance in pixels.
PIXEL_SIZE_MM = 0.00156192
PRINCIPAL_DISTANCE_PX = 2312.78104
#: STRIP.m's radial distortion, r in mm, corrected = measured + delta.
STRIP_M_K1 = 8.756635940e-4
STRIP_M_K2 = -8.843480548e-5
#: ``Calibration/cal.cal`` (Agisoft PhotoScan): focal length and principal
#: point in pixels (column, row from the top-left corner).
CAL_FOCAL_PX = 2320.1052500623382
CAL_PRINCIPAL_POINT_PX = (2001.9224147846980, 1487.4452793843993)
IMAGE_SIZE_PX = (4000, 3000)

#: GCPs used as full control: the two nearest each end of the strip and two
#: in the middle (by position along the strip, among the GCPs seen on at
#: least three photos of strip 1); every other GCP of strip 1 is a check point.
CONTROL_IDS = ("36", "41", "34", "32", "18", "22")


@dataclass(frozen=True)
class UavStrip:
    """Rows of one strip, ids prefixed by their source file.

    ``image_rows``: (photo, point, x, y) with x, y in mm from the image
    centre, x right, y up.  Tie points of ``Tie_points_for_AO.txt`` are
    ``T<id>``, those of ``Matching.txt`` ``M<id>``, GCPs keep their number.
    """

    photos: tuple[str, ...]
    image_rows: tuple[tuple[str, str, float, float], ...]
    gcp: dict[str, tuple[float, float, float]]


def read_image_file(path: Path) -> list[tuple[str, str, float, float]]:
    """Whitespace file ``image Num x y n m`` (a header line is skipped)."""
    rows = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) < 4 or not parts[0].upper().endswith(".JPG"):
            continue  # header or blank
        rows.append((parts[0][:-4], parts[1], float(parts[2]), float(parts[3])))
    return rows


def read_strip(data_dir: Path, strip: int = 1) -> UavStrip:
    """Image observations and GCPs of one strip.

    ``Matching.txt`` and ``Tie_points_for_AO.txt`` number their points
    independently; about half of the Matching points are the same
    measurements as tie points (same photo, within 5 µm) under another id.
    Those Matching points are left out, the others are kept.
    """
    photos = tuple(f"B{strip}_{n}" for n in range(1, 11))
    keep = set(photos)
    gcp_rows = [r for r in read_image_file(data_dir / "GCP_ImageCs.txt") if r[0] in keep]
    tie_rows = [r for r in read_image_file(data_dir / "Tie_points_for_AO.txt") if r[0] in keep]
    match_rows = [r for r in read_image_file(data_dir / "Matching.txt") if r[0] in keep]
    tie_xy: dict[str, np.ndarray] = {}
    for photo in photos:
        tie_xy[photo] = np.array([(x, y) for p, _, x, y in tie_rows if p == photo]).reshape(-1, 2)
    duplicate: set[str] = set()
    for photo, pid, x, y in match_rows:
        if tie_xy[photo].size:
            if np.min(np.hypot(*(tie_xy[photo] - (x, y)).T)) < 0.005:
                duplicate.add(pid)
    rows = [(p, g, x, y) for p, g, x, y in gcp_rows]
    rows += [(p, f"T{i}", x, y) for p, i, x, y in tie_rows]
    rows += [(p, f"M{i}", x, y) for p, i, x, y in match_rows if i not in duplicate]
    gcp = {}
    for line in (data_dir / "GCP_UTM.txt").read_text().splitlines():
        parts = line.split()
        if len(parts) == 4:
            gcp[parts[0]] = (float(parts[1]), float(parts[2]), float(parts[3]))
    seen = {r[1] for r in gcp_rows}
    return UavStrip(photos, tuple(rows), {k: v for k, v in gcp.items() if k in seen})


def write_project(
    data_dir: Path,
    out_dir: Path,
    *,
    strip: int = 1,
    control_ids: Sequence[str] = CONTROL_IDS,
    photo_step: int | str = 2,
    camera: str = "cal",
    distortion: bool = True,
    polynomial: int | str | None = 1,
) -> Path:
    """Write ``strip.toml``, ``image_points.csv`` and ``control.csv``.

    Parameters
    ----------
    data_dir, out_dir : Path
        The data folder and the project folder to write.
    strip : int
        Strip number (1-3).
    control_ids : sequence of str
        GCPs used as full control; the other GCPs of the strip are checks.
    photo_step : int or "auto"
        ``[adjustment] photo_step``.
    camera : {"strip_m", "cal"}
        ``STRIP.m``'s principal distance with the principal point at the image
        centre, or ``cal.cal``'s focal length and principal point.
    distortion : bool
        Apply STRIP.m's radial distortion (r in mm, correction form).
    polynomial : int, "auto" or None
        J's polynomial (``block = "strips"``); None leaves it out: every
        model at once (``block = "models"``, the default).

    Returns
    -------
    Path
        The project file.
    """
    data = read_strip(data_dir, strip)
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = ["photo,point,x,y"]
    lines += [f"{p},{i},{x:.9f},{y:.9f}" for p, i, x, y in data.image_rows]
    (out_dir / "image_points.csv").write_text("\n".join(lines) + "\n")
    control = ["point,X,Y,H,type"]
    for pid, (e, n, h) in sorted(data.gcp.items(), key=lambda kv: int(kv[0])):
        kind = "full" if pid in control_ids else "check"
        control.append(f"{pid},{e:.3f},{n:.3f},{h:.3f},{kind}")
    (out_dir / "control.csv").write_text("\n".join(control) + "\n")
    if camera == "strip_m":
        c_mm = PRINCIPAL_DISTANCE_PX * PIXEL_SIZE_MM
        pp = (0.0, 0.0)
    elif camera == "cal":
        c_mm = CAL_FOCAL_PX * PIXEL_SIZE_MM
        # column right, row down -> x right, y up, from the image centre
        pp = (
            (CAL_PRINCIPAL_POINT_PX[0] - IMAGE_SIZE_PX[0] / 2) * PIXEL_SIZE_MM,
            -(CAL_PRINCIPAL_POINT_PX[1] - IMAGE_SIZE_PX[1] / 2) * PIXEL_SIZE_MM,
        )
    else:
        raise ValueError(f'Expected camera "strip_m" or "cal", got {camera!r}')
    step = f'"{photo_step}"' if isinstance(photo_step, str) else str(photo_step)
    poly = f'"{polynomial}"' if isinstance(polynomial, str) else str(polynomial)
    toml = [
        "[strip]",
        f'name = "FC300X strip {strip}"',
        "photos = [" + ", ".join(f'"{p}"' for p in data.photos) + "]",
        "",
        "[camera]",
        f"principal_distance_mm = {c_mm:.9f}",
        f"principal_point_mm = [{pp[0]:.9f}, {pp[1]:.9f}]",
        "",
        "[images]",
        'file = "image_points.csv"',
        "# x right, y up in mm from the image centre; the flight runs along +y",
        'flight_direction = "+y"',
        "# about one pixel",
        f"sigma_mm = {PIXEL_SIZE_MM:.8f}",
        "",
    ]
    if distortion:
        toml += [
            "[distortion]",
            "# src/STRIP.m: r in mm, corrected = measured + delta",
            f"k1 = {STRIP_M_K1!r}",
            f"k2 = {STRIP_M_K2!r}",
            'units = "mm"',
            'model = "correction"',
            "",
        ]
    toml += [
        "[control]",
        'file = "control.csv"',
        "# UTM easting, northing (zone not stated) used as a local site system",
        'crs = "local"',
        "",
        "[adjustment]",
        'route = "projected"',
        *([] if polynomial is None else [f"polynomial = {poly}"]),
        f"photo_step = {step}",
        "",
    ]
    path = out_dir / "strip.toml"
    path.write_text("\n".join(toml))
    return path


def _stepped(result: sa.StripResult) -> bool:
    """True when the strip's models were formed on every k-th photo (k > 1)."""
    return result.strip.n_models < result.strip.observations.n_photos - 1


def _run_stepped(project: Project) -> sa.StripResult:
    """``[adjustment] photo_step`` by hand: densify, then the ground stage."""
    from strip_aerotri.strip.densify import form_strip_stepped

    adj = project.adjustment
    options = sa.StripOptions(
        relative_orientation=str(adj.relative_orientation.value),
        intersection=str(adj.intersection.value),
        scale_transfer=str(adj.scale_transfer.value),
        max_iterations=int(adj.max_iterations),
    )
    strip = form_strip_stepped(
        project.observations,
        options,
        photo_step=adj.photo_step,
        min_base_to_height=adj.min_base_to_height,
    )
    ground = sa.adjust_to_ground(
        strip,
        project.control,
        project.crs,
        options=sa.GroundOptions(route=str(adj.route.value), polynomial=adj.polynomial),
    )
    residuals = ground.control_residuals
    return sa.StripResult(
        strip=strip,
        ground=ground,
        control=project.control,
        control_statistics=sa.AccuracyStatistics.from_residuals(residuals[~ground.is_check]),
        check_statistics=sa.AccuracyStatistics.from_residuals(residuals[ground.is_check]),
        warnings=project.warnings,
    )


def run(project: Project) -> sa.StripResult:
    """Adjust the project with ``run_project``.

    Where ``run_project`` does not yet honour ``[adjustment] photo_step``
    (its strip then has a model on every pair of consecutive photos, or the
    classical chain fails on the short bases), the same steps are done here
    with the public functions: ``densify.form_strip_stepped`` and
    ``adjust_to_ground``.
    """
    if project.adjustment.photo_step == 1:
        return sa.run_project(project)
    try:
        result = sa.run_project(project)
    except sa.StripAerotriError:
        return _run_stepped(project)
    return result if _stepped(result) else _run_stepped(project)


def ground_sample_distance(result: sa.StripResult) -> float:
    """Median GSD in metres: median camera-to-point distance / c · pixel size.

    The photos are oblique (about 43° off nadir), so the distance, not the
    height, sets the footprint of a pixel; it varies over the image.
    """
    obs = result.strip.observations
    distance = np.linalg.norm(result.points[obs.point] - result.photo_centres[obs.photo], axis=1)
    return float(np.nanmedian(distance)) / obs.principal_distance * PIXEL_SIZE_MM


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", type=Path, default=DATA_DIR)
    parser.add_argument("--out", type=Path, default=OUT_DIR)
    parser.add_argument("--step", default="2")
    parser.add_argument("--camera", default="cal", choices=("strip_m", "cal"))
    parser.add_argument("--no-distortion", action="store_true")
    parser.add_argument("--polynomial", default="1")
    args = parser.parse_args(argv)
    if not args.data.is_dir():
        print(f"data folder not found: {args.data}", file=sys.stderr)
        return 1
    step = args.step if args.step == "auto" else int(args.step)
    poly = args.polynomial if args.polynomial == "auto" else int(args.polynomial)
    toml = write_project(
        args.data,
        args.out / "project",
        photo_step=step,
        camera=args.camera,
        distortion=not args.no_distortion,
        polynomial=poly,
    )
    project = load_project(toml)
    result = run(project)
    stats = result.check_statistics
    c_mm = project.camera.principal_distance_mm
    gsd = ground_sample_distance(result)
    print(f"project: {toml}")
    print(
        f"photos {len(result.photo_ids)}, models {result.strip.n_models} "
        f"({', '.join(result.strip.model_labels)}), c = {c_mm:.4f} mm"
    )
    print(f"control: {', '.join(CONTROL_IDS)}")
    print(
        f"check points: {stats.n_plan} plan, {stats.n_height} height; RMSE E N H = "
        f"{stats.rmse[0]:.3f} {stats.rmse[1]:.3f} {stats.rmse[2]:.3f} m, plan "
        f"{stats.rmse_plan:.3f} m (GSD {gsd * 100:.2f} cm: plan {stats.rmse_plan / gsd:.1f} px, "
        f"height {stats.rmse[2] / gsd:.1f} px)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
