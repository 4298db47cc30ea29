"""format_csv writes a row with one % (nothing to quote) or through the csv
module: either way the text of the csv module on the values formatted one
by one (floats rounded to their decimals, NaN empty, -0 as 0)."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from strip_aerotri.report.files import format_csv


def _reference(header: list[str], columns: list[np.ndarray], decimals: list[int]) -> str:
    texts = []
    for column, digits in zip(columns, decimals, strict=True):
        if column.dtype.kind == "b":
            texts.append(["true" if v else "false" for v in column.tolist()])
        elif column.dtype.kind in "iu":
            texts.append([str(v) for v in column.tolist()])
        elif column.dtype.kind == "f":
            rounded = np.round(column, digits) + 0.0
            texts.append(["" if not np.isfinite(v) else f"{v:.{digits}f}" for v in rounded])
        else:
            texts.append([str(v) for v in column.tolist()])
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(zip(*texts, strict=True))
    return buffer.getvalue()


_IDS = {
    "plain": ["P1", "08", "a b", "x%sy", "é"],
    "comma": ["P1", "a,b", "c"],
    "quote": ['say "hi"', "b", "c"],
    "newline": ["a\nb", "c", "d"],
    "empty": ["a", "", "c"],
    "empty first": ["", "b"],
}


@pytest.mark.parametrize("kind", sorted(_IDS))
@pytest.mark.parametrize("nan", [False, True])
def test_rows_as_the_csv_module_writes_them(kind: str, nan: bool) -> None:
    rng = np.random.default_rng(len(kind))
    ids = np.array(_IDS[kind], dtype=object)
    n = ids.size
    values = rng.normal(size=n) * 1e3
    values[0] = -0.00001  # written 0.0000
    if nan:
        values[-1] = np.nan
    columns = [ids, values, rng.integers(-5, 5, n), rng.random(n) > 0.5, -rng.random(n) * 1e-6]
    header = ["id", "X", "n", "flag", "tiny"]
    decimals = [0, 4, 0, 0, 6]
    text = format_csv(header, [ids, (values, 4), columns[2], columns[3], (columns[4], 6)])
    assert text == _reference(header, columns, decimals)
    first = list(csv.reader(io.StringIO(text)))[1]
    assert first[1] == "0.0000"  # -0.00001 rounded, not "-0.0000"


def test_a_single_column_of_empty_text_is_quoted_as_csv_does() -> None:
    assert format_csv(["id"], [np.array(["", "a"], dtype=object)]) == 'id\n""\na\n'


def test_no_rows_is_the_header_line() -> None:
    assert format_csv(["a", "b"], [np.zeros(0), np.zeros(0, dtype=np.int64)]) == "a,b\n"


def test_a_row_of_empty_cells_as_the_csv_module_writes_it() -> None:
    ids = np.array(["", "a"], dtype=object)
    values = np.array([np.nan, 1.0])
    expected = _reference(["id", "X"], [ids, values], [0, 4])
    assert format_csv(["id", "X"], [ids, values]) == expected == "id,X\n,\na,1.0000\n"


@pytest.mark.parametrize("finite", ["none", "one", "some", "all"])
def test_float_columns_with_empty_cells_and_text_ids(finite: str) -> None:
    # residual columns: empty for most rows (tie points), inf empty too;
    # ids as numpy text (dtype U) and as objects
    rng = np.random.default_rng(5)
    n = 40
    values = rng.normal(size=n) * 10.0 ** rng.integers(-6, 6, n)
    keep = {
        "none": np.zeros(n, bool),
        "one": np.arange(n) == 7,
        "some": rng.random(n) < 0.2,
        "all": np.ones(n, bool),
    }[finite]
    values[~keep] = np.where(rng.random((~keep).sum()) < 0.5, np.nan, np.inf)
    values[keep & (np.arange(n) % 5 == 0)] = -0.00001  # written 0.0000
    ids = np.array([f"P{k:03d}" for k in range(n)])
    for id_column in (ids, ids.astype(object)):
        columns = [id_column, values, values * -3.0]
        text = format_csv(["id", "dE", "dN"], [id_column, (values, 4), (values * -3.0, 6)])
        assert text == _reference(["id", "dE", "dN"], columns, [0, 4, 6])
