"""_stats.chi_critical_value: the chi-square quantile of the blunder tests in
closed form, against scipy's chdtri, without importing scipy.special."""

from __future__ import annotations

import subprocess
import sys

import pytest
from scipy.special import chdtri

from strip_aerotri._stats import _chi2_upper_quantile, chi_critical_value


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 5, 6, 7, 10, 15, 50, 200])
def test_the_chi_square_quantile_is_scipys(dof: int) -> None:
    for p in (0.999, 0.9, 0.5, 0.05, 1e-3, 1e-6, 1e-9, 1e-12, 1e-15, 1e-30):
        assert _chi2_upper_quantile(dof, p) == pytest.approx(float(chdtri(dof, p)), rel=1e-12)
    assert chi_critical_value(84_824, 1e-3, dof) == pytest.approx(
        float(chdtri(dof, 1e-3 / 84_824)) ** 0.5, rel=1e-12
    )


def test_the_quantile_refuses_what_it_cannot_give() -> None:
    for dof, p in ((0, 0.5), (3, 0.0), (3, 1.0)):
        with pytest.raises(ValueError, match="Expected dof"):
            _chi2_upper_quantile(dof, p)


def test_the_critical_value_imports_no_scipy_special() -> None:
    code = (
        "import sys\n"
        "from strip_aerotri._stats import chi_critical_value\n"
        "chi_critical_value(1000, 0.001, 3)\n"
        "assert 'scipy.special' not in sys.modules, 'scipy.special imported'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
