"""``stripaero simulate``: write a ready project of a simulated strip or block."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .options import DOCS_EPILOG, common_options, echo_progress, echo_result

if TYPE_CHECKING:  # the simulator is imported when the command runs
    from ..simulate import SimulatedBlock, SimulatedStrip, StripPreset

__all__ = ["BLOCK_CONTROL_LAYOUTS", "CAMERA_NAMES", "CONTROL_LAYOUTS", "PRESET_NAMES", "simulate"]

PRESET_NAMES = ("film", "drone", "corridor")
"""Names of :data:`strip_aerotri.simulate.PRESETS` (listed here so that --help
does not import the simulator)."""

PROJECT_FILES = ("strip.toml", "image_points.csv", "control.csv")


CAMERA_NAMES = ("film88", "film152", "film210", "ff35", "apsc16", "oneinch")
"""Names of :data:`strip_aerotri.simulate.CAMERAS` (listed here for --help)."""

CONTROL_LAYOUTS = ("ends", "fig4", "every_k_models", "dense", "weak")
"""The simulator's control layouts (listed here for --help)."""

BLOCK_CONTROL_LAYOUTS = ("perimeter", "corners")
"""The control layouts of blocks only (a block takes the strip layouts too)."""

FLIGHTS = ("serpentine", "same")


@click.command(epilog=DOCS_EPILOG, short_help="Write a simulated project to try the tool.")
@click.argument("preset", type=click.Choice(PRESET_NAMES, case_sensitive=False), required=False)
@click.option(
    "--camera",
    type=click.Choice(CAMERA_NAMES, case_sensitive=False),
    default=None,
    help="A camera instead of PRESET: film 88/152/210 mm on 230 mm, ff35 (35 mm on "
    "36x24), apsc16, oneinch (8.8 mm on 13.2x8.8).",
)
@click.option(
    "--long-side",
    type=click.Choice(["along", "across"]),
    default="along",
    show_default=True,
    help="With --camera: the format's long side along or across the flight.",
)
@click.option(
    "--overlap",
    type=click.FloatRange(51.0, 95.0),
    default=None,
    metavar="PCT",
    help="With --camera: forward overlap in percent (default 60 film, 80 sensors).",
)
@click.option(
    "--height-m",
    type=click.FloatRange(min=1.0),
    default=None,
    help="With --camera: flying height above the terrain, m (default 1:8000 film, 120 m).",
)
@click.option(
    "--tilt-deg",
    type=click.FloatRange(min=0.0, max=10.0),
    default=None,
    help="With --camera: standard deviation of omega and phi (default 1.5).",
)
@click.option(
    "--kappa-deg",
    type=click.FloatRange(min=0.0, max=30.0),
    default=None,
    help="With --camera: standard deviation of kappa about the heading (default 2).",
)
@click.option(
    "--relief-m",
    type=click.FloatRange(min=0.0),
    default=None,
    help="With --camera: terrain relief amplitude, m (default 5 % of the height).",
)
@click.option(
    "--line/--no-line",
    default=None,
    help="A straight road along the strip whose points form a straight-line condition.",
)
@click.option(
    "--image-blunders",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Observations given a gross error (15-40 times the noise).",
)
@click.option(
    "--control-blunders",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Control points given a gross error of 0.5-2 m in one coordinate.",
)
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
    help="Number of photos (of each strip of a block).",
)
@click.option(
    "--strips",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help="Number of parallel strips: 2 or more write a block ([[strips]] tables).",
)
@click.option(
    "--side-overlap",
    type=click.FloatRange(20.0, 60.0),
    default=None,
    metavar="PCT",
    help="With --strips: side overlap of adjacent strips in percent (default 30).",
)
@click.option(
    "--flight",
    type=click.Choice(FLIGHTS),
    default=None,
    help="With --strips: every other strip flown the other way (serpentine, the "
    "default) or all strips in the same direction.",
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
    type=click.Choice(CONTROL_LAYOUTS + BLOCK_CONTROL_LAYOUTS),
    default=None,
    help="Control layout (default: ends for a strip, perimeter for a block; perimeter "
    "and corners are for blocks, the others give each strip its own control).",
)
@click.option(
    "--polynomial",
    type=click.Choice(["0", "1", "2", "3", "auto"]),
    default=None,
    help="[adjustment] polynomial written to strip.toml (J's construction; with --strips "
    'every strip\'s own, block = "strips", 0-3); without it every model is transformed at '
    "once (the default).",
)
@click.option(
    "--camera-error",
    "camera_errors",
    multiple=True,
    metavar="NAME=VALUE",
    help="An uncorrected camera error, repeatable: a Brown/Fraser parameter (c, x0, y0 in "
    "mm; k1, k2, k3 in mm^-2, mm^-4, mm^-6; p1, p2 in mm^-1; b1 affinity, b2 shear) as the "
    "correction the measurements need (docs/bundle.md, Self-calibration); e.g. "
    "--camera-error k1=-3e-8 --camera-error b1=6e-5.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Overwrite strip.toml, image_points.csv and control.csv already in the folder.",
)
@common_options
def simulate(
    preset: str | None,
    camera: str | None,
    long_side: str,
    overlap: float | None,
    height_m: float | None,
    tilt_deg: float | None,
    kappa_deg: float | None,
    relief_m: float | None,
    line: bool | None,
    image_blunders: int,
    control_blunders: int,
    out: Path,
    photos: int,
    strips: int,
    side_overlap: float | None,
    flight: str | None,
    crs: str,
    heading: float,
    seed: int,
    noise_um: float | None,
    control_layout: str | None,
    polynomial: str | None,
    camera_errors: tuple[str, ...],
    force: bool,
) -> None:
    """Write a project of a simulated strip or block of PRESET to the folder --out.

    PRESET is "film" (1:8000 wide-angle film, 60 % overlap), "drone" (1-inch
    sensor at 120 m, 80 % overlap) or "corridor" (film with a straight road
    whose points form a straight-line condition). Instead of a preset,
    --camera with --long-side, --overlap, --height-m, --tilt-deg,
    --kappa-deg and --relief-m describes any camera and flight. The strip is
    simulated on the curved earth with a known truth; control and check
    points follow the chosen layout ("fig4": three full points at each end,
    height points between, R4's strip layout). The folder then holds
    strip.toml, image_points.csv and control.csv, ready for `stripaero run`.

    With --strips N (2 or more) the project is a block of N parallel strips
    of --photos photos each, --side-overlap percent apart, flown --flight
    serpentine or same; the points of each side overlap are observed on the
    photos of both strips, and the default control runs around the block's
    perimeter ("perimeter"; "corners": four corners and heights across the
    middle).

    \b
    Examples:
      stripaero simulate film --out demo
      stripaero simulate corridor --out road --photos 20 --crs EPSG:2180 --seed 3
      stripaero simulate --camera ff35 --overlap 80 --height-m 150 --tilt-deg 2.5 \\
          --kappa-deg 3 --noise-um 5 --photos 60 --control fig4 --out drone
      stripaero simulate drone --strips 4 --photos 15 --side-overlap 40 --out block
      stripaero run demo/strip.toml
    """
    _check_out(out, force)

    from ..errors import ConfigError
    from ..simulate import camera_preset, simulate_block, simulate_strip

    camera_flight = {
        "--overlap": overlap,
        "--height-m": height_m,
        "--tilt-deg": tilt_deg,
        "--kappa-deg": kappa_deg,
        "--relief-m": relief_m,
    }
    if (preset is None) == (camera is None):
        raise click.UsageError("give either PRESET or --camera")
    if camera is None and any(v is not None for v in camera_flight.values()):
        given = next(k for k, v in camera_flight.items() if v is not None)
        raise click.UsageError(f"{given} describes the flight of --camera, not of a preset")
    block = strips >= 2
    _check_block_flags(block, preset, line, control_layout, side_overlap, flight)
    layout = control_layout or ("perimeter" if block else "ends")
    what = preset.lower() if preset is not None else f"{camera} ({long_side})"
    if block:
        side = 30.0 if side_overlap is None else side_overlap
        pattern = flight or "serpentine"
        echo_progress(
            f"simulating a {what} block of {strips} strips x {photos} photos, {side:g} % side "
            f"overlap, {pattern} flight (seed {seed})"
        )
    else:
        echo_progress(f"simulating a {what} strip of {photos} photos (seed {seed})")
    chosen: StripPreset | str
    try:
        if camera is not None:
            film = camera.lower().startswith("film")
            chosen = camera_preset(
                camera.lower(),
                long_side=long_side,
                forward_overlap=(overlap if overlap is not None else (60.0 if film else 80.0))
                / 100.0,
                flying_height_m=height_m,
                tilt_deg=1.5 if tilt_deg is None else tilt_deg,
                kappa_deg=2.0 if kappa_deg is None else kappa_deg,
                relief_m=relief_m,
                noise_um=noise_um,
                line=bool(line),
            )
        else:
            assert preset is not None  # PRESET or --camera, checked above
            chosen = preset.lower()
        common: dict[str, Any] = {
            "preset": chosen,
            "crs": crs if crs.lower() != "local" else "local",
            "heading_deg": heading,
            "seed": seed,
            "image_noise_mm": (
                None if noise_um is None or camera is not None else noise_um / 1000.0
            ),
            "control": layout,
            "image_blunders": image_blunders,
            "control_blunders": control_blunders,
            "camera_errors": _camera_errors(camera_errors),
        }
        sim: SimulatedStrip | SimulatedBlock
        if block:
            extra: dict[str, Any] = {"line": False} if camera is None and line is False else {}
            sim = simulate_block(
                strips,
                photos,
                side_overlap=side / 100.0,
                flight=pattern,
                **common,
                **extra,
            )
        else:
            sim = simulate_strip(photos, line=line if camera is None else None, **common)
    except ValueError as exc:
        raise ConfigError(f"simulate {what}: {exc}") from exc
    _echo_written(sim, _write(sim, out, polynomial))


def _check_out(out: Path, force: bool) -> None:
    """--out may be written: no project there unless --force, not a file."""
    from ..report.files import OutputError

    existing = [name for name in PROJECT_FILES if (out / name).exists()]
    if existing and not force:
        raise OutputError(
            f"{out / existing[0]} already exists; give another --out or --force to overwrite"
        )
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out: '{out}' is a file, not a folder")


def _check_block_flags(
    block: bool,
    preset: str | None,
    line: bool | None,
    control_layout: str | None,
    side_overlap: float | None,
    flight: str | None,
) -> None:
    """The options of a block given only with --strips 2 or more, and a
    straight road only for one strip."""
    if not block:
        for given, value in (("--side-overlap", side_overlap), ("--flight", flight)):
            if value is not None:
                raise click.UsageError(f"{given} describes a block: give --strips 2 or more")
        if control_layout in BLOCK_CONTROL_LAYOUTS:
            raise click.UsageError(
                f"--control {control_layout} is for a block: give --strips 2 or more"
            )
    elif line or (preset is not None and preset.lower() == "corridor" and line is None):
        raise click.UsageError(
            "a block has no straight road: --line and the corridor preset are for one "
            "strip (--no-line turns the corridor's road off)"
        )


def _echo_written(sim: SimulatedStrip | SimulatedBlock, toml_path: Path) -> None:
    """What was written, and how to run it."""
    from ..simulate import SimulatedBlock

    obs = sim.observations
    kinds = [k.value for k in sim.control.kind]
    counts = f"{len(kinds) - kinds.count('check')} control and {kinds.count('check')} check points"
    if isinstance(sim, SimulatedBlock):
        shared = min(len(sim.common_points(s, s + 1)) for s in range(len(sim.strips) - 1))
        echo_result(
            f"wrote {toml_path}: {len(sim.strips)} strips, {obs.n_photos} photos, "
            f"{obs.n_points} points (at least {shared} common to each pair of adjacent "
            f"strips), {counts}"
        )
    else:
        echo_result(
            f"wrote {toml_path}: {obs.n_photos} photos, {obs.n_points} points, {counts}"
            + (f", {len(sim.lines)} straight line(s)" if sim.lines else "")
        )
    echo_result(f"run it with: stripaero run {toml_path}")


def _write(sim: SimulatedStrip | SimulatedBlock, out: Path, polynomial: str | None) -> Path:
    """The project files; a block's polynomials are every strip's own
    (``block = "strips"``), and "auto" is for one strip."""
    from ..options import OptionError
    from ..simulate import SimulatedBlock

    poly: int | str | None = (
        None if polynomial is None else polynomial if polynomial == "auto" else int(polynomial)
    )
    try:
        if isinstance(sim, SimulatedBlock):
            # a block's polynomials are every strip's own: block = "strips"
            block = "models" if poly is None else "strips"
            return sim.write_project(out, polynomial=poly, block=block)
        return sim.write_project(out, polynomial=poly)
    except OptionError as exc:  # the loader's rule, e.g. "auto" in a block
        raise click.BadParameter(exc.rule, param_hint="--polynomial") from None


def _camera_errors(items: tuple[str, ...]) -> dict[str, float] | None:
    """``--camera-error NAME=VALUE`` items as a dict (None without any)."""
    from ..geometry.camera_model import BROWN_PARAMETERS

    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip().lower()
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not sep or name not in BROWN_PARAMETERS or number != number:
            raise click.BadParameter(
                f"expected NAME=VALUE with NAME one of {', '.join(BROWN_PARAMETERS)} and a "
                f"number, got {item!r}",
                param_hint="--camera-error",
            )
        out[name] = number
    return out or None
