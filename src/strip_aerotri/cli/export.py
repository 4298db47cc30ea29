"""``stripaero export``: files for other programs from a finished run."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from .options import DOCS_EPILOG, common_options, echo_result, project_arg

if TYPE_CHECKING:
    from ..export.tables import ResultTable
    from ..project import Project

__all__ = ["export"]

F = TypeVar("F", bound=Callable[..., Any])


def _result_folder(project: Project, results: Path | None) -> Path:
    """The run's result folder: ``--from``, else where ``stripaero run`` wrote it."""
    from ..project import DEFAULT_OUTPUT

    return results or project.output_directory or project.path.parent / DEFAULT_OUTPUT


def _tables(
    project_file: Path, results: Path | None
) -> tuple[Project, Path, ResultTable, ResultTable]:
    """The project, its result folder and the points and photos tables read
    from it (:func:`strip_aerotri.export.read_results`)."""
    from ..export import read_results
    from ..project import load_project

    project = load_project(project_file)
    folder = _result_folder(project, results)
    points, photos = read_results(folder)
    return project, folder, points, photos


def _write_whole(target: Path, data: str | bytes) -> None:
    """Write ``target`` whole or not at all (:func:`strip_aerotri._atomic.atomic_file`)."""
    from .._atomic import atomic_file

    def write() -> None:
        with atomic_file(target) as partial:
            if isinstance(data, str):
                partial.write_text(data, encoding="utf-8")
            else:
                partial.write_bytes(data)

    _written(target, write)


def _written(target: Path, write: Callable[[], None]) -> None:
    """Call ``write``; an I/O error names ``target`` (not a temporary file), and
    a file written into a result folder is noted in its marker, so that the
    next run keeps it."""
    from ..errors import StripAerotriError
    from ..report.files import OutputError, record_export

    try:
        write()
    except StripAerotriError:
        raise
    except (OSError, RuntimeError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc).splitlines()[0]
        raise OutputError(f"cannot write '{target}': {reason}") from exc
    try:
        record_export(target)
    except OSError:
        pass  # the export is written; only the note for the next run is missing


_FROM_HELP = "The run's result folder (default: the project's, as stripaero run chose it)."
from_option = click.option(
    "--from",
    "results",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help=_FROM_HELP,
)


def out_option(default_name: str) -> Callable[[F], F]:
    """``-o/--out FILE``, by default ``default_name`` in the result folder."""
    return click.option(
        "-o",
        "--out",
        type=click.Path(dir_okay=False, path_type=Path),
        default=None,
        help=f"File to write (default: {default_name} in the result folder).",
    )


@click.group(epilog=DOCS_EPILOG, short_help="Write files for other programs from a run.")
def export() -> None:
    """Write files for other programs from the result folder of a run."""


@export.command("cameras", epilog=DOCS_EPILOG)
@project_arg
@from_option
@out_option("cameras_opk.txt")
@common_options
def cameras(project_file: Path, results: Path | None, out: Path | None) -> None:
    """Photo centres and omega, phi, kappa for Pix4D and Metashape.

    Reads STRIP_TOML (for the CRS and the image axes) and the photos.csv of
    its result folder, and writes one line per photo, imageName X Y Z Omega
    Phi Kappa: the PATB angles on the map grid, camera x right, y up
    (docs/export.md). A geographic CRS has no map grid and is refused.

    \b
    Examples:
      stripaero export cameras strip.toml
      stripaero export cameras strip.toml --from out-2024 -o cameras.txt
    """
    import csv

    import numpy as np

    from ..errors import ConfigError
    from ..export import cameras_opk_text
    from ..project import load_project

    project = load_project(project_file)
    folder = _result_folder(project, results)
    table = folder / "photos.csv"
    if not table.is_file():
        raise ConfigError(f"{table}: not found; run the project first (stripaero run)")
    with table.open(encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    try:
        ids = [r["photo"] for r in rows]
        centres = np.array([[float(r[c]) for c in ("X", "Y", "Z")] for r in rows])
        opk = np.radians([[float(r[c]) for c in ("omega", "phi", "kappa")] for r in rows])
    except (KeyError, ValueError) as exc:
        raise ConfigError(f"{table}: not a photos.csv of stripaero run ({exc})") from None
    text = cameras_opk_text(ids, centres, opk, project.crs, project.images.flight_direction)
    target = out or folder / "cameras_opk.txt"
    _write_whole(target, text)
    echo_result(f"wrote {target}: {len(ids)} photos")


_ROLES = {
    "control": ("control-full", "control-plan", "control-height"),
    "check": ("check",),
    "marked": ("control-full", "control-plan", "control-height", "check"),
    "all": None,
}


@export.command("odm", epilog=DOCS_EPILOG)
@project_arg
@from_option
@out_option("gcp_list.txt")
@click.option(
    "--points",
    type=click.Choice(list(_ROLES)),
    default="marked",
    show_default=True,
    help="Which points: the control, the check points, both (marked) or every triangulated point.",
)
@click.option(
    "--image-ext",
    default="",
    help="Appended to the photo ids to give the image file names (e.g. .JPG).",
)
@common_options
def odm(
    project_file: Path, results: Path | None, out: Path | None, points: str, image_ext: str
) -> None:
    """Points with their pixel measurements as OpenDroneMap's gcp_list.txt.

    Reads STRIP_TOML (its CRS and its image file, measured in pixels or in mm
    with [images] pixel_size_mm and principal_point_px, as the FC300X import
    writes them) and the points.csv of its result folder, and writes a line per
    observation of each chosen point: its adjusted coordinates, its pixel
    column and row, the image and the point (docs/export.md).

    \b
    Examples:
      stripaero export odm strip.toml --image-ext .JPG
      stripaero export odm strip.toml --points all -o gcp_list.txt
    """
    import csv

    import numpy as np

    from ..errors import ConfigError
    from ..export import gcp_list_text
    from ..options import ImageUnits
    from ..project import IMAGE_COLUMNS, load_project
    from ..project.csvfiles import float_column, read_csv

    project = load_project(project_file)
    images = project.images
    in_mm = images.units is not ImageUnits.PIXEL
    if in_mm and (images.pixel_size_mm is None or images.principal_point_px is None):
        raise ConfigError(
            f"{project.path}: [images]: gcp_list.txt needs pixels, and this project's image "
            "coordinates are in millimetres without pixel_size_mm and principal_point_px (the "
            "pixel column and row of the mm origin); add them to convert"
        )
    folder = _result_folder(project, results)
    table = folder / "points.csv"
    if not table.is_file():
        raise ConfigError(f"{table}: not found; run the project first (stripaero run)")
    wanted = _ROLES[points]
    with table.open(encoding="utf-8", newline="") as fh:
        rows = [
            r
            for r in csv.DictReader(line for line in fh if not line.startswith("#"))
            if wanted is None or r.get("role") in wanted
        ]
    geo_of = {r["point"]: [float(r[c]) for c in ("X", "Y", "H")] for r in rows}
    raw = read_csv(project.images_file, IMAGE_COLUMNS, "[images] file")
    column, _ = float_column(raw, "x")
    row_px, _ = float_column(raw, "y")
    if in_mm:  # x right, y up in mm from the origin at principal_point_px
        size, (c0, r0) = float(images.pixel_size_mm), images.principal_point_px  # type: ignore[arg-type, misc]
        column, row_px = c0 + column / size, r0 - row_px / size
    line_to_row = {int(line): k for k, line in enumerate(raw.line)}
    obs = project.observations
    keep = [k for k in range(obs.photo.size) if obs.point_ids[int(obs.point[k])] in geo_of]
    source = [line_to_row[int(obs.source_line[k])] for k in keep]
    names = [obs.point_ids[int(obs.point[k])] for k in keep]
    text = gcp_list_text(
        project.crs,
        np.array([geo_of[n] for n in names]).reshape(-1, 3),
        np.column_stack([column[source], row_px[source]]),
        [obs.photo_ids[int(obs.photo[k])] + image_ext for k in keep],
        names,
    )
    target = out or folder / "gcp_list.txt"
    _write_whole(target, text)
    echo_result(f"wrote {target}: {len(geo_of)} points, {len(keep)} observations")


@export.command("geojson", epilog=DOCS_EPILOG)
@project_arg
@from_option
@out_option("results.geojson")
@common_options
def geojson(project_file: Path, results: Path | None, out: Path | None) -> None:
    """Points and photo centres as GeoJSON (WGS 84 longitude, latitude).

    Reads STRIP_TOML (for the CRS) and the points.csv and photos.csv of its
    result folder, and writes one RFC 7946 FeatureCollection: a feature per
    point (role, residuals, counts: every column of points.csv) and per photo
    centre (strip, omega, phi, kappa in degrees as in photos.csv)
    (docs/export.md). crs = "local" has no geodesy to WGS 84 and is refused.

    \b
    Examples:
      stripaero export geojson strip.toml
      stripaero export geojson strip.toml --from out-2024 -o strip.geojson
    """
    from ..export import results_geojson

    project, folder, points, photos = _tables(project_file, results)
    text = results_geojson(points, photos, project.crs, strip=project.name)
    target = out or folder / "results.geojson"
    _write_whole(target, text)
    echo_result(f"wrote {target}: {len(points.ids)} points, {len(photos.ids)} photo centres")


@export.command("gpkg", epilog=DOCS_EPILOG)
@project_arg
@from_option
@out_option("results.gpkg")
@common_options
def gpkg(project_file: Path, results: Path | None, out: Path | None) -> None:
    """Points and photo centres as a GeoPackage in the project's CRS.

    Reads STRIP_TOML (for the CRS) and the points.csv and photos.csv of its
    result folder, and writes two layers, points and photo_centres, with
    every column of the tables as fields (docs/export.md). crs = "local"
    writes the site coordinates without a CRS. Needs pyogrio:
    pip install 'strip_aerotri[gpkg]'.

    \b
    Examples:
      stripaero export gpkg strip.toml
      stripaero export gpkg strip.toml --from out-2024 -o strip.gpkg
    """
    from ..export import write_gpkg

    project, folder, points, photos = _tables(project_file, results)
    target = out or folder / "results.gpkg"
    _written(target, lambda: write_gpkg(target, points, photos, project.crs, strip=project.name))
    echo_result(f"wrote {target}: {len(points.ids)} points, {len(photos.ids)} photo centres")
