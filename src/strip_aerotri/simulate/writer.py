"""Project files of a simulation: ``strip.toml``, ``image_points.csv``,
``control.csv`` (docs/project-file.md).

:func:`write_strip_project` writes a ``[strip]`` project, and
:func:`write_block_project` a block of ``[[strips]]`` tables; both write
the one image file and the one control file in the same way. The truth is
never written.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._toml import toml_id_list, toml_string, toml_value
from ..observations import ControlPoints, ImageObservations
from ..options import OptionError, adjustment_options
from ._geodesy import _LOCAL

__all__ = ["write_block_project", "write_control", "write_image_points", "write_strip_project"]

def _adjustment_lines(crs: str, given: dict[str, object], *, block: bool) -> list[str]:
    """The ``[adjustment]`` keys given (None: left out), checked by the rules
    the loader applies (:func:`strip_aerotri.options.adjustment_options`), so
    that the project written is one ``stripaero run`` takes."""
    given = {key: value for key, value in given.items() if value is not None}
    adjustment_options(given, block=block)
    if given.get("route") == "geocentric" and crs == _LOCAL:
        raise OptionError("route", '"geocentric" needs a real CRS, not crs = "local"')
    return [
        f"{key} = {toml_value(value)}"
        for key, value in given.items()
    ]


def _common_lines(observations: ImageObservations, crs: str) -> list[str]:
    """The ``[camera]``, ``[images]`` and ``[control]`` tables."""
    return [
        "[camera]",
        f"principal_distance_mm = {observations.principal_distance!r}",
        "",
        "[images]",
        'file = "image_points.csv"',
        "",
        "[control]",
        'file = "control.csv"',
        f"crs = {toml_string(crs)}",
    ]


def write_strip_project(
    directory: str | Path,
    observations: ImageObservations,
    control: ControlPoints,
    crs: str,
    *,
    name: str,
    lines: Sequence[tuple[Sequence[str], float]] = (),
    polynomial: int | str | None = None,
    route: str | None = None,
) -> Path:
    """Write the ``[strip]`` project of one strip; returns the path of ``strip.toml``.

    ``lines`` are straight lines (point ids, weight); ``polynomial`` and
    ``route`` are written to ``[adjustment]`` when not None. See
    :meth:`~strip_aerotri.simulate.SimulatedStrip.write_project`.
    """
    adjustment = _adjustment_lines(crs, {"route": route, "polynomial": polynomial}, block=False)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    text = [
        "# Simulated strip (strip_aerotri.simulate); truth is not in these files.",
        "[strip]",
        f"name = {toml_string(name)}",
        f"photos = {toml_id_list(observations.photo_ids, per_line=None)}",
        "",
        *_common_lines(observations, crs),
    ]
    for ids, weight in lines:
        text += ["", "[[straight_line]]", f"points = {toml_id_list(ids, per_line=None)}"]
        text.append(f"weight = {float(weight)!r}")
    text += ["", "[adjustment]", *adjustment]
    toml_path = directory / "strip.toml"
    toml_path.write_text("\n".join(text) + "\n", encoding="utf-8")
    write_image_points(directory / "image_points.csv", observations)
    write_control(directory / "control.csv", control, crs)
    return toml_path


def write_block_project(
    directory: str | Path,
    strips: Sequence[tuple[str, Sequence[str]]],
    observations: ImageObservations,
    control: ControlPoints,
    crs: str,
    *,
    name: str,
    block: str = "models",
    models: str | None = None,
    polynomial: int | str | None = None,
    route: str | None = None,
) -> Path:
    """Write the ``[[strips]]`` project of a block; returns the path of ``strip.toml``.

    ``strips`` are (name, photo ids in flight order) in file order;
    ``block`` is written to ``[adjustment] block``, and ``models``,
    ``polynomial``, ``route`` when not None. ``name`` goes into the first
    comment line and ``[project] name``. See
    :meth:`~strip_aerotri.simulate.SimulatedBlock.write_project`.
    """
    adjustment = _adjustment_lines(
        crs,
        {"block": block, "models": models, "route": route, "polynomial": polynomial},
        block=True,
    )
    if len(strips) < 2:
        raise ValueError(f"Expected two or more strips in a block, got {len(strips)}")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    text = [
        f"# {_comment(name)}",
        "# Simulated block (strip_aerotri.simulate); truth is not in these files.",
        "[project]",
        f"name = {toml_string(name)}",
        "",
    ]
    for strip_name, photos in strips:
        text += [
            "[[strips]]",
            f"name = {toml_string(strip_name)}",
            f"photos = {toml_id_list(tuple(photos), per_line=None)}",
            "",
        ]
    text += [*_common_lines(observations, crs), "", "[adjustment]", *adjustment]
    toml_path = directory / "strip.toml"
    toml_path.write_text("\n".join(text) + "\n", encoding="utf-8")
    write_image_points(directory / "image_points.csv", observations)
    write_control(directory / "control.csv", control, crs)
    return toml_path


def write_image_points(path: str | Path, observations: ImageObservations) -> None:
    """Write ``image_points.csv``: ``photo,point,x,y,sigma`` in mm, one row per observation."""
    obs = observations
    with Path(path).open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(["photo", "point", "x", "y", "sigma"])
        photo_names = np.asarray(obs.photo_ids, dtype=object)[obs.photo]
        point_names = np.asarray(obs.point_ids, dtype=object)[obs.point]
        writer.writerows(
            [p, q, f"{x:.6f}", f"{y:.6f}", f"{s:.6f}"]
            for p, q, (x, y), s in zip(
                photo_names, point_names, obs.xy.tolist(), obs.sigma.tolist(), strict=True
            )
        )


def write_control(path: str | Path, control: ControlPoints, crs: str) -> None:
    """Write ``control.csv``: ``point,X,Y,H,type,sigma_xy,sigma_h``.

    X, Y with 4 decimals (metres) or 10 (degrees of a geographic ``crs``),
    H with 4; a coordinate that is not given (NaN) is left empty.
    """
    from pyproj import CRS

    geographic = crs != _LOCAL and CRS.from_user_input(crs).is_geographic
    xy_fmt = "{:.10f}" if geographic else "{:.4f}"
    ctrl = control
    with Path(path).open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(["point", "X", "Y", "H", "type", "sigma_xy", "sigma_h"])
        for pid, (x, y, h), kind, sxy, sh in zip(
            ctrl.point_ids,
            ctrl.xyz.tolist(),
            ctrl.kind,
            ctrl.sigma_xy.tolist(),
            ctrl.sigma_h.tolist(),
            strict=True,
        ):
            writer.writerow(
                [
                    pid,
                    "" if math.isnan(x) else xy_fmt.format(x),
                    "" if math.isnan(y) else xy_fmt.format(y),
                    "" if math.isnan(h) else f"{h:.4f}",
                    kind.value,
                    f"{sxy:.4f}",
                    f"{sh:.4f}",
                ]
            )


# ----------------------------------------------------------------------------
# TOML writing helpers (tomllib only reads)


def _comment(text: str) -> str:
    """One line of a TOML comment (no control characters)."""
    return " ".join("".join(ch if ch.isprintable() else " " for ch in str(text)).split())
