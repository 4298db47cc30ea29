"""Packaging that pyproject.toml cannot say: the docs/ pages ship inside the
package as ``strip_aerotri.docs`` (read by ``stripaero docs``), from the one
docs/ folder of the repository.  Everything else is in pyproject.toml."""

from setuptools import find_namespace_packages, setup

setup(
    packages=[
        *find_namespace_packages(where="src", include=["strip_aerotri*"]),
        "strip_aerotri.docs",
    ],
    package_dir={"": "src", "strip_aerotri.docs": "docs"},
    package_data={"strip_aerotri": ["py.typed"], "strip_aerotri.docs": ["*.md"]},
)
