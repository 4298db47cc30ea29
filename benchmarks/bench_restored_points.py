"""Points the strip method (or the block) left out, restored before the bundle.

Run from the repository root::

    python benchmarks/bench_restored_points.py            # seeds 0-4
    python benchmarks/bench_restored_points.py --seeds 2

Simulated drone strips (40 photos with 20 image blunders, 100 photos with
60; control "fig4") and 3 x 15 drone blocks (40 and 120 blunders), each run
with ``refine = "bundle"`` twice: as the refinement starts now
(:mod:`strip_aerotri.bundle.start_points` restores the points the strip
method dropped) and without the restoration (only the strip method's
points).  Per case: points the strip method dropped, points the refinement
leaves out, good rays of those, blunders rejected, other rays rejected
(false alarms), and the check RMSE (plan / height, m).
"""

from __future__ import annotations

import argparse
import warnings
from contextlib import ExitStack
from typing import Any
from unittest import mock

import numpy as np

import strip_aerotri.bundle.refine as refine_module
import strip_aerotri.bundle.start_points as start_module
from strip_aerotri.pipeline import triangulate, triangulate_block
from strip_aerotri.simulate import simulate_block, simulate_strip


def _unrestored(observations: Any, centres: Any, rotations: Any, points: Any, **_: Any) -> Any:
    pts = np.array(points, dtype=np.float64)
    return start_module.RestoredPoints(pts, np.zeros(len(pts), bool), 1.0)


def _row_of(obs: Any) -> dict[tuple[str, str], int]:
    return {
        (obs.photo_ids[ph], obs.point_ids[pt]): k
        for k, (ph, pt) in enumerate(zip(obs.photo, obs.point, strict=True))
    }


def _measure(kind: str, photos: int, blunders: int, seed: int, restore: bool) -> tuple[Any, ...]:
    with ExitStack() as stack, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if not restore:
            stack.enter_context(mock.patch.object(refine_module, "restore_points", _unrestored))
            stack.enter_context(mock.patch.object(start_module, "restore_points", _unrestored))
        if kind == "strip":
            sim = simulate_strip(
                photos, preset="drone", seed=seed, image_blunders=blunders, control="fig4"
            )
            first = triangulate(sim.observations, sim.control, sim.crs)
            result = triangulate(sim.observations, sim.control, sim.crs, refine="bundle")
            stats = result.refined.check_statistics
            rejections = result.refined.rejections
        else:
            sim = simulate_block(3, photos, preset="drone", seed=seed, image_blunders=blunders)
            args = (sim.observations, sim.control, sim.crs, sim.strips)
            first = triangulate_block(*args)
            result = triangulate_block(*args, refine="bundle")
            stats = result.check_statistics
            rejections = result.rejections
    obs = sim.observations
    bad = np.zeros(obs.photo.size, bool)
    bad[list(sim.truth.blunder_observations)] = True
    rows = _row_of(obs)
    rejected = np.zeros(obs.photo.size, bool)
    for r in rejections:
        if r.stage == "bundle" and r.applied:
            rejected[rows[(r.photos[0], r.point)]] = True
    dropped = int(np.count_nonzero(~np.all(np.isfinite(first.points), axis=1)))
    lost = np.flatnonzero(~np.all(np.isfinite(result.points), axis=1))
    good_lost = int(np.count_nonzero(np.isin(obs.point, lost) & ~bad))
    return (
        dropped,
        lost.size,
        good_lost,
        int(np.count_nonzero(rejected & bad)),
        int(bad.sum()),
        int(np.count_nonzero(rejected & ~bad)),
        stats.rmse_plan,
        stats.rmse[2],
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args(argv)
    print(
        "case                      seed  start     dropped  left out  good rays lost  "
        "blunders found  false  check plan / height"
    )
    totals: dict[bool, np.ndarray] = {True: np.zeros(4), False: np.zeros(4)}
    for kind, photos, blunders in (
        ("strip", 40, 20), ("strip", 100, 60), ("block", 15, 40), ("block", 15, 120)
    ):  # fmt: skip
        for seed in range(args.seeds):
            for restore in (False, True):
                d, lost, good, found, n_bad, false, plan, height = _measure(
                    kind, photos, blunders, seed, restore
                )
                totals[restore] += (lost, good, found, false)
                label = f"{kind} {photos} ph, {blunders} blunders"
                print(
                    f"{label:26s}{seed:4d}  {'restored' if restore else 'strip   '}  {d:7d}  "
                    f"{lost:8d}  {good:14d}  {found:7d} of {n_bad:3d}  {false:5d}  "
                    f"{plan:.3f} / {height:.3f}"
                )
    for restore in (False, True):
        lost, good, found, false = totals[restore].astype(int)
        print(
            f"total, {'restored' if restore else 'strip method points only'}: left out {lost}, "
            f"good rays lost {good}, blunders found {found}, false alarms {false}"
        )


if __name__ == "__main__":
    main()
