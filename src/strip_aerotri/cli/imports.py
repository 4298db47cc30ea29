"""numpy's submodules that importing scipy.linalg touches and a run never
uses, loaded when first used instead.

scipy (1.14 and later) builds its array-API namespace of numpy by reading
every public name of numpy (``array_api_compat``'s ``clone_module``), and
numpy imports its submodules on first access: so ``import scipy.linalg``
imports ``numpy.f2py`` (with some 60 regular expressions compiled),
``numpy.testing``, ``numpy.polynomial``, ``numpy.ma`` and others, about 0.04
to 0.06 s of a 1000-photo run's CPU, for nothing a run calls.
:func:`defer_numpy_submodules` puts those not yet imported in place as
modules loaded on first attribute access (:class:`importlib.util.LazyLoader`,
the standard library's lazy import): scipy sees a module object, and any use
of one loads it then, as before.  ``numpy.random`` is left out: scipy uses
it while importing.

For the ``stripaero`` process only (the library does not change what its
caller's imports do).
"""

from __future__ import annotations

import importlib.util
import sys

__all__ = ["DEFERRED", "defer_numpy_submodules"]

#: The submodules of numpy deferred, those that numpy itself imports lazily.
DEFERRED = ("f2py", "testing", "polynomial", "ma", "ctypeslib", "rec", "strings", "char")


def defer_numpy_submodules() -> tuple[str, ...]:
    """Put the :data:`DEFERRED` submodules of numpy that are not imported yet
    in place as lazily loaded modules; the names so deferred."""
    import numpy

    deferred = []
    for short in DEFERRED:
        name = f"numpy.{short}"
        if name in sys.modules or short in vars(numpy):
            continue
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            continue
        loader = importlib.util.LazyLoader(spec.loader)
        spec.loader = loader
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        loader.exec_module(module)  # loads on first attribute access
        setattr(numpy, short, module)
        deferred.append(short)
    return tuple(deferred)
