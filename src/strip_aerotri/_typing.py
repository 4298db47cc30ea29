"""Type aliases shared by the package (shapes are stated in docstrings)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]
Int8Array = npt.NDArray[np.int8]
BoolArray = npt.NDArray[np.bool_]
StrArray = npt.NDArray[np.str_]

__all__ = ["ArrayLike", "BoolArray", "FloatArray", "Int8Array", "IntArray", "StrArray"]
