"""The control lookup over the strip's point ids (ground.common.index_of)."""

import numpy as np
import pytest

from strip_aerotri.ground.common import index_of as _index_of


def reference(ids, names):
    return np.array([ids.index(n) if n in ids else -1 for n in names], dtype=np.intp)


SORTED = tuple(f"{i:04d}" for i in range(0, 500, 3))


@pytest.mark.parametrize(
    "ids, names",
    [
        (SORTED, ["0000", "0300", "0498"]),  # first, middle, last
        (SORTED, ["0001", "0300", "zzz", ""]),  # absent between, beyond the end, before the start
        # not sorted: binary search misses names that are present; the pass finds them
        (("b", "a", "d", "c", "e"), ["a", "b", "c", "d", "e", "x"]),
        (tuple(reversed(SORTED)), ["0000", "0300", "0498", "0001"]),
        ((), ["a"]),
        (SORTED, []),
    ],
)
def test_index_of_matches_a_linear_search(ids, names):
    np.testing.assert_array_equal(_index_of(ids, names), reference(list(ids), names))
    assert _index_of(ids, names).dtype == np.intp
