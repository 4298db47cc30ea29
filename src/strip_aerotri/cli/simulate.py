"""``stripaero simulate``: write a ready project of a simulated strip."""

from __future__ import annotations

from pathlib import Path

import click

from .options import DOCS_EPILOG, common_options, echo_progress, echo_result

__all__ = ["PRESET_NAMES", "simulate"]

PRESET_NAMES = ("film", "drone", "corridor")
"""Names of :data:`strip_aerotri.simulate.PRESETS` (listed here so that --help
does not import the simulator)."""

PROJECT_FILES = ("strip.toml", "image_points.csv", "control.csv")


@click.command(epilog=DOCS_EPILOG, short_help="Write a simulated project to try the tool.")
@click.argument("preset", type=click.Choice(PRESET_NAMES, case_sensitive=False))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Project folder to write (created if needed).",
)
@click.option(
    "--photos",
    type=click.IntRange(min=3),
    default=12,
    show_default=True,
    help="Number of photos.",
)
@click.option(
    "--crs",
    default="EPSG:32634",
    show_default=True,
    help='Control CRS (any horizontal CRS pyproj understands, or "local").',
)
@click.option(
    "--heading",
    type=float,
    default=75.0,
    show_default=True,
    metavar="DEG",
    help="Flight azimuth, degrees clockwise from north.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option(
    "--noise-um",
    type=click.FloatRange(min=0.0),
    default=None,
    metavar="X",
    help="Image noise standard deviation in micrometres (default: the preset's).",
)
@click.option(
    "--control",
    "control_layout",
    type=click.Choice(["ends", "every_k_models", "dense"]),
    default="ends",
    show_default=True,
    help="Control layout.",
)
@click.option(
    "--polynomial",
    type=click.Choice(["0", "1", "2", "3", "auto"]),
    default="3",
    show_default=True,
    help="[adjustment] polynomial written to strip.toml.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Overwrite strip.toml, image_points.csv and control.csv already in the folder.",
)
@common_options
def simulate(
    preset: str,
    out: Path,
    photos: int,
    crs: str,
    heading: float,
    seed: int,
    noise_um: float | None,
    control_layout: str,
    polynomial: str,
    force: bool,
) -> None:
    """Write a project of a simulated strip of PRESET to the folder --out.

    PRESET is "film" (1:8000 wide-angle film, 60 % overlap), "drone" (1-inch
    sensor at 120 m, 80 % overlap) or "corridor" (film with a straight road
    whose points form a straight-line condition). The strip is simulated on
    the curved earth with a known truth; control and check points follow the
    chosen layout. The folder then holds strip.toml, image_points.csv and
    control.csv, ready for `stripaero run`.

    \b
    Examples:
      stripaero simulate film --out demo
      stripaero simulate corridor --out road --photos 20 --crs EPSG:2180 --seed 3
      stripaero run demo/strip.toml
    """
    existing = [name for name in PROJECT_FILES if (out / name).exists()]
    if existing and not force:
        from ..io import OutputError

        raise OutputError(
            f"{out / existing[0]} already exists; give another --out or --force to overwrite"
        )
    if out.exists() and not out.is_dir():
        from ..io import OutputError

        raise OutputError(f"--out: '{out}' is a file, not a folder")

    from ..simulate import simulate_strip

    echo_progress(f"simulating a {preset} strip of {photos} photos (seed {seed})")
    try:
        sim = simulate_strip(
            photos,
            preset=preset.lower(),
            crs=crs if crs.lower() != "local" else "local",
            heading_deg=heading,
            seed=seed,
            image_noise_mm=None if noise_um is None else noise_um / 1000.0,
            control=control_layout,
        )
    except ValueError as exc:
        from ..errors import ConfigError

        raise ConfigError(f"simulate {preset}: {exc}") from exc
    poly: int | str = polynomial if polynomial == "auto" else int(polynomial)
    toml_path = sim.write_project(out, polynomial=poly)
    obs = sim.observations
    kinds = [k.value for k in sim.control.kind]
    echo_result(
        f"wrote {toml_path}: {obs.n_photos} photos, {obs.n_points} points, "
        f"{len(kinds) - kinds.count('check')} control and {kinds.count('check')} check points"
        + (f", {len(sim.lines)} straight line(s)" if sim.lines else "")
    )
    echo_result(f"run it with: stripaero run {toml_path}")
