"""The two measures of the control heights' unit (``ground/height_units.py``)
on real and simulated projects, as given and with their units changed.

Run from the repository root::

    python benchmarks/bench_height_units.py PROJECT/strip.toml ...
    python benchmarks/bench_height_units.py --fc300x ../shared/data/uav-block-fc300x
    python benchmarks/bench_height_units.py --simulated

``--fc300x`` imports the block and measures it under the six control / check
splits of ``bench_fc300x_splits.py``; ``--simulated`` writes and measures a
fixed set of ``stripaero simulate`` projects (film and drone strips, seeds
0-3, tilts of 1.5-5 degrees, weak and fig4 control, blocks).  Each strip of
each project is formed as the run forms it and scaled to the plan control as
the ground stage's first look does; per strip and per unit change (none; H
x 3.28084, feet; X, Y x 3.28084, feet with H in metres; H x 10; X, Y x 10)
it prints:

* **slope**: :func:`height_slope` and its standard deviation;
* **ratio**: :func:`gradient_ratio` and its standard deviation, with the
  plan and height points of its fits (``-`` where it cannot be formed);
* **verdict**: what :func:`strip_aerotri.ground.height_units.height_unit_problems`
  answers on the ground stage's inputs (``pass``, or the cause named), by
  which measure (``ratio`` when the ratio is told, else ``slope``);
  ``pass (no similarity)`` by ``-`` where the strip's control is too scant
  for the first look (``stripaero check`` passes it: the similarity's own
  rules say so).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FEET = 1.0 / 0.3048
CHANGES = (
    ("as given", 1.0, 1.0),
    ("H ft", 1.0, FEET),
    ("XY ft", FEET, 1.0),
    ("H dm", 1.0, 10.0),
    ("XY dm", 10.0, 1.0),
)
#: ``stripaero simulate`` arguments of --simulated: name -> arguments.
SIMULATED = {
    **{f"film s{s}": ["film", "--seed", str(s)] for s in range(4)},
    **{f"film weak s{s}": ["film", "--seed", str(s), "--control", "weak"] for s in range(2)},
    **{f"drone s{s}": ["drone", "--seed", str(s)] for s in range(4)},
    **{f"drone weak s{s}": ["drone", "--seed", str(s), "--control", "weak"] for s in range(2)},
    **{
        f"oneinch tilt{t} s{s}": [
            "--camera", "oneinch", "--height-m", "100", "--tilt-deg", str(t),
            "--kappa-deg", "5", "--photos", "30", "--control", "fig4", "--seed", str(s),
        ]
        for t in (3, 5) for s in range(2)
    },
    **{
        f"film152 tilt5 weak s{s}": [
            "--camera", "film152", "--tilt-deg", "5", "--control", "weak", "--seed", str(s),
        ]
        for s in range(2)
    },
    "film block 3x8": ["film", "--strips", "3", "--photos", "8"],
    "drone block 3x10": ["drone", "--strips", "3", "--photos", "10", "--seed", "1"],
    "drone block corners": ["drone", "--strips", "3", "--photos", "10", "--control", "corners"],
}  # fmt: skip


def changed(control: Any, plan: float, height: float) -> Any:
    """The control with X, Y times ``plan`` and H times ``height`` (their
    sigmas as given: a unit mistake in the coordinates' columns only)."""
    return dataclasses.replace(control, xyz=control.xyz * np.array([plan, plan, height]))


def strips_of(project: Any) -> Iterator[tuple[str, Any]]:
    """Each strip of the project formed as the run forms it (name, model)."""
    from strip_aerotri.block.strips import strip_observations
    from strip_aerotri.pipeline import form_strip_of

    specs = project.strips or (None,)
    for spec in specs:
        obs = project.observations
        if spec is not None:
            obs = strip_observations(project.observations, spec.photo_ids)
        name = spec.name if spec is not None else "strip"
        yield name, form_strip_of(obs, project.adjustment, blunders=project.blunders)


def measure(project: Any, strip: Any, control: Any) -> dict[str, Any]:
    """Slope, ratio and verdict of one strip under ``control``."""
    from strip_aerotri.errors import GeometryError
    from strip_aerotri.geodesy import GroundCRS
    from strip_aerotri.ground import height_units, polynomials
    from strip_aerotri.ground.common import control_rows, resolve_route

    crs = GroundCRS.from_user_input(project.crs)
    route = resolve_route(project.adjustment.route, crs)
    picked = control_rows(strip, control)
    try:
        first = polynomials._first_look(strip, picked, crs, route)
    except GeometryError:  # too little control for the similarity: the check passes
        return {"slope": None, "ratio": None, "by": "-", "verdict": "pass (no similarity)"}
    inputs = polynomials._unit_inputs(first, picked)
    slope = height_units.height_slope(inputs["model_xyz"], inputs["height"], inputs["sigma"])
    ratio = height_units.gradient_ratio(*inputs["plan"], inputs["model_xyz"], *inputs["given"])
    problems = height_units.height_unit_problems(**inputs)
    told = ratio is not None and ratio.told
    verdict = problems[0].rsplit(": ", 1)[-1].split(" (")[0] if problems else "pass"
    return {"slope": slope, "ratio": ratio, "by": "ratio" if told else "slope",
            "verdict": verdict}  # fmt: skip


def report(label: str, project: Any) -> None:
    """One line per strip and unit change."""
    for name, strip in strips_of(project):
        for change, plan, height in CHANGES:
            m = measure(project, strip, changed(project.control, plan, height))
            slope = m["slope"]
            ratio = m["ratio"]
            s = f"{slope[0]:7.4f} ± {slope[1]:6.4f}" if slope else f"{'-':>16s}"
            r = (
                f"{ratio.ratio:7.4f} ± {ratio.sd:6.4f} ({ratio.n_plan:2d}/{ratio.n_height:2d})"
                if ratio else f"{'-':>24s}"
            )  # fmt: skip
            print(f"{label:24s} {name:6s} {change:9s} {s} {r} {m['by']:5s} {m['verdict']}")
            sys.stdout.flush()


def _load(toml: Path, types: dict[str, str] | None = None) -> Any:
    from strip_aerotri.project import load_project

    if types is not None:
        import csv

        path = toml.parent / "control.csv"
        with path.open(newline="") as f:
            rows = list(csv.DictReader(f))
        with path.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            for row in rows:
                writer.writerow({**row, "type": types.get(row["point"], row["type"])})
    return load_project(toml)


def _simulate(folder: Path, args: list[str]) -> Path:
    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    res = CliRunner().invoke(cli, ["simulate", *args, "--out", str(folder)])
    if res.exit_code != 0:
        raise SystemExit(res.output)
    return folder / "strip.toml"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("projects", nargs="*", type=Path, help="strip.toml files")
    parser.add_argument("--fc300x", type=Path, help="the FC300X data folder: its six splits")
    parser.add_argument("--simulated", action="store_true", help="the simulated set")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    print(f"{'project':24s} {'strip':6s} {'change':9s} {'slope ± sd':>16s} "
          f"{'ratio ± sd (plan/height)':>24s} {'by':5s} verdict")  # fmt: skip
    for toml in args.projects:
        report(toml.parent.name, _load(toml))
    with tempfile.TemporaryDirectory() as tmp:
        if args.fc300x is not None:
            sys.path.insert(0, str(ROOT / "benchmarks"))
            from bench_fc300x_splits import _import, _splits

            toml = _import(args.fc300x, Path(tmp) / "fc300x")
            splits = _splits(toml.parent / "control.csv")
            for split, types in splits.items():
                report(f"FC300X {split}", _load(toml, types))
        if args.simulated:
            for label, sim_args in SIMULATED.items():
                folder = Path(tmp) / label.replace(" ", "-")
                report(label, _load(_simulate(folder, sim_args)))


if __name__ == "__main__":
    main()
