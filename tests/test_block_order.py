"""The units of a block's transformation numbered across the strips.

The order changes the band of the reduced normal equations (the cost), not
the solution: the block by models is solved with its units in the order of
their centres along the flight and strip after strip, with the same result.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import strip_aerotri.block.snooping as block_snooping
import strip_aerotri.block.strips as block_strips
from strip_aerotri.block.strips import adjust_block
from strip_aerotri.errors import StripAerotriWarning
from strip_aerotri.geometry.normals import NormalStructure
from strip_aerotri.observations import StripSpec
from strip_aerotri.simulate import simulate_block


@pytest.fixture(scope="module")
def block():
    return simulate_block(4, 14, preset="drone", side_overlap=0.4, seed=3)


def _adjust(sim):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        return adjust_block(
            sim.observations,
            sim.control,
            sim.crs,
            [StripSpec(s.name, s.photo_ids) for s in sim.strips],
        )


def test_across_the_strips_is_the_narrowest_band_and_changes_nothing(monkeypatch, block):
    orders = []
    band_order = block_snooping._band_order

    def spy(p):
        order = band_order(p)
        rows = p.rows
        n_units = p.unit_strip.shape[0]
        widths = {
            name: NormalStructure.from_indices(
                n_units, 7, int(rows.point.max()) + 1, rows.unit, rows.point, order=o
            ).width
            for name, o in (("across", order), ("given", "given"), ("rcm", "rcm"))
        }
        orders.append(widths)
        return order

    monkeypatch.setattr(block_snooping, "_band_order", spy)
    across = _adjust(block)
    # measured: a half-band of 20 models across the strips, 24 by reverse
    # Cuthill-McKee, 25 strip after strip (10 x 100 drone: 53, 111, 197)
    widths = orders[0]
    assert widths["across"] < min(widths["rcm"], widths["given"])
    monkeypatch.setattr(block_snooping, "_band_order", lambda p: "given")
    monkeypatch.setattr(block_strips, "_band_order", lambda p: "given")
    strip_by_strip = _adjust(block)
    np.testing.assert_allclose(across.points, strip_by_strip.points, rtol=0, atol=1e-8)
    np.testing.assert_allclose(
        across.photo_centres, strip_by_strip.photo_centres, rtol=0, atol=1e-8
    )
    assert [r.point for r in across.rejections] == [r.point for r in strip_by_strip.rejections]
