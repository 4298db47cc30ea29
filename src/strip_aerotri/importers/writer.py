""":func:`write_project`: an imported project as a contract project
(``strip.toml``, ``image_points.csv``, ``control.csv``, ``gnss.csv``,
``imu.csv``), written whole or not at all.
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._atomic import folder_beside, input_inside, swap_folder
from .._toml import toml_id_list as _toml_id_list
from .._toml import toml_string, toml_value
from .._typing import FloatArray, StrArray
from ..errors import ConfigError
from .tables import ImportedProject

__all__ = ["project_files", "project_toml", "write_project"]


def _comment(text: str) -> list[str]:
    return ["# " + line if line else "#" for line in str(text).splitlines()]


def project_toml(project: ImportedProject) -> str:
    """The text of ``strip.toml`` for ``project``."""
    p = project
    lines = [f"# Written by `stripaero import` from {p.source}."]
    lines += [f"# {s}" for s in (n.replace("\n", " ") for n in p.notes)]
    lines.append("")
    if len(p.strips) == 1:
        lines += ["[strip]", f"name = {toml_string(p.name)}"]
        lines.append(f"photos = {_toml_id_list(p.strips[0].photos)}")
    else:
        lines += ["[project]", f"name = {toml_string(p.name)}", ""]
        for strip in p.strips:
            lines += ["[[strips]]", f"name = {toml_string(strip.name)}"]
            lines.append(f"photos = {_toml_id_list(strip.photos)}")
    lines += [
        "",
        "[camera]",
        f"principal_distance_mm = {toml_value(p.camera.principal_distance_mm)}",
    ]
    if p.camera.principal_point_mm is not None:
        lines.append(f"principal_point_mm = {toml_value(list(p.camera.principal_point_mm))}")
    f = p.frame
    lines += ["", "[images]", 'file = "image_points.csv"']
    if f.units == "pixel" or (f.pixel_size_mm is not None and f.principal_point_px is not None):
        if f.units == "pixel":
            lines.append('units = "pixel"')
        else:
            lines.append("# where the mm origin lies in the pixels (for export odm)")
        lines += [
            f"pixel_size_mm = {toml_value(float(f.pixel_size_mm))}",  # type: ignore[arg-type]
            f"principal_point_px = {toml_value([float(v) for v in f.principal_point_px])}",  # type: ignore[union-attr]
        ]
    lines.append(f"flight_direction = {toml_string(p.flight_direction)}")
    sigma = f.sigma_mm if f.sigma_mm is not None else f.pixel_size_mm
    if sigma is not None:
        if f.sigma_mm is None:
            lines.append("# one pixel")
        lines.append(f"sigma_mm = {toml_value(float(sigma))}")
    d = p.distortion
    if d is not None and not d.is_zero:
        lines += ["", "[distortion]"]
        lines += _comment(d.comment) if d.comment else []
        for key in ("k1", "k2", "k3", "p1", "p2"):
            value = getattr(d, key)
            if value:
                lines.append(f"{key} = {toml_value(float(value))}")
        lines += [f"units = {toml_string(d.units)}", f"model = {toml_string(d.model)}"]
    lines += ["", "[control]", 'file = "control.csv"', f"crs = {toml_string(p.crs)}"]
    if p.gnss is not None or p.imu_opk_deg is not None:
        lines += [
            "",
            "[adjustment]",
            "# GNSS centres and IMU attitudes are observations of the bundle refinement",
            'refine = "bundle"',
        ]
    if p.gnss is not None:
        lines += ["", "[gnss]", 'file = "gnss.csv"']
    if p.imu_opk_deg is not None:
        lines += ["", "[imu]", 'file = "imu.csv"']
    return "\n".join(lines) + "\n"


def _csv_text(values: StrArray) -> StrArray:
    """Ids as CSV fields, quoted where a comma, a quote or a leading '#' needs it."""
    v = np.asarray(values, dtype=str)
    if v.size == 0:
        return v
    needs = (np.char.find(v, ",") >= 0) | (np.char.find(v, '"') >= 0) | np.char.startswith(v, "#")
    if needs.any():
        quoted = np.char.add(np.char.add('"', np.char.replace(v, '"', '""')), '"')
        v = np.where(needs, quoted, v)
    return v


def _numbers(values: FloatArray, fmt: str) -> StrArray:
    """``values`` formatted with ``fmt``; NaN gives an empty cell."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.size == 0:
        return np.empty(0, dtype=str)
    text = np.char.mod(fmt, np.where(np.isnan(arr), 0.0, arr))
    return np.where(np.isnan(arr), "", text)


def _join(columns: Sequence[StrArray]) -> list[str]:
    out = np.asarray(columns[0], dtype=str)
    for col in columns[1:]:
        out = np.char.add(np.char.add(out, ","), np.asarray(col, dtype=str))
    return [str(v) for v in out]


def _table(header: str, columns: Sequence[StrArray]) -> str:
    return "\n".join([header, *_join(columns)]) + "\n"


def _is_geographic(crs: str) -> bool:
    if crs.strip().lower() == "local":
        return False
    from pyproj import CRS

    try:
        return bool(CRS.from_user_input(crs).is_geographic)
    except Exception:  # the loader reports a bad CRS with its own message
        return False


def project_files(project: ImportedProject) -> dict[str, str]:
    """The text of every file of the project, by file name."""
    p = project
    files = {"strip.toml": project_toml(p)}
    img = p.images
    order = np.lexsort((img.point, img.photo))  # stable, reproducible output
    img = img.take(order)
    xy_fmt = "%.9f" if p.frame.units == "mm" else "%.6f"
    cols = [
        _csv_text(img.photo),
        _csv_text(img.point),
        _numbers(img.xy[:, 0], xy_fmt),
        _numbers(img.xy[:, 1], xy_fmt),
    ]
    header = "photo,point,x,y"
    if img.sigma_mm is not None and np.isfinite(img.sigma_mm).any():
        cols.append(_numbers(img.sigma_mm, "%.9f"))
        header += ",sigma"
    files["image_points.csv"] = _table(header, cols)

    c = p.control
    geographic = _is_geographic(p.crs)
    xy_fmt = "%.10f" if geographic else "%.6f"
    cols = [
        _csv_text(c.point),
        _numbers(c.xyz[:, 0], xy_fmt),
        _numbers(c.xyz[:, 1], xy_fmt),
        _numbers(c.xyz[:, 2], "%.6f"),
        np.asarray(c.kind, dtype=str),
    ]
    header = "point,X,Y,H,type"
    for name in ("sigma_xy", "sigma_h"):
        value = getattr(c, name)
        if value is not None and np.isfinite(value).any():
            cols.append(_numbers(value, "%.6f"))
            header += f",{name}"
    files["control.csv"] = _table(header, cols)

    if p.gnss is not None:
        g = p.gnss
        cols = [
            _csv_text(g.photo),
            _numbers(g.xyz[:, 0], xy_fmt),
            _numbers(g.xyz[:, 1], xy_fmt),
            _numbers(g.xyz[:, 2], "%.6f"),
        ]
        header = "photo,X,Y,Z"
        for name in ("sigma_xy", "sigma_z"):
            value = getattr(g, name)
            if value is not None and np.isfinite(value).any():
                cols.append(_numbers(value, "%.6f"))
                header += f",{name}"
        files["gnss.csv"] = _table(header, cols)
    if p.imu_opk_deg is not None:
        photo, opk = p.imu_opk_deg
        cols = [_csv_text(photo)] + [_numbers(opk[:, k], "%.9f") for k in range(3)]
        files["imu.csv"] = _table("photo,omega,phi,kappa", cols)
    return files


def _check_target(out: Path, inputs: Sequence[Path], force: bool) -> None:
    if out.is_symlink():
        raise ConfigError(f"output folder '{out}' is a symbolic link; give the real folder")
    item = input_inside(out, inputs)
    if item is not None:
        raise ConfigError(
            f"output folder '{out}' contains the input file '{item}'; choose another --out"
        )
    if input_inside(out, [Path.cwd()]) is not None:
        raise ConfigError(
            f"output folder '{out}' contains the current folder; choose another --out"
        )
    if out.exists():
        if not out.is_dir():
            raise ConfigError(f"output folder '{out}' is a file")
        if any(out.iterdir()) and not force:
            raise ConfigError(
                f"output folder '{out}' exists and is not empty; give --force to replace it"
            )


def write_project(project: ImportedProject, out_dir: str | Path, *, force: bool = False) -> Path:
    """Write ``project`` into ``out_dir`` atomically; return the path of strip.toml.

    The files are written into a hidden temporary folder beside ``out_dir``,
    which then replaces ``out_dir`` by renames; on any failure the temporary
    folder is removed and ``out_dir`` is left as it was.

    Raises
    ------
    ConfigError
        ``out_dir`` exists and is not empty and ``force`` is False; it is a
        file or a symbolic link; it contains an input file or the current
        folder.
    """
    out = Path(out_dir)
    _check_target(out, project.inputs, force)
    files = project_files(project)
    tmp = folder_beside(out.resolve())
    try:
        for name, text in files.items():
            (tmp / name).write_text(text, encoding="utf-8", newline="\n")
        swap_folder(tmp, out.resolve())
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out / "strip.toml"
