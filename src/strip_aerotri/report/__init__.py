"""The outputs of a run.

- :mod:`.outputs`: :func:`build_outputs`, every file of a result folder;
- :mod:`.tables`: ``points.csv``, ``photos.csv``, ``points.geojson``;
- :mod:`.record`: ``report.json`` (:func:`build_report`);
- :mod:`.html`, :mod:`.figures`: ``report.html`` and its figures;
- :mod:`.tolerances`: the R4 tolerance criteria and their verdicts;
- :mod:`.values`: plain JSON values, point roles, control rows;
- :mod:`.files`: CSV formatting and the atomic result folder.
"""
