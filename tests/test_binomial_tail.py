"""_stats.binomial_tail and normal_tail, the chance of report.tolerances.chance_beyond
without scipy.special: against scipy's betainc and ndtr, and against the exact
sum in 60-digit decimals."""

from __future__ import annotations

import math
import subprocess
import sys
from decimal import Decimal, localcontext

import numpy as np
import pytest
import scipy
from scipy.special import betainc, ndtr

from strip_aerotri._stats import binomial_tail, normal_tail
from strip_aerotri.report.tolerances import CHANCE_LEVEL, LIMIT_FACTOR, LIMIT_SHARE, chance_beyond

#: The chances the tolerances use: beyond three sigma (2 Φ(−3)) and the 1 % share.
USED_P = (float(2.0 * ndtr(-LIMIT_FACTOR)), LIMIT_SHARE)
#: scipy's betainc is Boost's ibeta from scipy 1.12, within about 1e-13 of the
#: exact sum; before, cephes's, within about 1e-10 (the minimum versions' CI
#: run): our own accuracy is tested against the exact sum below, not here.
BOOST = tuple(int(v) for v in scipy.__version__.split(".")[:2]) >= (1, 12)


def _scipy_rel(reference: float) -> float:
    """How close scipy's betainc is to the exact tail (see BOOST)."""
    if not BOOST:
        return 1e-9
    # where a verdict is decided, scipy's own error there; deep in the tail
    # to the exponent's rounding
    return 2e-13 if reference >= 1e-4 else 2e-12


def _counts_around_mean(n: int, p: float) -> list[int]:
    spread = math.sqrt(n * p * (1.0 - p))
    around = np.round(n * p + spread * np.linspace(-6.0, 10.0, 41))
    return sorted(set(np.clip(np.r_[np.arange(1, 25), around], 1, n).astype(int).tolist()))


@pytest.mark.parametrize("p", [*USED_P, 0.05, 0.3])
@pytest.mark.parametrize("n", [1, 2, 7, 40, 333, 1000, 20_000, 100_000])
def test_the_binomial_tail_is_scipys(n: int, p: float) -> None:
    for count in _counts_around_mean(n, p):
        reference = float(betainc(count, n - count + 1, p))
        assert binomial_tail(count, n, p) == pytest.approx(
            reference, rel=_scipy_rel(reference), abs=1e-300
        )


def _exact_tail(count: int, n: int, p: float) -> float:
    with localcontext() as context:
        context.prec = 60
        chance, other = Decimal(p), 1 - Decimal(p)
        return float(
            sum(
                Decimal(math.comb(n, j)) * chance**j * other ** (n - j)
                for j in range(count, n + 1)
            )
        )


def _exact_lower_complement(count: int, n: int, p: float) -> float:
    """1 − P(X < count) in 60-digit decimals, the terms by their ratio (for
    large n, where the upper sum has too many terms; no cancellation when the
    tail is not small)."""
    with localcontext() as context:
        context.prec = 60
        chance, other = Decimal(p), 1 - Decimal(p)
        term, lower = other**n, Decimal(0)
        for j in range(count):
            lower += term
            term = term * (n - j) / (j + 1) * chance / other
        return float(1 - lower)


@pytest.mark.parametrize(
    ("count", "n", "p"),
    [(1, 40, USED_P[0]), (2, 1000, USED_P[0]), (13, 5000, USED_P[0]), (20, 1000, USED_P[0]),
     (18, 6667, USED_P[0]), (31, 12540, USED_P[0]), (10, 1000, 0.01), (25, 1000, 0.01),
     (74, 1000, 0.05), (45, 100, 0.3), (3, 3, 0.3)],
)
def test_the_binomial_tail_is_the_exact_sum(count: int, n: int, p: float) -> None:
    # to a few units of the last place (scipy's betainc is 1.2e-13 off at 18 of 6667)
    assert binomial_tail(count, n, p) == pytest.approx(_exact_tail(count, n, p), rel=3e-15)


def test_the_binomial_tail_at_its_ends() -> None:
    assert binomial_tail(0, 10, 0.3) == 1.0
    assert binomial_tail(-2, 10, 0.3) == 1.0
    assert binomial_tail(11, 10, 0.3) == 0.0
    assert binomial_tail(3, 10, 0.0) == 0.0
    assert binomial_tail(3, 10, 1.0) == 1.0
    assert binomial_tail(10, 10, 0.3) == pytest.approx(0.3**10, rel=1e-15)
    assert binomial_tail(1, 10, 0.3) == pytest.approx(1.0 - 0.7**10, rel=1e-15)
    # a million trials: the first term underflows in products, not in Loader's form
    assert binomial_tail(2800, 1_000_000, USED_P[0]) == pytest.approx(
        _exact_lower_complement(2800, 1_000_000, USED_P[0]), rel=1e-13
    )


def test_the_normal_tail_is_scipys() -> None:
    for x in np.linspace(0.0, 8.0, 161):
        assert normal_tail(x) == pytest.approx(float(ndtr(-x)), rel=1e-15)


def test_chance_beyond_is_the_binomial_survival() -> None:
    for count, n in ((1, 40), (3, 300), (12, 2000), (40, 10_000)):
        p = float(2.0 * ndtr(-LIMIT_FACTOR))
        reference = float(betainc(count, n - count + 1, p))
        assert chance_beyond(count, n) == pytest.approx(reference, rel=_scipy_rel(reference))
        capped = float(betainc(count, n - count + 1, min(p, 1e-3)))
        assert chance_beyond(count, n, at_most=1e-3) == pytest.approx(
            capped, rel=_scipy_rel(capped)
        )
    assert 0.0 < chance_beyond(45, 10_000) < CHANCE_LEVEL < chance_beyond(30, 10_000)


def test_the_run_imports_no_scipy_special() -> None:
    code = (
        "import importlib, sys\n"
        "from strip_aerotri.cli.loading import BEFORE_FORK, RUN_MODULES\n"
        "for name in (*BEFORE_FORK, *RUN_MODULES):\n"
        "    importlib.import_module(name)\n"
        "from strip_aerotri.report.tolerances import chance_beyond\n"
        "chance_beyond(3, 300)\n"
        "assert 'scipy.special' not in sys.modules, 'scipy.special imported'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
