"""Check-point RMSE of the real FC300X block over six control/check splits.

The 33 GCPs of ``../shared/data/uav-block-fc300x`` (docs/block.md) split into
16 full control and the rest check points six ways: the importer's split, the
importer's swapped (its check points as control, its control as check), and
four random draws of 16 (``numpy.random.default_rng(seed)``, seeds 1-4).  Each
configuration given on the command line (``key=value`` pairs of
``[adjustment]``, ``distortion=none`` to remove the ``[distortion]`` table,
``variance_components=...``; ``image_groups=manual|strips|manual+strips``
with ``weights="estimated"``, the study of :data:`IMAGE_GROUPS`) runs on all six; the table gives the check RMSE
plan / height (m) without the weakly determined check points, and the medians.

    python benchmarks/bench_fc300x_splits.py ../shared/data/uav-block-fc300x \\
        'block="strips"' 'refine="bundle"' 'refine="bundle" self_calibration="auto"'

With ``--differences`` every configuration after the first is also given,
per split, its RMSE minus the first one's (mm, plan / height) and the
bootstrap standard deviation of that difference over the split's check
points (2000 resamplings of the same points for both): with 13-15 check
points of about 2 cm error each, a difference within one or two of these is
not a difference the split can show.
"""

from __future__ import annotations

import argparse
import csv
import re
import sys
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

SPLIT_NAMES = ("importer", "swapped", "random1", "random2", "random3", "random4")


def _import(data: Path, out: Path) -> Path:
    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    res = CliRunner().invoke(cli, ["import", "uav-fc300x", str(data), "-o", str(out)])
    if res.exit_code != 0:
        raise SystemExit(res.output)
    return out / "strip.toml"


def _splits(control_csv: Path) -> dict[str, dict[str, str]]:
    """Point id -> type ("full" / "check") for each split."""
    with control_csv.open() as f:
        rows = [r for r in csv.DictReader(f)]
    ids = [r["point"] for r in rows]
    given = {r["point"]: r["type"] for r in rows}
    out = {"importer": given}
    out["swapped"] = {p: ("check" if t == "full" else "full") for p, t in given.items()}
    n_full = sum(t == "full" for t in given.values())
    for seed in range(1, 5):
        pick = set(np.random.default_rng(seed).choice(ids, size=n_full, replace=False))
        out[f"random{seed}"] = {p: ("full" if p in pick else "check") for p in ids}
    return out


def _write_case(toml: Path, types: dict[str, str], settings: list[str], folder: Path) -> Path:
    text = toml.read_text()
    adjustment = []
    images = toml.parent / "image_points.csv"
    for s in settings:
        key, _, value = s.partition("=")
        if key == "min_rays":
            images = _tie_points_on(images, types, int(value), folder)
        elif key == "control_sigma":
            sigma_xy, _, sigma_h = value.partition("/")
            types = {p: f"{t},{sigma_xy},{sigma_h}" for p, t in types.items()}
        elif key == "image_groups":
            continue  # run_case's, not the project file's
        elif key == "distortion" and value == "none":
            text = re.sub(r"\n\[distortion\]\n(?:[^\[\n].*\n|\n)*", "\n", text)
        else:
            adjustment.append(f"{key} = {value}")
    if adjustment:
        text += "\n[adjustment]\n" + "\n".join(adjustment) + "\n"
    text = text.replace('file = "image_points.csv"', f'file = "{images}"')
    with (toml.parent / "control.csv").open() as f:
        lines = [line for line in f if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    sigmas = any("," in t for t in types.values())
    with (folder / "control.csv").open("w") as f:
        f.write("point,X,Y,H,type" + (",sigma_xy,sigma_h\n" if sigmas else "\n"))
        for r in rows:
            f.write(f"{r['point']},{r['X']},{r['Y']},{r['H']},{types[r['point']]}\n")
    path = folder / "strip.toml"
    path.write_text(text)
    return path


def _tie_points_on(images: Path, types: dict[str, str], n: int, folder: Path) -> Path:
    """The image points without the tie points seen on fewer than ``n`` photos."""
    with images.open() as f:
        lines = [line for line in f if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    count: dict[str, int] = {}
    for r in rows:
        count[r["point"]] = count.get(r["point"], 0) + 1
    out = folder / "image_points.csv"
    with out.open("w") as f:
        f.write(lines[0])
        for line, r in zip(lines[1:], rows, strict=True):
            if r["point"] in types or count[r["point"]] >= n:
                f.write(line)
    return out


def check_residuals(result: object) -> np.ndarray:
    """Given - adjusted (m) at the check points of the statistics (the weakly
    determined ones left out), rows in the control's order."""
    from strip_aerotri.ground.check_precision import strong_checks

    refined = getattr(result, "refined", None)
    final = refined if refined is not None and not isinstance(refined, bool) else result
    strong = strong_checks(final, final.control, getattr(result, "weak_checks", ()))  # type: ignore[attr-defined]
    return np.asarray(final.control_residuals, dtype=np.float64)[strong]  # type: ignore[attr-defined]


def rmse_difference(first: np.ndarray, second: np.ndarray, draws: int = 2000) -> np.ndarray:
    """(plan, height) RMSE of ``second`` minus ``first`` at the same check
    points, and the bootstrap standard deviation of each: shape (2, 2), m."""
    ok = np.all(np.isfinite(first), axis=1) & np.all(np.isfinite(second), axis=1)
    a, b = first[ok], second[ok]

    def rmse(r: np.ndarray) -> np.ndarray:  # (..., n, 3) -> (..., 2)
        return np.sqrt(np.stack([np.mean(np.sum(r[..., :2] ** 2, -1), -1), np.mean(r[..., 2] ** 2, -1)], -1))

    pick = np.random.default_rng(0).integers(0, a.shape[0], (draws, a.shape[0]))
    boot = rmse(b[pick]) - rmse(a[pick])
    return np.stack([rmse(b) - rmse(a), boot.std(axis=0)])


#: ``image_groups=...``: the image observations' variance groups with
#: ``weights="estimated"`` (``refine_frame_weighted``'s ``image_groups``), a
#: study not in the project file: "manual" the control and check points'
#: marks (measured by hand) against the tie points (matched); "strips" the
#: tie points per strip, the control points' marks one group; "manual+strips"
#: both.
IMAGE_GROUPS = ("manual", "strips", "manual+strips")


def image_groups(project: object, how: str) -> Callable[[object], np.ndarray]:
    """The label of each image observation of an adjustment's observations."""
    strips = getattr(project, "strips", ())
    strip_of = {photo: s.name for s in strips for photo in s.photo_ids}
    control = getattr(project, "control")
    manual = set(control.point_ids)
    with_control = {
        p for p, k in zip(control.point_ids, control.kind, strict=True) if k.value != "check"
    }

    def labels(obs: object) -> np.ndarray:
        photo_ids = np.asarray(getattr(obs, "photo_ids"))[getattr(obs, "photo")]
        point_ids = np.asarray(getattr(obs, "point_ids"))[getattr(obs, "point")]
        marked = np.isin(point_ids, sorted(manual if "manual" in how else with_control))
        ties = np.array(
            ["image, tie points" + (f", {strip_of.get(p, '')}" if "strips" in how else "")
             for p in photo_ids]
        )
        return np.where(marked, "image, marked points", ties)

    return labels


def run_case(path: Path, groups: str = "") -> tuple[float, float, object]:
    from strip_aerotri.bundle import variance
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project

    project = load_project(path)
    original = variance.refine_frame_weighted
    if groups:
        labels = image_groups(project, groups)

        def weighted(observations: object, *args: object, **kwargs: object) -> object:
            return original(observations, *args, image_groups=labels(observations), **kwargs)

        variance.refine_frame_weighted = weighted  # type: ignore[assignment]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = run_project(project)
    finally:
        variance.refine_frame_weighted = original
    stats = result.check_statistics
    refined = getattr(result, "refined", None)  # a block's is a flag: its statistics are
    if refined is not None and not isinstance(refined, bool):
        stats = refined.check_statistics
    return float(stats.rmse_plan), float(stats.rmse[2]), result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path)
    parser.add_argument("configs", nargs="+", help="space-separated key=value settings")
    parser.add_argument("--splits", default=",".join(SPLIT_NAMES))
    parser.add_argument(
        "--differences", action="store_true", help="each configuration against the first"
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        toml = _import(args.data, Path(tmp) / "imported")
        splits = _splits(toml.parent / "control.csv")
        names = args.splits.split(",")
        print("config".ljust(50), " ".join(n.rjust(13) for n in names), "  median")
        first: dict[str, np.ndarray] = {}
        for j, config in enumerate(args.configs):
            settings = config.split()
            cells, plan, height, diffs = [], [], [], []
            for name in names:
                folder = Path(tmp) / f"case_{name}"
                folder.mkdir(exist_ok=True)
                try:
                    groups = dict(x.partition("=")[::2] for x in settings).get("image_groups", "")
                    p, h, result = run_case(
                        _write_case(toml, splits[name], settings, folder), groups.strip('"')
                    )
                    cells.append(f"{p:.4f}/{h:.4f}")
                    plan.append(p)
                    height.append(h)
                    resid = check_residuals(result)
                    if j == 0:
                        first[name] = resid
                    elif name in first:
                        d = rmse_difference(first[name], resid) * 1000.0
                        diffs.append(f"{d[0, 0]:+.1f}±{d[1, 0]:.1f}/{d[0, 1]:+.1f}±{d[1, 1]:.1f}")
                except Exception as exc:  # noqa: BLE001 - a failing case is a result too
                    cells.append("failed".rjust(13))
                    diffs.append("-")
                    print(f"  {name}: {exc}", file=sys.stderr)
            med = f"{np.median(plan):.4f}/{np.median(height):.4f}" if plan else "-"
            print(config[:50].ljust(50), " ".join(c.rjust(13) for c in cells), " ", med)
            if args.differences and diffs:
                print("  minus the first, mm (bootstrap sd)".ljust(50), " ".join(diffs))
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
