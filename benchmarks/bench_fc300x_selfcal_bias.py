"""The self-calibration's residuals in the observations' space, against an
independent re-solve: c, b1 and the FC300X block's check points.

Written ``x(S, R, X) - (x_obs + D(x_obs; theta))``, weighted with the sigma
of ``x_obs``, the image residual is ``(I + dD/dx)`` times the observation's
error: where D scales the coordinates (c: ``-(x/c) dc``; b1, the radial
terms), it scales the residuals too, the sum of squares falls by about ``2
dc / c`` of itself as c grows and the least-squares c is drawn towards
shrinking the image, by about ``Q_cc * Omega / c`` (Omega the sum of
squares, Q_cc c's cofactor).  The refinement takes its residuals in the
observations' space, ``x̂ - x_obs`` with ``x̂ + D(x̂) = x(S, R, X)``
(docs/bundle.md, "Self-calibration"; its pull was five of c's standard
deviations here before).  This script solves the refinement's problem again
with the residuals mapped back to first order, ``(I + dD/dx(x_obs))^-1
(x(S, R, X) - x_obs - D(x_obs))`` (exact for c alone), by the reference
bundle's own unknowns, finite differences and Gauss-Newton: the two columns
agree to the digits printed.  (``mapped=False`` gives the former
equation.)  A camera constant on the projection's side (``x = -(c + dc) u /
w``, as COLMAP writes it) has no pull either.

Run from the repository root::

    python benchmarks/bench_fc300x_selfcal_bias.py ../shared/data/uav-block-fc300x \\
        'self_calibration=["c","x0","y0","k1","k2","k3","p1","p2","b1","b2"]' \\
        'self_calibration="auto"'

For each configuration and each of ``bench_fc300x_splits.py``'s six splits it
runs ``refine = "bundle"`` with it (the data's calibration), then solves the
same problem again (the rays the refinement kept, its control and sigmas, its
kept camera parameters, from its solution; ``bench_reference_bundle.py``'s
unknowns and Gauss-Newton, the camera's correction and its derivatives by
``CameraModel``) with the residuals mapped back.  Printed per split: the
check RMSE plan / height (m) of the refinement and of the mapped solution,
c and b1 of each (mm, and 1); then the medians.
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

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_fc300x_splits as splits  # noqa: E402
import bench_reference_bundle as reference  # noqa: E402


@dataclasses.dataclass
class MappedBundle(reference.ReferenceBundle):
    """The reference's unknowns and the refinement's camera model (``model``,
    from ``start`` values; the camera unknowns are increments to them), each
    image residual mapped back by ``(I + dD/dx)^-1`` (``mapped``)."""

    model: Any = None
    start: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    mapped: bool = True

    def image_residuals(
        self, rot: np.ndarray, centres: np.ndarray, points: np.ndarray, q: dict[str, float]
    ) -> np.ndarray:
        theta = self.start + np.array(list(q.values()))
        u = np.einsum("kji,kj->ki", rot[self.photo], points[self.point] - centres[self.photo])
        computed = -self.c * u[:, :2] / u[:, 2:3]
        r = computed - (self.xy + self.model.correction(self.xy, theta))
        if self.mapped:
            jac = np.eye(2) + self.model.xy_partials(self.xy, theta)
            r = np.linalg.solve(jac, r[:, :, None])[:, :, 0]
        out: np.ndarray = r / self.sigma[:, None]
        return out


def mapped_solution(
    result: Any, mapped: bool = True, gnss: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple[MappedBundle, dict[str, float]]:
    """The refinement's problem solved again with mapped residuals; the
    solution and the camera's values (absolute increments from the given
    camera, the refinement's names).  ``gnss``: observed centres (M, 3) in
    the result's site system and their sigmas (M, 3), if the refinement had
    them."""
    est = result.self_calibration.estimate
    used = reference._used_rays(result)
    names = tuple(est.names)
    base = reference.from_block(result, used=used, camera=tuple(f"t{i}" for i in range(len(names))))
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(base) if f.init}
    if gnss is not None:
        fields["centre_xyz"] = gnss[0] - np.mean(result.photo_centres, axis=0)
        fields["centre_sigma"] = gnss[1]
    bundle = MappedBundle(**fields, model=est.model, start=np.asarray(est.values), mapped=mapped)
    bundle.solve(iterations=12, tolerance=1e-12)
    _, _, _, q = bundle.unpack(bundle.solution)
    return bundle, dict(zip(names, bundle.start + np.array(list(q.values())), strict=True))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path)
    parser.add_argument("configs", nargs="+", help="key=value settings of [adjustment]")
    parser.add_argument("--splits", default=",".join(splits.SPLIT_NAMES))
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        toml = splits._import(args.data, Path(tmp) / "imported")
        cases = splits._splits(toml.parent / "control.csv")
        for config in args.configs:
            settings = ['refine="bundle"', *config.split()]
            print(f"\n{config}")
            print(f"{'split':9s} {'refinement':>15s} {'mapped':>15s}   c refinement / mapped (mm), b1")
            ours, theirs = [], []
            for name in args.splits.split(","):
                folder = Path(tmp) / f"case_{name}"
                folder.mkdir(exist_ok=True)
                p, h, result = splits.run_case(splits._write_case(toml, cases[name], settings, folder))
                ours.append((p, h))
                if result.self_calibration is None or result.self_calibration.estimate is None:
                    theirs.append((p, h))
                    print(f"{name:9s} {p:.4f}/{h:.4f}   (no camera parameter kept)")
                    continue
                est = result.self_calibration.estimate
                bundle, camera = mapped_solution(result)
                weak = tuple(getattr(result, "weak_checks", ()))
                pm, hm = reference.rmse(reference.check_errors(bundle, result), weak)
                theirs.append((pm, hm))
                given = dict(zip(est.names, est.values, strict=True))
                cs = f"{given.get('c', np.nan):+.4f} / {camera.get('c', np.nan):+.4f}"
                bs = f"{given.get('b1', np.nan):+.5f} / {camera.get('b1', np.nan):+.5f}"
                print(f"{name:9s} {p:.4f}/{h:.4f}   {pm:.4f}/{hm:.4f}   c {cs}, b1 {bs}; "
                      f"kept {' '.join(est.names)}", flush=True)  # fmt: skip
            a, b = np.median(ours, axis=0), np.median(theirs, axis=0)
            print(f"{'median':9s} {a[0]:.4f}/{a[1]:.4f}   {b[0]:.4f}/{b[1]:.4f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
