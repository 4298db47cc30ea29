"""cli.imports.defer_numpy_submodules: numpy's submodules that importing
scipy.linalg touches are not run by it, and work as before when used."""

from __future__ import annotations

from _cli_process import python_subprocess

_CODE = """
import sys
from strip_aerotri.cli.imports import defer_numpy_submodules
deferred = defer_numpy_submodules()
import scipy.linalg
import numpy as np
# not run by scipy's import: neither module has executed its own code yet
untouched = [n for n in ("f2py", "testing") if "__all__" not in object.__getattribute__(
    sys.modules["numpy." + n], "__dict__")]
print(",".join(deferred), ",".join(untouched))
np.testing.assert_allclose(np.polynomial.polynomial.polyval(2.0, [1.0, 1.0]), 3.0)
print(np.ma.masked_invalid([1.0, np.nan]).count(), np.char.upper("a"))
import numpy.f2py
print(callable(numpy.f2py.run_main))
"""


def test_deferred_submodules_wait_for_their_first_use() -> None:
    done = python_subprocess(_CODE)
    assert done.returncode == 0, done.stderr
    out = done.stdout.splitlines()
    deferred, untouched = out[0].split(" ")
    assert {"f2py", "testing"} <= set(deferred.split(","))
    assert untouched.split(",") == ["f2py", "testing"]
    assert out[1] == "1 A"
    assert out[2] == "True"
