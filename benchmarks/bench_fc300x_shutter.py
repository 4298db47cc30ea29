"""The FC300X block's check RMSE with a rolling shutter's motion in the bundle.

The DJI Phantom 3's FC300X has a rolling-shutter sensor (Vautherin et al.
2016).  This runs ``bench_fc300x_splits.py``'s six control/check splits with
each bundle adjustment of the refinement given one motion of the centre over
the readout per group of photos (``strip_aerotri.bundle.adjust.bundle_adjust``'s
``motion``, :class:`strip_aerotri.geometry.camera_model.ShutterMotion`) and
prints per split the check RMSE plan / height (m), the motions (m, site X Y
H, with their sigmas) and sigma0, then the medians.  Groups: ``strip`` (one
motion per strip B1, B2, B3), ``block`` (one for all), ``photo`` (one per
photo).  Rows are read along the sensor's y axis (the 3000 rows of 4000 x
3000, 4.686 mm), or along x with ``--readout-axis x`` (a control: a real
shutter has one axis).

    python benchmarks/bench_fc300x_shutter.py ../shared/data/uav-block-fc300x \\
        'refine="bundle"' --groups strip

The motion enters through the refinement's one call of ``bundle_adjust``
(``bundle/_snoop_camera.py``), wrapped here: the project file has no key for it.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import bench_fc300x_splits as splits  # noqa: E402

#: The FC300X's format: 3000 rows of 0.001561925 mm.
READOUT_MM = 3000 * 0.001561925
#: The imported block's flight runs along image +y (``[images] flight_direction``).
FLIGHT_PLUS_Y = np.array([[0.0, 1.0], [-1.0, 0.0]])

_GROUPS: dict[str, Callable[[str], str]] = {
    "strip": lambda photo: photo.split("_")[0],
    "block": lambda photo: "all",
    "photo": lambda photo: photo,
}


def _with_motion(groups: str, axis: str, log: list[Any]) -> Callable[..., Any]:
    from strip_aerotri.bundle import _snoop_camera as snooping
    from strip_aerotri.geometry.camera_model import ShutterMotion

    plain = snooping.bundle_adjust
    flight = FLIGHT_PLUS_Y if axis == "y" else FLIGHT_PLUS_Y @ np.array([[0.0, 1.0], [1.0, 0.0]])

    def adjust(obs: Any, *args: Any, **kwargs: Any) -> Any:
        key = _GROUPS[groups]
        names = sorted({key(p) for p in obs.photo_ids})
        group = np.array([names.index(key(p)) for p in obs.photo_ids])
        kwargs["motion"] = ShutterMotion(group, tuple(names), READOUT_MM, flight)
        res = plain(obs, *args, **kwargs)
        log.append((res, obs))
        return res

    snooping.bundle_adjust = adjust  # type: ignore[assignment]
    return plain


def _save(
    path: Path, res: Any, obs: Any, types: dict[str, str], rmse: tuple[float, float]
) -> None:
    """The adjustment's points, image residuals (mm) by photo and point, the
    motion and sigma0, the split's check points and its check RMSE."""
    motion = np.zeros((0, 3)) if res.motion is None else res.motion.values
    std = np.zeros((0, 3)) if res.motion is None else res.motion.std
    np.savez(
        path, point_ids=np.array(obs.point_ids), photo_ids=np.array(obs.photo_ids),
        photo=obs.photo, point=obs.point, points=res.points, residuals=res.residuals_mm,
        motion=motion, motion_std=std, sigma0=res.sigma0, rmse=np.array(rmse),
        check=np.array(sorted(p for p, t in types.items() if t.startswith("check"))),
    )  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path)
    parser.add_argument("settings", nargs="+", help="key=value settings of [adjustment]")
    parser.add_argument("--groups", choices=sorted(_GROUPS), default="strip")
    parser.add_argument("--readout-axis", choices=("x", "y"), default="y")
    parser.add_argument("--none", action="store_true", help="without the motion (reference)")
    parser.add_argument(
        "--save", type=Path, help="a folder for each split's last adjustment (.npz)"
    )
    args = parser.parse_args(argv)
    if args.save is not None:
        args.save.mkdir(parents=True, exist_ok=True)
    log: list[Any] = []
    if not args.none:
        _with_motion(args.groups, args.readout_axis, log)
    settings = " ".join(args.settings).split()
    plan, height = [], []
    with tempfile.TemporaryDirectory() as tmp:
        toml = splits._import(args.data, Path(tmp) / "imported")
        cases = splits._splits(toml.parent / "control.csv")
        for name in splits.SPLIT_NAMES:
            folder = Path(tmp) / f"case_{name}"
            folder.mkdir()
            log.clear()
            p, h, _ = splits.run_case(splits._write_case(toml, cases[name], settings, folder))
            plan.append(p)
            height.append(h)
            line = f"{name:9s} {p:.4f}/{h:.4f}"
            last, obs = log[-1] if log else (None, None)
            if args.save is not None and last is not None and obs is not None:
                _save(args.save / f"{name}.npz", last, obs, cases[name], (p, h))
            if last is not None and last.motion is not None and last.motion.values.shape[0] <= 3:
                mo = last.motion
                line += "  " + "  ".join(
                    f"{g}: " + " ".join(f"{v:+.3f}±{s:.3f}" for v, s in zip(val, sd, strict=True))
                    for g, val, sd in zip(mo.group_names, mo.values, mo.std, strict=True)
                )
            if last is not None:
                line += f"  sigma0 {last.sigma0:.3f}"
            print(line, flush=True)
    print(f"median    {np.median(plan):.4f}/{np.median(height):.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
