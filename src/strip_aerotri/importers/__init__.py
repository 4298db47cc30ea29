"""Importers: write a contract project (strip.toml and CSV files) from another program's files.

One module per source format reads its files into arrays and hands them to
:func:`~strip_aerotri.importers.common.assemble`, which decides the strips,
the photo order, the image axis along the flight and the control/check
split; :func:`~strip_aerotri.importers.common.write_project` writes the
project atomically.  See docs/import.md.
"""
