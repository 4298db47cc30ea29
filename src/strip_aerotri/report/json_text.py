"""report.json's text: ``json.dumps(value, indent=..., allow_nan=False)``, faster.

The standard library encodes with an indent in pure Python, one generator
step per token; a strip's report has about 300 000 of them.  :func:`dumps`
writes the same text (byte for byte, tested against ``json.dumps``) for
the plain values a report is made of (dict with str keys, list, str, int,
float, bool, None): containers are joined whole, and a list or object of
scalars is one ``join`` of its encoded values.  Anything else (a tuple, a
subclass, a key that is not a string) is handed to ``json.dumps`` itself,
its lines moved to the depth where it stands.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from json.encoder import encode_basestring, encode_basestring_ascii
from typing import Any

__all__ = ["dumps"]


def _number(value: float) -> str:
    text = float.__repr__(value)
    if text[-1] in "nf":  # nan, inf, -inf: allow_nan=False, as the report is written
        raise ValueError(f"Out of range float values are not JSON compliant: {text}")
    return text


def dumps(value: Any, *, indent: int = 1, ensure_ascii: bool = False) -> str:
    """``json.dumps(value, indent=indent, ensure_ascii=ensure_ascii, allow_nan=False)``."""
    text = encode_basestring_ascii if ensure_ascii else encode_basestring
    scalars: dict[type, Callable[[Any], str]] = {
        str: text,
        float: _number,
        int: int.__repr__,
        bool: lambda v: "true" if v else "false",
        type(None): lambda v: "null",
    }
    get = scalars.get

    def fallback(item: Any, depth: int) -> str:
        return json.dumps(item, indent=indent, ensure_ascii=ensure_ascii, allow_nan=False).replace(
            "\n", "\n" + " " * (indent * depth)
        )

    def encode(item: Any, depth: int) -> str:
        kind = type(item)
        scalar = scalars.get(kind)
        if scalar is not None:
            return scalar(item)
        inner = "\n" + " " * (indent * (depth + 1))
        close = "\n" + " " * (indent * depth)
        if kind is list:
            if not item:
                return "[]"
            if type(item[0]) is dict:
                records = table(item, depth)
                if records is not None:
                    return records
            # scalars encoded here, containers one level down
            values = [encode(v, depth + 1) if (f := get(type(v))) is None else f(v) for v in item]
            return "[" + inner + ("," + inner).join(values) + close + "]"
        if kind is dict and all(type(key) is str for key in item):
            if not item:
                return "{}"
            members = [
                text(k) + (": " + (encode(v, depth + 1) if (f := get(type(v))) is None else f(v)))
                for k, v in item.items()
            ]
            return "{" + inner + ("," + inner).join(members) + close + "}"
        return fallback(item, depth)

    def table(rows: list[Any], depth: int) -> str | None:
        """A list of objects with the same keys in the same order (the report's
        tables: a record per pair, model, point): the keys written once into a
        ``%`` template that takes each row's encoded values; None otherwise."""
        keys = tuple(rows[0])
        if not keys or not all(type(k) is str for k in keys):
            return None
        if not all(type(row) is dict and tuple(row) == keys for row in rows):
            return None
        row_inner = "\n" + " " * (indent * (depth + 2))
        template = (
            "{"
            + row_inner
            + ("," + row_inner).join(text(k).replace("%", "%%") + ": %s" for k in keys)
            + "\n"
            + " " * (indent * (depth + 1))
            + "}"
        ).__mod__
        encoded = [
            template(
                tuple(
                    [
                        encode(v, depth + 2) if (f := get(type(v))) is None else f(v)
                        for v in row.values()
                    ]
                )
            )
            for row in rows
        ]
        inner = "\n" + " " * (indent * (depth + 1))
        return "[" + inner + ("," + inner).join(encoded) + "\n" + " " * (indent * depth) + "]"

    return encode(value, 0)
