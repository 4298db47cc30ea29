"""Why the FC300X strips' control heights have a slope of 0.57-0.66 against
their strip models' heights (``ground/height_units.py``'s test of the height
unit), where simulated strips have 0.95-1.02.

Run from the repository root::

    python benchmarks/bench_fc300x_height_slope.py ../shared/data/uav-block-fc300x

It imports the block (the importer's split), forms each strip as the run
forms it (``pipeline.form_strip_of``), scales it to the plan control as the
ground stage's first look does, and runs ``refine = "bundle"`` and ``block =
"strips"`` on the block.  Per strip it prints:

* **rule**: the slope s of H = a + bx x + by y + s z over the height control
  and its standard deviation (``height_units.height_slope``);
* **Deming**: the same fit with the errors of the model heights allowed for
  (errors-in-variables with the ratio of the model heights' error variance,
  the MAD of their scatter about the bundle below, to the control heights'
  sigma²; the plan terms partialled out first): regression dilution would
  show as a Deming slope well above the rule's;
* **noise / relief**: that error variance over the variance of the control
  heights left by the plan terms: the attenuation of a least-squares slope is
  1 / (1 + this);
* **bundle**: the control heights' slope against the refined bundle's
  heights at the same points, and against the strip method's (after the
  polynomials), the same fit;
* **affine**: over every point of the strip that the bundle determines, the
  3D affine transformation model -> bundle, its three singular values (equal:
  a similarity, no stretch in any direction) and the angle between the
  model's z axis and the site's vertical;
* **level**: a slope that no rotation changes: the norm of the height's
  gradient over the model coordinates (H = a + g . m, g fitted over the full
  control of the strip) over the mean norm of the plan coordinates'
  gradients (X, Y = a + G m): 1 when heights and plan are in one unit.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np


def deming(x: np.ndarray, y: np.ndarray, ratio: float) -> float:
    """Deming slope of y on x (centred), ``ratio`` = var(error of y) / var(error of x)."""
    sxx, syy, sxy = x @ x, y @ y, x @ y
    d = syy - ratio * sxx
    return float((d + np.sqrt(d * d + 4.0 * ratio * sxy * sxy)) / (2.0 * sxy))


def partial_out(plan: np.ndarray, *columns: np.ndarray) -> list[np.ndarray]:
    """Each column less its least-squares fit on 1 and the plan coordinates."""
    design = np.column_stack([np.ones(len(plan)), plan - plan.mean(axis=0)])
    return [c - design @ np.linalg.lstsq(design, c, rcond=None)[0] for c in columns]


def ols_slope(plan: np.ndarray, x: np.ndarray, y: np.ndarray) -> float:
    """The slope on ``x`` of y = a + b . plan + s x (least squares)."""
    xr, yr = partial_out(plan, x, y)
    return float(xr @ yr / (xr @ xr))


def level_ratio(model: np.ndarray, given: np.ndarray) -> float:
    """|grad H| / mean |grad X|, |grad Y| over the model coordinates: the
    height unit against the plan unit, whatever the model's rotation."""
    design = np.column_stack([np.ones(len(model)), model - model.mean(axis=0)])
    grad = np.linalg.lstsq(design, given - given.mean(axis=0), rcond=None)[0][1:]
    norms = np.linalg.norm(grad, axis=0)
    return float(norms[2] / np.sqrt(0.5 * (norms[0] ** 2 + norms[1] ** 2)))


def _run(toml: Path, settings: str) -> Any:
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    path = toml.parent / f"{abs(hash(settings))}.toml"
    path.write_text(toml.read_text() + f"\n[adjustment]\n{settings}\n")
    return run_project(load_project(path))


def main(argv: list[str] | None = None) -> None:
    from strip_aerotri.block.strips import strip_observations
    from strip_aerotri.geodesy import GroundCRS
    from strip_aerotri.ground import polynomials
    from strip_aerotri.ground.common import control_rows, resolve_route
    from strip_aerotri.ground.height_units import height_slope
    from strip_aerotri.importers.uav_fc300x import import_uav_fc300x
    from strip_aerotri.importers.writer import write_project
    from strip_aerotri.pipeline import form_strip_of
    from strip_aerotri.project import load_project

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path, help="the FC300X data folder")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        write_project(import_uav_fc300x(args.data), tmp, force=True)
        toml = Path(tmp) / "strip.toml"
        project = load_project(toml)
        bundle = _run(toml, 'refine = "bundle"')
        strips = _run(toml, 'block = "strips"')
    crs = GroundCRS.from_user_input(project.crs)
    control = project.control
    print(f"{'strip':5s} {'rule':>14s} {'Deming':>7s} {'noise/relief':>12s} {'bundle':>7s} "
          f"{'strips':>7s} {'affine singular values':>24s} {'z tilt':>7s} {'level':>6s}")  # fmt: skip
    for spec in project.strips:
        sub = dataclasses.replace(
            project, observations=strip_observations(project.observations, spec.photo_ids),
            photo_ids=spec.photo_ids, strips=(),
        )  # fmt: skip
        strip = form_strip_of(sub.observations, sub.adjustment, blunders=sub.blunders)
        picked = control_rows(strip, control)
        first = polynomials._first_look(strip, picked, crs, resolve_route(project.adjustment.route, crs))
        z = picked.use_z
        model = first.strip_xyz[z] * first.metres_per_model
        given = first.target[z, 2]
        rule = height_slope(model, given, first.exp_z[z])
        assert rule is not None
        # every point of the strip the bundle determines: the model against the bundle
        scaled = strip.points * first.metres_per_model
        lookup = {p: i for i, p in enumerate(bundle.observations.point_ids)}
        rows = np.array([lookup.get(p, -1) for p in strip.observations.point_ids])
        both = np.isfinite(scaled).all(axis=1) & (rows >= 0)
        both[both] &= np.isfinite(bundle.points[rows[both]]).all(axis=1)
        m_all, b_all = scaled[both], bundle.points[rows[both]]
        design = np.column_stack([np.ones(len(m_all)), m_all - m_all.mean(axis=0)])
        fit = np.linalg.lstsq(design, b_all - b_all.mean(axis=0), rcond=None)[0]
        matrix = fit[1:].T  # bundle = A model + t
        singular = np.linalg.svd(matrix, compute_uv=False)
        rot = matrix / np.cbrt(np.linalg.det(matrix))
        tilt = np.degrees(np.arccos(np.clip(rot[2, 2], -1.0, 1.0)))
        # the model heights' own error: their scatter about the bundle's, by the affine
        resid = (b_all - b_all.mean(axis=0)) - design @ fit
        mad = 1.4826 * float(np.median(np.abs(resid[:, 2] - np.median(resid[:, 2]))))
        noise_model = (mad / abs(rule[0])) ** 2  # in model-height units
        zr, hr = partial_out(model[:, :2], model[:, 2], given)
        sigma_h = float(np.median(picked.sigma_h[z]))
        slope_deming = deming(zr, hr, sigma_h**2 / noise_model)
        # control heights against the bundle's and the strip method's at the same points
        ids = np.asarray(picked.ids)[z]
        pts = [np.array([r.points[lookup_r[p]] for p in ids]) for r, lookup_r in (
            (bundle, lookup), (strips, {p: i for i, p in enumerate(strips.observations.point_ids)}))]  # fmt: skip
        on_bundle, on_strips = (ols_slope(p[:, :2], p[:, 2], given) for p in pts)
        full = picked.use_xy & picked.use_z
        level = level_ratio(first.strip_xyz[full], np.column_stack(
            [first.target[full, :2], first.target[full, 2]]))  # fmt: skip
        print(f"{spec.name:5s} {rule[0]:6.3f} ± {rule[1]:5.3f} {slope_deming:7.3f} "
              f"{noise_model / np.var(zr):12.1e} {on_bundle:7.3f} {on_strips:7.3f} "
              f"{np.array2string(singular, precision=3):>24s} {tilt:6.1f}° {level:6.3f}")  # fmt: skip
    sys.stdout.flush()


if __name__ == "__main__":
    main()
