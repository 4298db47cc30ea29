"""The multiple correlations ``"auto"``'s first rule sees for c, x0, y0: the
oblique FC300X block against vertical simulated blocks.

Run from the repository root::

    python benchmarks/bench_selfcal_correlations.py ../shared/data/uav-block-fc300x

``"auto"`` holds c, x0, y0 when their multiple correlation with the
orientation and the points exceeds 0.999 (docs/bundle.md, "Self-calibration").
Printed per case: the correlation of each of c, x0, y0, p1, p2 (as the rule
takes it, from the design of all ten at the start values), and, from an
adjustment of all ten, their t values: on the FC300X block (each of
``bench_fc300x_splits.py``'s six splits, the data's calibration), on
simulated vertical drone blocks of 3 x 8 and 3 x 20 photos with and without
GNSS centres of 2 cm (``simulate_block``, 20 µm of camera errors), and on a
simulated film strip.  Whether a rule can tell a c the data determine (t of
5) from the flying height's twin is then a question of the digits after
0.999.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_fc300x_splits as splits  # noqa: E402

from strip_aerotri.observations import GnssCentres, StripSpec  # noqa: E402
from strip_aerotri.options import SelfCalibration  # noqa: E402
from strip_aerotri.pipeline import triangulate, triangulate_block  # noqa: E402
from strip_aerotri.simulate import simulate_block, simulate_strip  # noqa: E402

NAMES = ("c", "x0", "y0", "p1", "p2")
ALL_TEN = ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "b1", "b2")
#: About 20 µm radial, 10 µm decentring and affinity at the format's corner (mm^-2, mm^-1, 1)
DRONE_ERRORS = {"k1": 4e-5, "p1": 1.6e-4, "b1": 1e-3}
FILM_ERRORS = {"k1": 4.6e-9, "p1": 3.8e-7, "b1": 6e-5}


def _outcome(result: Any) -> Any:
    """The self-calibration's outcome of a block's or a strip's refinement."""
    refined = getattr(result, "refined", None)
    return (result if refined is None or isinstance(refined, bool) else refined).self_calibration


def _row(label: str, auto: Any, ten: Any) -> str:
    corr = {p.name: p.orientation_correlation for p in _outcome(auto).parameters}
    t = {p.name: p.t for p in _outcome(ten).parameters} if ten is not None else {}
    cells = "  ".join(f"{n} {corr.get(n, np.nan):.6f} (t {t.get(n, np.nan):+6.1f})" for n in NAMES)
    kept = " ".join(_outcome(auto).kept) or "nothing"
    return f"{label:22s} {cells}   auto kept {kept}"


def _block(n_photos: int, seed: int, gnss: bool) -> tuple[Any, Any]:
    sim = simulate_block(3, n_photos, preset="drone", seed=seed, crs="local",
                         camera_errors=DRONE_ERRORS)  # fmt: skip
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    extra: dict[str, Any] = {}
    if gnss:
        m = sim.truth.photo_centres_crs.shape[0]
        noise = np.random.default_rng(100 + seed).normal(0, 0.02, (m, 3))
        extra["gnss"] = GnssCentres(tuple(sim.observations.photo_ids),
                                    sim.truth.photo_centres_crs + noise,
                                    np.full(m, 0.02), np.full(m, 0.02))  # fmt: skip
    out = []
    for spec in (SelfCalibration("auto"), SelfCalibration(ALL_TEN)):
        try:
            out.append(triangulate_block(sim.observations, sim.control, sim.crs, specs,
                                         route="projected", refine="bundle",
                                         self_calibration=spec, **extra))  # fmt: skip
        except Exception as exc:  # an explicit c over flat ground may not be determined
            print(f"    ({spec.choice if isinstance(spec.choice, str) else 'all ten'}: {exc})")
            out.append(None)
    return out[0], out[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path)
    parser.add_argument("--splits", default=",".join(splits.SPLIT_NAMES))
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        toml = splits._import(args.data, Path(tmp) / "imported")
        cases = splits._splits(toml.parent / "control.csv")
        for name in filter(None, args.splits.split(",")):
            res = []
            for choice in ('"auto"', "[" + ",".join(f'"{n}"' for n in ALL_TEN) + "]"):
                folder = Path(tmp) / f"case_{name}_{len(res)}"
                folder.mkdir(exist_ok=True)
                settings = ['refine="bundle"', f"self_calibration={choice}"]
                res.append(splits.run_case(splits._write_case(toml, cases[name], settings, folder))[2])
            print(_row(f"FC300X {name}", res[0], res[1]), flush=True)
    for n_photos in (8, 20):
        for gnss in (False, True):
            auto, ten = _block(n_photos, 1, gnss)
            if auto is not None:
                print(_row(f"drone 3 x {n_photos}{' GNSS' if gnss else ''}", auto, ten), flush=True)
    sim = simulate_strip(12, preset="film", seed=3, camera_errors=FILM_ERRORS)
    auto = triangulate(sim.observations, sim.control, sim.crs, refine="bundle",
                       self_calibration=SelfCalibration("auto"))  # fmt: skip
    print(_row("film strip 12", auto, None), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
