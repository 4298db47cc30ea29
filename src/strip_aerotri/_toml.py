"""Writing TOML (``tomllib`` only reads it): the values of a project file,
written alike by ``stripaero import`` and the simulator."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["toml_id_list", "toml_string", "toml_value"]


def toml_string(text: str) -> str:
    """A TOML basic string."""
    out = []
    for ch in str(text):
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_value(value: object) -> str:
    """A TOML value for a str, bool, int, finite float or a list of them."""
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        f = float(value)
        if not math.isfinite(f):
            raise ValueError(f"TOML has no value for {f!r}")
        return repr(f)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {type(value).__name__}")


def toml_id_list(ids: Sequence[str], per_line: int | None = 6) -> str:
    """A TOML list of id strings, ``per_line`` to a line (None: one line)."""
    items = [toml_string(i) for i in ids]
    if per_line is None or len(items) <= per_line:
        return "[" + ", ".join(items) + "]"
    lines = [", ".join(items[k : k + per_line]) for k in range(0, len(items), per_line)]
    return "[\n    " + ",\n    ".join(lines) + ",\n]"
