"""The cofactors of the simultaneous transformation's control points: the
diagonal asked for per component equals that of the full 3 x 3 blocks."""

from __future__ import annotations

import numpy as np

from strip_aerotri.geometry import simultaneous as sm
from strip_aerotri.simulate import simulate_block


def test_component_cofactors_equal_the_full_blocks(monkeypatch):
    seen = {}
    original = sm.point_cofactors

    def spy(normals, lu, scale, points, components=None):
        seen["args"] = (normals, lu, scale, points, components)
        return original(normals, lu, scale, points, components)

    monkeypatch.setattr(sm, "point_cofactors", spy)
    from strip_aerotri.block.strips import adjust_block
    from strip_aerotri.observations import StripSpec

    sim = simulate_block(3, 8, preset="film", seed=1)
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    adjust_block(sim.observations, sim.control, sim.crs, specs)
    normals, lu, scale, points, components = seen["args"]
    assert components is not None and components.any() and not components.all()
    full = original(normals, lu, scale, points)
    part = original(normals, lu, scale, points, components)
    owner, axis = np.nonzero(components)
    np.testing.assert_allclose(
        part[owner, axis, axis], full[owner, axis, axis], rtol=1e-12, atol=0
    )
    assert np.isnan(part[~components[:, :, None] & np.eye(3, dtype=bool)]).all()
    # a variance: positive
    assert (part[owner, axis, axis] > 0).all()
