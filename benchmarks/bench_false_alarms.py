"""False alarms on clean strips and blunders found in the sweep's blunder family.

Run from the repository root::

    python benchmarks/bench_false_alarms.py                 # 20 seeds per case
    python benchmarks/bench_false_alarms.py --seeds 5 --no-blunders

Clean strips: the package's simulator (:func:`strip_aerotri.simulate.simulate_strip`)
with the ``film`` and ``drone`` presets as ``stripaero simulate`` makes them
(EPSG:32634, heading 75°), 6, 12 and 30 photos, seeds 0 .. n - 1, run as
``stripaero run`` does (:func:`strip_aerotri.pipeline.triangulate`).  Every
rejection on them is a false alarm; they are counted per stage, and the tie
points' image positions (on the middle photo of the triple overlap) listed with
``-v``.

Blunder family: the cases of ``benchmarks/sweep.py --family blunders`` (its
seeds and validity rule).  A simulated image blunder counts as found when a
rejection names its point and its photo; a control blunder when a rejection
names its point.  Rejections of points with no blunder are false alarms.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections import Counter
from pathlib import Path

from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sweep import cases  # noqa: E402

SIZES = (6, 12, 30)
PRESETS = ("film", "drone")


def clean_rejections(preset: str, photos: int, seed: int) -> list[tuple[str, str, str, float]]:
    """(stage, point, photos, w) of every rejection on one clean strip."""
    sim = simulate_strip(photos, preset=preset, crs="EPSG:32634", heading_deg=75.0, seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = triangulate(sim.observations, sim.control, sim.crs)
    return [(r.stage, r.point, "-".join(r.photos), r.w) for r in result.rejections]


def clean_table(seeds: int, verbose: bool) -> int:
    total = 0
    print(f"clean strips, {seeds} seeds each: rejections per stage (all false alarms)")
    for preset in PRESETS:
        for photos in SIZES:
            stages: Counter[str] = Counter()
            strips_hit = 0
            for seed in range(seeds):
                found = clean_rejections(preset, photos, seed)
                stages.update(r[0] for r in found)
                strips_hit += bool(found)
                if verbose:
                    for stage, point, on, w in found:
                        print(f"    seed {seed}: {stage} {point} photos {on} w {w:.2f}")
            n = sum(stages.values())
            total += n
            detail = ", ".join(f"{k} {v}" for k, v in sorted(stages.items())) or "-"
            print(
                f"  {preset:6s} {photos:3d} photos: {n:3d} rejections on {strips_hit:2d} "
                f"of {seeds} strips ({detail})"
            )
    print(f"  total false alarms on clean strips: {total}")
    return total


def blunder_table(count: int) -> tuple[int, int, int]:
    found_all = missed_all = false_all = 0
    print(f"\nblunder family (benchmarks/sweep.py, {count} cases)")
    for case, sim, why in cases({"blunders": count}):
        if sim is None:
            print(f"  {case.label}: invalid ({why})")
            continue
        obs = sim.observations
        image = {
            (obs.point_ids[obs.point[r]], obs.photo_ids[obs.photo[r]])
            for r in sim.truth.blunder_observations
        }
        control = {sim.control.point_ids[r] for r in sim.truth.blunder_control}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = triangulate(sim.observations, sim.control, sim.crs)
        except Exception as exc:  # a failure is a result of the benchmark
            print(f"  {case.label}: {type(exc).__name__}: {exc}")
            missed_all += len(image) + len(control)
            continue
        named = [(r.point, set(r.photos)) for r in result.rejections]
        found = sum(any(p == pid and ph in on for p, on in named) for pid, ph in image)
        found += sum(any(p == pid for p, _ in named) for pid in control)
        bad_points = {pid for pid, _ in image} | control
        false = sum(p not in bad_points for p, _ in named)
        n = len(image) + len(control)
        found_all += found
        missed_all += n - found
        false_all += false
        print(f"  {case.label}: {found}/{n} blunders found, {false} false alarms")
    print(f"  total: {found_all} found, {missed_all} missed, {false_all} false alarms")
    return found_all, missed_all, false_all


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20, help="clean strips per case")
    parser.add_argument("--blunder-cases", type=int, default=8, help="the sweep's count")
    parser.add_argument("--no-blunders", action="store_true")
    parser.add_argument("--no-clean", action="store_true")
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    if not args.no_clean:
        clean_table(args.seeds, args.verbose)
    if not args.no_blunders:
        blunder_table(args.blunder_cases)
    return 0


if __name__ == "__main__":
    sys.exit(main())
