"""``stripaero import FORMAT ...``: write a ready project from another program's files.

Each format is a subcommand; they share the options that decide what the
source does not say (strips, photo order, flight direction, control and
check points) and how the project is written (``--out``, ``--force``).
Errors are raised as :class:`~strip_aerotri.errors.ConfigError` and become
one line on stderr and exit code 1 at the group's boundary (``cli/main.py``).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, overload

import click

from ..options import DEFAULT_DUPLICATE_TOL_MM, FlightDirection
from .options import F, common_options, echo_result, echo_warning

if TYPE_CHECKING:  # the formats are imported when a command runs (a fast --help)
    from ..importers.common import ImportedProject, ImportOptions
    from ..importers.odm import PixelCamera

__all__ = ["import_group"]

IMPORT_EPILOG = (
    "Documentation: stripaero docs import (every format, its options and what is decided)."
)


def _id_list(
    ctx: click.Context, param: click.Parameter, value: str | None
) -> tuple[str, ...] | None:
    if value is None:
        return None
    ids = tuple(v.strip() for v in value.split(",") if v.strip())
    if not ids:
        raise click.BadParameter("expected comma-separated ids")
    return ids


def _int_list(
    ctx: click.Context, param: click.Parameter, value: str | None
) -> tuple[int, ...] | None:
    if value is None:
        return None
    try:
        numbers = tuple(int(v) for v in value.split(",") if v.strip())
    except ValueError:
        raise click.BadParameter(
            f"expected comma-separated strip numbers, got {value!r}"
        ) from None
    if not numbers or min(numbers) < 1:
        raise click.BadParameter("expected strip numbers 1, 2, ...")
    return numbers


def _shared(func: F) -> F:
    """The options of every format."""
    decorators = [
        click.option(
            "-o",
            "--out",
            required=True,
            type=click.Path(file_okay=False, path_type=Path),
            help="Project folder to write (strip.toml and the CSV files).",
        ),
        click.option("--force", is_flag=True, help="Replace the --out folder if it exists."),
        click.option(
            "--strips",
            "strips",
            callback=_int_list,
            metavar="N[,N...]",
            help="Import only these strips (1, 2, ... in the order found); one strip gives a "
            "[strip] project, more a block of [[strips]].",
        ),
        click.option(
            "--control",
            "control_ids",
            callback=_id_list,
            metavar="IDS",
            help="Comma-separated full control points; every other GCP becomes a check point.",
        ),
        click.option(
            "--check",
            "check_ids",
            callback=_id_list,
            metavar="IDS",
            help="Comma-separated check points; with --control, GCPs in neither are left out.",
        ),
        click.option(
            "--flight-direction",
            type=click.Choice(["auto", *(d.value for d in FlightDirection)]),
            default="auto",
            show_default=True,
            help="Image axis along the flight; auto decides it from the shift of the points "
            "between consecutive photos.",
        ),
        click.option(
            "--photo-order",
            type=click.Path(dir_okay=False, path_type=Path),
            default=None,
            help="Text file, one strip per line: photo ids in flight order.",
        ),
        click.option("--name", default=None, help="Project name (default from the source)."),
        click.option(
            "--sigma-mm",
            type=click.FloatRange(min=0.0, min_open=True),
            default=None,
            help="[images] sigma_mm (default: one pixel when the pixel size is known).",
        ),
        click.option(
            "--turn-deg",
            type=click.FloatRange(min=1.0, max=179.0),
            default=45.0,
            show_default=True,
            help="Heading change that ends a strip when strips are found from positions.",
        ),
        common_options,
    ]
    for decorator in reversed(decorators):
        func = decorator(func)
    return func


def _camera_options(func: F) -> F:
    """Focal length, pixel size, image size and principal point of a digital camera."""
    decorators = [
        click.option(
            "--focal-mm",
            type=click.FloatRange(min=0.0, min_open=True),
            default=None,
            help="Calibrated focal length (principal distance), mm.",
        ),
        click.option(
            "--pixel-um",
            type=click.FloatRange(min=0.0, min_open=True),
            default=None,
            help="Pixel size, micrometres.",
        ),
        click.option(
            "--sensor-width-mm",
            type=click.FloatRange(min=0.0, min_open=True),
            default=None,
            help="Sensor width, mm (pixel size = width / image width).",
        ),
        click.option(
            "--image-size",
            type=(int, int),
            default=None,
            metavar="W H",
            help="Image width and height, pixels.",
        ),
        click.option(
            "--principal-point-px",
            type=(float, float),
            default=None,
            metavar="CX CY",
            help="Principal point column and row, pixels (default: image centre).",
        ),
    ]
    for decorator in reversed(decorators):
        func = decorator(func)
    return func


def _options(kw: dict[str, Any]) -> ImportOptions:
    from ..importers.common import ImportOptions
    from ..importers.text import read_photo_order

    direction = kw.pop("flight_direction")
    return ImportOptions(
        strips=kw.pop("strips"),
        control_ids=kw.pop("control_ids"),
        check_ids=kw.pop("check_ids"),
        flight_direction=None if direction == "auto" else direction,
        photo_order=read_photo_order(kw.pop("photo_order")),
        name=kw.pop("name"),
        sigma_mm=kw.pop("sigma_mm"),
        turn_deg=kw.pop("turn_deg"),
    )


@overload
def _camera(kw: dict[str, Any], required: Literal[True]) -> PixelCamera: ...


@overload
def _camera(kw: dict[str, Any], required: bool) -> PixelCamera | None: ...


def _camera(kw: dict[str, Any], required: bool) -> PixelCamera | None:
    from ..importers.odm import PixelCamera

    values = [
        kw.pop(k)
        for k in ("focal_mm", "pixel_um", "sensor_width_mm", "image_size", "principal_point_px")
    ]
    if not required and all(v is None for v in values):
        return None
    return PixelCamera.from_options(*values)


def _pixel_size_mm(kw: dict[str, Any], width: int | None = None) -> float | None:
    from ..importers.text import pixel_size_mm

    return pixel_size_mm(kw.pop("pixel_um", None), kw.pop("sensor_width_mm", None), width)


def _write(project: ImportedProject, out: Path, force: bool) -> None:
    from ..importers.common import write_project

    path = write_project(project, out, force=force)
    for text in project.warnings:
        echo_warning(text)
    echo_result(f"wrote {path}: {project.summary()}")
    echo_result(f"next: stripaero check {path}")


@click.group(
    name="import",
    epilog=IMPORT_EPILOG,
    short_help="Write a project from another program's files.",
)
@common_options
def import_group() -> None:
    """Write a ready project (strip.toml and CSV files) from another program's files.

    Each FORMAT reads its files, decides what they do not say (strips and
    photo order, the image axis along the flight, full control and check
    points; each decision is a comment at the top of strip.toml) and writes
    the project to --out, atomically.

    \b
    Examples:
      stripaero import uav-fc300x ../shared/data/uav-block-fc300x --out fc300x --strips 1
      stripaero import odm gcp_list.txt --ties sparse/0 --pixel-um 2.41 --out proj
      stripaero import patb block.im block.con --focal-mm 120 --crs EPSG:25832 --out proj
    """


@import_group.command("uav-fc300x", epilog=IMPORT_EPILOG)
@click.argument("data_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--crs",
    default="local",
    show_default=True,
    help="CRS of GCP_UTM.txt's E, N (its UTM zone is not stated in the data).",
)
@click.option("--no-distortion", is_flag=True, help="Leave out cal.cal's radial distortion.")
@click.option(
    "--duplicate-tol-mm",
    type=click.FloatRange(min=0.0),
    default=DEFAULT_DUPLICATE_TOL_MM,
    show_default=True,
    help="Observations closer than this on one photo are one point.",
)
@_shared
def uav_fc300x(
    data_dir: Path,
    crs: str,
    no_distortion: bool,
    duplicate_tol_mm: float,
    out: Path,
    force: bool,
    **kw: Any,  # the options of _shared and _camera_options, as click parsed them
) -> None:
    """The FC300X UAV block: image point files, GCP_UTM.txt and cal.cal in DATA_DIR.

    \b
    Examples:
      stripaero import uav-fc300x DATA --out fc300x-b1 --strips 1
      stripaero import uav-fc300x DATA --out fc300x-block
      stripaero import uav-fc300x DATA --out b1 --strips 1 --control 36,41,34,32,18,22
    """
    from ..importers.uav_fc300x import import_uav_fc300x

    project = import_uav_fc300x(
        data_dir,
        _options(kw),
        crs=crs,
        distortion=not no_distortion,
        duplicate_tol_mm=duplicate_tol_mm,
    )
    _write(project, out, force)


@import_group.command("odm", epilog=IMPORT_EPILOG)
@click.argument("gcp_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--ties",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="COLMAP text model of the same photos: tie points and camera.",
)
@click.option("--crs", default=None, help="Overrides the CRS line of GCP_FILE.")
@click.option(
    "--pose-crs",
    default=None,
    help="With --ties: the model is geo-registered in this CRS; its projection centres "
    "are written as [gnss].",
)
@_camera_options
@_shared
def odm(
    gcp_file: Path,
    ties: Path | None,
    crs: str | None,
    pose_crs: str | None,
    out: Path,
    force: bool,
    **kw: Any,  # the options of _shared and _camera_options, as click parsed them
) -> None:
    """OpenDroneMap / WebODM gcp_list.txt (GCPs and their pixel positions).

    The file has no tie points: add them with --ties (a COLMAP text model of
    the same photos), which also gives the camera. Without --ties give the
    camera with --focal-mm, --pixel-um (or --sensor-width-mm) and --image-size.

    \b
    Examples:
      stripaero import odm gcp_list.txt --ties sparse/0 --pixel-um 2.41 --out proj
      stripaero import odm gcp_list.txt --focal-mm 8.8 --pixel-um 2.41 \\
          --image-size 4000 3000 --out proj
    """
    from ..importers.odm import import_odm

    options = _options(kw)
    if ties is not None:
        camera_given = any(kw.get(k) is not None for k in ("focal_mm", "principal_point_px"))
        if camera_given:
            from ..errors import ConfigError

            raise ConfigError(
                "with --ties the camera comes from the COLMAP model; leave out "
                "--focal-mm and --principal-point-px"
            )
        size = kw.pop("image_size")
        kw.pop("focal_mm"), kw.pop("principal_point_px")
        pixel = _pixel_size_mm(kw, size[0] if size else None)
        project = import_odm(
            gcp_file, options, ties=ties, pixel_size_mm=pixel, crs=crs, pose_crs=pose_crs
        )
    else:
        project = import_odm(gcp_file, options, camera=_camera(kw, True), crs=crs)
    _write(project, out, force)


@import_group.command("colmap", epilog=IMPORT_EPILOG)
@click.argument("model_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--gcps",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="Control: an OpenDroneMap gcp_list.txt of the same photos.",
)
@click.option(
    "--pixel-um",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    help="Pixel size, micrometres.",
)
@click.option(
    "--sensor-width-mm",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    help="Sensor width, mm (pixel size = width / the camera's image width).",
)
@click.option("--crs", default=None, help="Overrides the CRS of --gcps.")
@click.option(
    "--pose-crs",
    default=None,
    help="The model is geo-registered in this CRS (e.g. EPSG:4978 for ECEF): its "
    "projection centres are written as [gnss].",
)
@click.option(
    "--min-track",
    type=click.IntRange(min=2),
    default=2,
    show_default=True,
    help="Leave out 3D points seen on fewer photos.",
)
@click.option(
    "--max-error-px",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    help="Leave out 3D points with a larger reprojection error.",
)
@_shared
def colmap(
    model_dir: Path,
    gcps: Path,
    crs: str | None,
    pose_crs: str | None,
    min_track: int,
    max_error_px: float | None,
    out: Path,
    force: bool,
    **kw: Any,  # the options of _shared and _camera_options, as click parsed them
) -> None:
    """COLMAP text model (cameras.txt, images.txt, points3D.txt) in MODEL_DIR, with GCPs.

    \b
    Examples:
      stripaero import colmap sparse/0 --gcps gcp_list.txt --pixel-um 2.41 --out proj
      stripaero import colmap geo/0 --gcps gcp_list.txt --pixel-um 2.41 \\
          --pose-crs EPSG:32632 --out proj
    """
    from ..importers.colmap import import_colmap, read_cameras

    width = None
    if kw.get("sensor_width_mm") is not None:
        cameras = read_cameras(model_dir / "cameras.txt")
        width = next(iter(cameras.values())).width
    pixel = _pixel_size_mm(kw, width)
    if pixel is None:
        from ..errors import ConfigError

        raise ConfigError("COLMAP works in pixels: give --pixel-um or --sensor-width-mm")
    project = import_colmap(
        model_dir,
        _options(kw),
        pixel_size_mm=pixel,
        gcps=gcps,
        crs=crs,
        pose_crs=pose_crs,
        min_track=min_track,
        max_error_px=max_error_px,
    )
    _write(project, out, force)


@import_group.command("patb", epilog=IMPORT_EPILOG)
@click.argument("im_file", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("con_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--focal-mm",
    type=click.FloatRange(min=0.0, min_open=True),
    required=True,
    help="Calibrated principal distance, mm.",
)
@click.option("--crs", required=True, help="CRS of the control coordinates (or 'local').")
@click.option(
    "--units",
    type=click.Choice(["mm", "um"]),
    default="mm",
    show_default=True,
    help="Units of the .im coordinates (the .pro file states them).",
)
@click.option(
    "--principal-point-mm",
    type=(float, float),
    default=None,
    metavar="X0 Y0",
    help="Principal point, when the .im coordinates are not reduced to it.",
)
@click.option(
    "--ori",
    "ori_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="PATB .ori file: its projection centres as [gnss] and to find the strips.",
)
@_shared
def patb(
    im_file: Path,
    con_file: Path,
    focal_mm: float,
    crs: str,
    units: str,
    principal_point_mm: tuple[float, float] | None,
    ori_file: Path | None,
    out: Path,
    force: bool,
    **kw: Any,  # the options of _shared and _camera_options, as click parsed them
) -> None:
    """PATB image coordinates (IM_FILE) and control points (CON_FILE).

    \b
    Examples:
      stripaero import patb block.im block.con --focal-mm 153.2 --crs EPSG:25832 --out proj
      stripaero import patb block.im block.con --focal-mm 100.5 --units um --crs local --out proj
    """
    from ..importers.patb import import_patb

    project = import_patb(
        im_file,
        con_file,
        _options(kw),
        focal_mm=focal_mm,
        crs=crs,
        principal_point_mm=principal_point_mm,
        units=units,
        ori_file=ori_file,
    )
    _write(project, out, force)


@import_group.command("metashape", epilog=IMPORT_EPILOG)
@click.argument("markers_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--cameras",
    "cameras_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Omega Phi Kappa camera text: [gnss] and [imu].",
)
@click.option("--crs", default=None, help="Overrides the chunk CRS.")
@click.option("--no-attitudes", is_flag=True, help="Do not write the attitudes ([imu]).")
@click.option(
    "--source-types",
    is_flag=True,
    help="Control types from the markers' reference flags (enabled: full control, "
    "disabled: check point) instead of the default choice.",
)
@_camera_options
@_shared
def metashape(
    markers_file: Path,
    cameras_file: Path | None,
    crs: str | None,
    no_attitudes: bool,
    source_types: bool,
    out: Path,
    force: bool,
    **kw: Any,  # the options of _shared and _camera_options, as click parsed them
) -> None:
    """Agisoft Metashape markers XML (MARKERS_FILE), optionally with its OPK camera text.

    \b
    Examples:
      stripaero import metashape markers.xml --cameras opk.txt --out proj
      stripaero import metashape markers.xml --focal-mm 8.8 --pixel-um 2.41 \\
          --image-size 4000 3000 --out proj
    """
    from ..importers.metashape import import_metashape

    project = import_metashape(
        markers_file,
        _options(kw),
        cameras_file=cameras_file,
        camera=_camera(kw, False),
        crs=crs,
        attitudes=not no_attitudes,
        source_types=source_types,
    )
    _write(project, out, force)


@import_group.command("pix4d", epilog=IMPORT_EPILOG)
@click.argument("marks_file", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("gcp_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--crs", required=True, help="CRS of the GCPs and of the external parameters.")
@click.option(
    "--external",
    "external_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="*_calibrated_external_camera_parameters.txt: [gnss] and [imu].",
)
@click.option(
    "--gcp-axis-order",
    type=click.Choice(["auto", "xy", "yx"]),
    default="auto",
    show_default=True,
    help="Order of the GCP file's two coordinates (auto: the CRS's).",
)
@click.option("--no-attitudes", is_flag=True, help="Do not write the attitudes ([imu]).")
@_camera_options
@_shared
def pix4d(
    marks_file: Path,
    gcp_file: Path,
    crs: str,
    external_file: Path | None,
    gcp_axis_order: str,
    no_attitudes: bool,
    out: Path,
    force: bool,
    **kw: Any,  # the options of _shared and _camera_options, as click parsed them
) -> None:
    """Pix4D marks (MARKS_FILE) and GCP coordinates (GCP_FILE), optionally external parameters.

    \b
    Examples:
      stripaero import pix4d marks.csv gcps.csv --crs EPSG:32632 --focal-mm 8.8 \\
          --pixel-um 2.41 --image-size 4000 3000 --out proj \\
          --external p_calibrated_external_camera_parameters.txt
    """
    from ..importers.pix4d import import_pix4d

    project = import_pix4d(
        marks_file,
        gcp_file,
        _options(kw),
        camera=_camera(kw, True),
        crs=crs,
        external_file=external_file,
        gcp_axis_order=gcp_axis_order,
        attitudes=not no_attitudes,
    )
    _write(project, out, force)
