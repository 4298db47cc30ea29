"""``stripaero export``: files for other programs from a finished run."""

from __future__ import annotations

from pathlib import Path

import click

from .options import DOCS_EPILOG, common_options, echo_result, project_arg

__all__ = ["export"]


@click.group(epilog=DOCS_EPILOG, short_help="Write files for other programs from a run.")
def export() -> None:
    """Write files for other programs from the result folder of a run."""


@export.command("cameras", epilog=DOCS_EPILOG)
@project_arg
@click.option(
    "--from",
    "results",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="The run's result folder (default: the project's, as stripaero run chose it).",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="File to write (default: cameras_opk.txt in the result folder).",
)
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
    import os

    import numpy as np

    from ..errors import ConfigError
    from ..export import cameras_opk_text
    from ..project import load_project

    project = load_project(project_file)
    folder = results or project.output_directory or project.path.parent / "out"
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
    partial = target.with_name(f".{target.name}.partial")
    partial.write_text(text, encoding="utf-8")
    os.replace(partial, target)  # whole or not at all
    echo_result(f"wrote {target}: {len(ids)} photos")
