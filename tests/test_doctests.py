"""Every example in the package's docstrings runs and gives what it shows
(the doctests of every module, as ``pytest --doctest-modules src`` would)."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import numpy as np
import pytest

PACKAGE = Path(__file__).parents[1] / "src" / "strip_aerotri"


def _modules() -> list[str]:
    names = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names.append(".".join(parts))
    return names


def _examples(module_name: str) -> list[doctest.DocTest]:
    module = importlib.import_module(module_name)
    tests = doctest.DocTestFinder(exclude_empty=True).find(module, module_name)
    # only the examples written in this module (not those of names it imports)
    return [t for t in tests if t.examples and t.name.startswith(module_name)]


WITH_EXAMPLES = [m for m in _modules() if _examples(m)]


def test_the_examples_are_found():
    assert len(WITH_EXAMPLES) >= 10, WITH_EXAMPLES


@pytest.mark.parametrize("module_name", WITH_EXAMPLES)
def test_docstring_examples_run(module_name, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # an example that writes files writes them here
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    numpy_2 = np.lib.NumpyVersion(np.__version__) >= "2.0.0"
    with np.printoptions(legacy="1.25" if numpy_2 else False):  # scalars shown as 1.0
        for test in _examples(module_name):
            runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed"


def test_a_wrong_example_fails():
    """The runner above reports a wrong example (the test can fail)."""

    def shown() -> None:
        """
        >>> 1 + 1
        3
        """

    runner = doctest.DocTestRunner()
    for test in doctest.DocTestFinder().find(shown, "shown"):
        runner.run(test, out=lambda text: None)
    assert runner.summarize(verbose=False).failed == 1
