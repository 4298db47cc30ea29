"""report/json_text.dumps writes the text of json.dumps with an indent, byte for byte."""

from __future__ import annotations

import enum
import json
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from strip_aerotri.report.json_text import dumps

_scalars = (
    st.none()
    | st.booleans()
    | st.integers(min_value=-(10**30), max_value=10**30)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=12)  # control characters, quotes, backslashes, non-ASCII
)
_values = st.recursive(
    _scalars,
    lambda inner: (
        st.lists(inner, max_size=5)
        | st.dictionaries(st.text(max_size=6), inner, max_size=5)
        | st.tuples(inner, inner)
    ),
    max_leaves=40,
)


@settings(max_examples=300, deadline=None)
@given(value=_values, indent=st.sampled_from([1, 2, 4]), ascii_only=st.booleans())
def test_same_text_as_json_dumps(value: Any, indent: int, ascii_only: bool) -> None:
    expected = json.dumps(value, indent=indent, ensure_ascii=ascii_only, allow_nan=False)
    assert dumps(value, indent=indent, ensure_ascii=ascii_only) == expected


class _Kind(enum.IntEnum):
    ONE = 1


class _Text(str):
    pass


def test_subclasses_tuples_and_other_keys_as_json_dumps() -> None:
    value = {
        "a": [_Kind.ONE, (1, [2.5, None]), _Text("x")],
        "b": {3: "int key", 2.5: "float key", True: "bool key", None: "none key"},
        "c": [[], {}, [[]], [{"d": ()}]],
        "é": "ü\u2028\x00",
    }
    for indent in (1, 2):
        for ascii_only in (False, True):
            expected = json.dumps(value, indent=indent, ensure_ascii=ascii_only, allow_nan=False)
            assert dumps(value, indent=indent, ensure_ascii=ascii_only) == expected


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_numbers_are_refused_as_by_json_dumps(bad: float) -> None:
    for value in (bad, [1.0, bad], {"a": {"b": [bad]}}):
        with pytest.raises(ValueError):
            json.dumps(value, indent=1, allow_nan=False)
        with pytest.raises(ValueError):
            dumps(value)


def test_a_report_is_written_as_json_dumps_writes_it() -> None:
    from strip_aerotri import simulate_strip
    from strip_aerotri.pipeline import triangulate
    from strip_aerotri.report.outputs import build_report

    sim = simulate_strip(8, seed=3)
    report = build_report(triangulate(sim.observations, sim.control, sim.crs))
    text = json.dumps(report, indent=1, ensure_ascii=False, allow_nan=False)
    assert len(text) > 10_000
    assert dumps(report) == text


_records = st.lists(
    st.fixed_dictionaries({"a%s": _values, "b": _scalars, "%d": st.lists(_scalars, max_size=3)}),
    min_size=1,
    max_size=6,
)


@settings(max_examples=200, deadline=None)
@given(rows=_records, indent=st.sampled_from([1, 2, 3]))
def test_tables_of_records_as_json_dumps(rows: list[dict[str, Any]], indent: int) -> None:
    # rows with the same keys in the same order (written through one template)
    # and the same rows mixed with ones that break the pattern
    variants: list[Any] = [
        rows,
        {"t": rows},
        [rows],
        [*rows, {"b": 1, "a%s": 2, "%d": []}],  # the same keys in another order
        [*rows, {"a%s": 1}],  # fewer keys
        [*rows, {**rows[0], "c": 1}],  # more keys
        [*rows, [1, 2]],  # not an object
        [*rows, {}],
        [{}, *rows],
        [*rows, _Dict(rows[0])],  # a subclass of dict
        [{1: "int key"}] * 2,
    ]
    for value in variants:
        expected = json.dumps(value, indent=indent, ensure_ascii=False, allow_nan=False)
        assert dumps(value, indent=indent) == expected


class _Dict(dict):  # type: ignore[type-arg]
    pass
