"""The bundle's normal-equation structures, reused within a refinement.

A refinement adjusts the same rays several times: the plan/height control
passes of :func:`strip_aerotri.bundle.refine.refine_bundle` repeat the whole
bundle with the same observations, and so do the snooping rounds that reject
nothing of the image.  Within :func:`reusing_structures` the structure of
the normal equations (:class:`~strip_aerotri.geometry.normals.NormalStructure`:
the band's order, the point groups and their index arrays; about a tenth of
a 1000-photo bundle's time) is built once for equal arguments and kept
until the block ends; outside it every call builds its own.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from contextvars import ContextVar

import numpy as np

from ..geometry.normals import NormalStructure

__all__ = ["reusing_structures", "structure_for"]

#: The last structure built inside :func:`reusing_structures` with what it
#: was built from; None outside (nothing is kept).
_LAST: ContextVar[list[tuple[tuple[object, ...], NormalStructure]] | None] = ContextVar(
    "bundle_structures", default=None
)


@contextlib.contextmanager
def reusing_structures() -> Iterator[None]:
    """Within the block, :func:`structure_for` reuses the last structure
    built for equal arguments (nested blocks share the outermost's)."""
    if _LAST.get() is not None:
        yield
        return
    token = _LAST.set([])
    try:
        yield
    finally:
        _LAST.reset(token)


def _same(a: tuple[object, ...], b: tuple[object, ...]) -> bool:
    if len(a) != len(b):
        return False
    for x, y in zip(a, b, strict=True):
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not (isinstance(x, np.ndarray) and isinstance(y, np.ndarray)):
                return False
            if not np.array_equal(x, y):
                return False
        elif x != y:
            return False
    return True


def structure_for(
    key: tuple[object, ...], build: Callable[[], NormalStructure]
) -> NormalStructure:
    """``build()``, or the structure built last for an equal `key` (arrays
    compared by value) inside :func:`reusing_structures`."""
    kept = _LAST.get()
    if kept is None:
        return build()
    if kept and _same(kept[0][0], key):
        return kept[0][1]
    structure = build()
    kept[:] = [(key, structure)]
    return structure
