"""The block family of the robustness sweep: seeded blocks over the envelope.

Run from the repository root::

    python benchmarks/sweep_blocks.py            # 16 seeded blocks, about half a minute
    python benchmarks/sweep_blocks.py --quick    # 4 of them

Each case is a block of :func:`strip_aerotri.simulate_block` with parameters
drawn from its family's ranges: film (c = 152.87 mm, 2-4 strips of 6-12
photos, 60 % forward overlap) and drone (1-inch camera, 3-5 strips of 12-25
photos, 75-85 % forward overlap); side overlap 20-60 %; serpentine or
same-direction flight; perimeter or corner control; noise as the preset's.
On the same observations it is solved by the block with every model at once
(``block = "models"``, the default), by one similarity per strip
(``block = "strips"``) and by the rigorous bundle refinement of the whole
block from the block's solution (the reference), and the check-point RMSE
ratios to the reference are printed, per case and per family (median and
largest).
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import dataclass

import numpy as np

from strip_aerotri import StripAerotriWarning, simulate_block
from strip_aerotri.block.strips import adjust_block
from strip_aerotri.observations import StripSpec


@dataclass
class Case:
    family: str
    seed: int
    kwargs: dict[str, object]


def draw(family: str, seed: int) -> Case:
    rng = np.random.default_rng(seed)
    common = {
        "side_overlap": float(rng.uniform(0.2, 0.6)),
        "flight": str(rng.choice(["serpentine", "same"])),
        "control": str(rng.choice(["perimeter", "perimeter", "corners"])),
        "seed": seed,
    }
    if family == "film":
        kwargs = {
            "n_strips": int(rng.integers(2, 5)),
            "n_photos_per_strip": int(rng.integers(6, 13)),
            "preset": "film",
        }
    else:
        kwargs = {
            "n_strips": int(rng.integers(3, 6)),
            "n_photos_per_strip": int(rng.integers(12, 26)),
            "preset": "drone",
            "forward_overlap": float(rng.uniform(0.75, 0.85)),
        }
    return Case(family, seed, {**kwargs, **common})


#: The bundle's weights estimated by group (``--weights estimated``).
ESTIMATED_WEIGHTS = [False]

def run(case: Case) -> tuple[float, float, float, float, float, float, float] | str:
    """(models plan, models height, strips plan, strips height ratios to the
    bundle, bundle plan, bundle height, seconds of the block) or the error."""
    try:
        sim = simulate_block(**case.kwargs)  # type: ignore[arg-type]
    except ValueError as exc:  # a draw the simulator refuses (too few common points)
        return f"not simulated: {exc}"
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        try:
            t0 = time.perf_counter()
            models = adjust_block(sim.observations, sim.control, sim.crs, specs)
            seconds = time.perf_counter() - t0
            strips = adjust_block(
                sim.observations, sim.control, sim.crs, specs, construction="strips"
            )
            bundle = adjust_block(
                sim.observations, sim.control, sim.crs, specs, refine=True,
                variance_components=ESTIMATED_WEIGHTS[0],
            )
        except Exception as exc:  # a failure is a finding of the sweep
            return f"{type(exc).__name__}: {exc}"
    b = bundle.check_statistics
    m, s = models.check_statistics, strips.check_statistics
    return (
        m.rmse_plan / b.rmse_plan,
        float(m.rmse[2] / b.rmse[2]),
        s.rmse_plan / b.rmse_plan,
        float(s.rmse[2] / b.rmse[2]),
        b.rmse_plan,
        float(b.rmse[2]),
        seconds,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4 blocks instead of 16")
    parser.add_argument(
        "--weights",
        choices=["given", "estimated"],
        default="given",
        help="the bundle's observation weights ([adjustment] weights)",
    )
    args = parser.parse_args()
    ESTIMATED_WEIGHTS[0] = args.weights == "estimated"
    per_family = 2 if args.quick else 8
    rows: dict[str, list[tuple[float, ...]]] = {"film": [], "drone": []}
    failures = 0
    t0 = time.perf_counter()
    for family in rows:
        for seed in range(1, per_family + 1):
            case = draw(family, 100 * seed + (family == "drone"))
            out = run(case)
            k = case.kwargs
            what = (
                f"{family:5s} {k['n_strips']} x {k['n_photos_per_strip']:2d}  side "
                f"{100 * float(k['side_overlap']):2.0f} %  {k['flight']:10s} {k['control']:9s}"
            )
            if isinstance(out, str):
                failures += 1
                print(f"{what}  FAILED {out}")
                continue
            rows[family].append(out)
            print(
                f"{what}  models {out[0]:.2f} {out[1]:.2f}  strips {out[2]:.2f} {out[3]:.2f}  "
                f"(bundle {out[4]:.3f} / {out[5]:.3f} m, block {out[6]:.2f} s)"
            )
    print()
    print("family  cases  models/bundle plan, height: median  max   strips/bundle: median  max")
    for family, values in [*rows.items(), ("all", rows["film"] + rows["drone"])]:
        a = np.array(values)
        med, mx = np.median(a[:, :4], axis=0), np.max(a[:, :4], axis=0)
        print(
            f"{family:6s}  {len(a):5d}  {med[0]:.2f} {med[1]:.2f}   {mx[0]:.2f} {mx[1]:.2f}"
            f"        {med[2]:.2f} {med[3]:.2f}   {mx[2]:.2f} {mx[3]:.2f}"
        )
    print(f"\n{failures} failed; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
