"""Text taken from the input, made safe to echo in a message, a figure or a page.

Every value a message repeats from a file (an id, a cell, a key, a name) goes
through :func:`shorten`: control characters are dropped (ANSI escape
sequences whole, so that a message cannot recolour or move the user's
terminal; NUL bytes, which cut C strings and figure texts short) and a long
value keeps its head and tail with the number of characters left out, so
that a message stays one readable line however large the value.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from itertools import accumulate

__all__ = ["MAX_ECHO", "MAX_LINE", "clean", "cut_at_items", "named", "shorten"]

#: Characters of one echoed value (an id, a cell, a name) in a message.
MAX_ECHO = 60
#: Characters of one message (its line stays under 500 with the
#: ``stripaero: error:`` prefix); a longer one loses its middle.
MAX_LINE = 480

# ECMA-48: CSI sequences (ESC [ ... final byte), other two-byte escapes, and
# the C0/C1 controls with DEL; tab and line breaks are kept (one_line joins lines)
_ANSI = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b[@-_]?|\x9b[0-?]*[ -/]*[@-~]")
_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f]")


def clean(text: object) -> str:
    """``text`` as a string without ANSI escape sequences or control
    characters (tab and line breaks kept)."""
    value = str(text)
    if not _CONTROL.search(value):
        return value
    return _CONTROL.sub("", _ANSI.sub("", value))


def shorten(text: object, limit: int = MAX_ECHO) -> str:
    """``text`` cleaned (:func:`clean`) and, when longer than ``limit``
    characters, cut to its head and tail around ``…(N characters)…``.

    >>> shorten("x" * 1000, 30)
    'xxxxxx…(989 characters)…xxxxx'
    >>> shorten("P1\\x1b[31m\\x00")
    'P1'
    """
    if len(str(text)) > 4 * limit:  # never clean megabytes to keep a few characters
        value = str(text)
        value = clean(value[: 2 * limit]) + clean(value[-2 * limit :])
        skipped = len(str(text)) - len(value)
    else:
        value, skipped = clean(text), 0
    if len(value) <= limit and not skipped:
        return value
    total = len(value) + skipped
    marker_len = len(f"…({total} characters)…")
    keep = max(limit - marker_len, 2)
    head, tail = value[: (keep + 1) // 2], value[len(value) - keep // 2 :]
    return f"{head}…({total - len(head) - len(tail)} characters)…{tail}"


def cut_at_items(text: object, limit: int = MAX_LINE, *, where: str = "") -> str:
    """``text`` cleaned and, when longer than ``limit`` characters, cut after
    the last whole item of its ``"; "``-separated list that fits, with how many
    items were left out (``where``: the file that has them all).  A text whose
    first item alone is too long loses its middle (:func:`shorten`).

    >>> cut_at_items("held: a (t 1); b (t 2); c (t 3)", 28)
    'held: a (t 1); … and 2 more'
    """
    if len(str(text)) > 40 * limit:  # never split megabytes to keep a few items
        return shorten(text, limit)
    value = clean(text)
    if len(value) <= limit:
        return value
    items = value.split("; ")
    ends = list(accumulate(len(i) + 2 for i in items))  # each item with its "; "
    for kept in range(len(items) - 1, 0, -1):
        more = f"… and {len(items) - kept} more" + (f" in {where}" if where else "")
        if ends[kept - 1] + len(more) <= limit:
            return "; ".join(items[:kept]) + "; " + more
    return shorten(value, limit)


def named(ids: Sequence[object], limit: int = 5) -> str:
    """The first ``limit`` of ``ids`` quoted and joined, and how many more.

    >>> named(["a", "b", "c"], 2)
    "'a', 'b' and 1 more"
    """
    text = ", ".join(repr(i) for i in ids[:limit])
    return text + (f" and {len(ids) - limit} more" if len(ids) > limit else "")
