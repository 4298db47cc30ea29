"""The bundle's normal-equation structures reused within a refinement
(bundle/_structures.py): built once for equal arguments, the same solution."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

import strip_aerotri.bundle.refine as refine_module
from strip_aerotri.bundle import _structures
from strip_aerotri.geometry.normals import NormalStructure
from strip_aerotri.pipeline import triangulate
from strip_aerotri.simulate import simulate_strip


def _structure(n: int = 4) -> NormalStructure:
    unit = np.repeat(np.arange(n), 3)
    point = np.tile(np.arange(3), n)
    return NormalStructure.from_indices(n, 6, 3, unit, point)


def test_a_structure_is_reused_only_inside_the_block_and_for_equal_keys() -> None:
    built: list[int] = []

    def build() -> NormalStructure:
        built.append(1)
        return _structure()

    key = (4, np.arange(5), "a")
    first = _structures.structure_for(key, build)
    assert _structures.structure_for(key, build) is not first  # outside: always built
    with _structures.reusing_structures():
        inside = _structures.structure_for(key, build)
        with _structures.reusing_structures():  # nested: the outer block's
            assert _structures.structure_for((4, np.arange(5), "a"), build) is inside
        assert _structures.structure_for((4, np.arange(5) + 1, "a"), build) is not inside
        longer = _structures.structure_for((4, np.arange(6), "a"), build)
        assert longer is not inside
        assert _structures.structure_for((4, np.arange(6), "a"), build) is longer
    assert len(built) == 5  # twice outside, then once per change of the key


def test_the_passes_of_a_refinement_build_one_structure_and_match_a_fresh_build(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a projected strip with plan and height control points: its curved frame
    # takes two passes of the whole bundle on the same rays
    sim = simulate_strip(40, preset="drone", seed=3, control="fig4")
    strip = triangulate(sim.observations, sim.control, sim.crs)
    calls: list[int] = []
    original = NormalStructure.from_indices

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(NormalStructure, "from_indices", counted)
    reused = refine_module.refine_bundle(strip)
    with_reuse = len(calls)
    calls.clear()
    monkeypatch.setattr(refine_module, "reusing_structures", contextlib.nullcontext)
    fresh = refine_module.refine_bundle(strip)
    assert with_reuse == 1 < len(calls)
    np.testing.assert_allclose(reused.points_frame, fresh.points_frame, rtol=0, atol=1e-9)
    np.testing.assert_allclose(reused.point_std, fresh.point_std, rtol=1e-9, equal_nan=True)
    assert reused.sigma0 == pytest.approx(fresh.sigma0, rel=1e-12)
