"""The small HTML pieces every report page uses: escaping, number
formatting, tables and inline figures (no page of its own, so that any
section can use them without importing a page)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def _esc(value: Any) -> str:
    import html

    return html.escape(str(value), quote=True)


def _fmt(value: Any, digits: int = 3) -> str:
    kind = type(value)  # the exact built-in types first: most cells of a page
    if kind is float:
        return f"{value:.{digits}f}" if math.isfinite(value) else "–"
    if kind is int:
        return str(value)
    if kind is str:
        return _esc(value)
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(float(value)):
            return "–"
        return f"{float(value):.{digits}f}"
    return _esc(value)


def _table(
    header: list[str],
    rows: list[list[Any]],
    *,
    left: int = 1,
    left_columns: tuple[int, ...] = (),
    scroll: bool = False,
    digits: list[int] | int = 3,
) -> str:
    if not rows:
        return "<p class='na'>none</p>"
    if isinstance(digits, int):
        digits = [digits] * len(header)
    head = "".join(
        ("<th class='l'>" if i < left else "<th>") + f"{_esc(h)}</th>"
        for i, h in enumerate(header)
    )
    body = []
    for row in rows:
        cells = []
        for i, v in enumerate(row):
            text = v[0] if isinstance(v, tuple) else _fmt(v, digits[i])
            cls = " class='l'" if i < left or i in left_columns else ""
            cells.append(f"<td{cls}>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    html_table = f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    return f"<div class='scroll'>{html_table}</div>" if scroll and len(rows) > 25 else html_table


def _figure(b64: str | None, caption: str, alt: str) -> str:
    if b64 is None:
        return f"<p class='na'>{_esc(caption)}: nothing to show.</p>"
    return (
        f"<figure><img alt='{_esc(alt)}' src='data:image/png;base64,{b64}'>"
        f"<figcaption>{_esc(caption)}</figcaption></figure>"
    )


def weak_check_sentence(check: Mapping[str, Any]) -> str:
    """The plain summary's sentence on the weakly determined check points of
    report.json's ``check`` ('' when none is): named, listed with the check
    points, left out of the figures."""
    weak = list(check.get("weakly_determined") or ())
    if not weak:
        return ""
    return (
        f"{len(weak)} more check point(s) ({', '.join(weak)}) are listed below but left out of "
        "these figures: their own rays fix them too loosely to check the adjustment. "
    )
