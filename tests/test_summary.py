"""The typed summary of a run (report/summary.py): the same figures as the
result and report.json, computed in the library."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.project import load_project, run_project
from strip_aerotri.report.summary import build_run
from strip_aerotri.simulate import simulate_block, simulate_strip


def _project(tmp_path, sim, extra=""):
    sim.write_project(tmp_path)
    toml = tmp_path / "strip.toml"
    toml.write_text(toml.read_text(encoding="utf-8") + extra, encoding="utf-8")
    return load_project(toml)


def test_strip_summary_is_the_result_and_its_report(tmp_path):
    project = _project(tmp_path, simulate_strip(8, seed=4), "\n[report]\nmap_scale = 5000\n")
    result = run_project(project)
    outputs = build_run(result, project=project)
    summary, record = outputs.summary, json.loads(outputs.files["report.json"])
    assert summary.kind == "strip" and summary.name == project.name
    assert summary.n_points == int(result.strip.triangulated.sum())
    assert summary.check.rmse_plan == result.check_statistics.rmse_plan
    assert summary.check.n_height == result.check_statistics.n_height
    criteria = record["tolerances"]["criteria"]
    assert summary.tolerances is not None and summary.tolerances.map_scale == 5000
    assert summary.tolerances.failed == tuple(
        c["name"] for c in criteria if c["passed"] is False
    )
    assert summary.tolerances.n_judged == sum(c["passed"] is not None for c in criteria)
    assert summary.report_name == "report.html" and set(summary.files) == set(outputs.files)


def test_block_summary_judges_the_transfer_as_report_json(tmp_path):
    project = _project(tmp_path, simulate_block(3, 6, seed=2))
    result = run_project(project)
    outputs = build_run(result, project=project)
    summary, record = outputs.summary, json.loads(outputs.files["report.json"])
    joins = record["block"]["joins"]
    assert summary.kind == "block" and summary.n_strips == 3
    assert summary.tolerances is None  # no map scale
    worst = max(joins, key=lambda j: j["mean_plan_m"])
    assert summary.join is not None and list(summary.join.strips) == worst["strips"]
    transfer = max(joins, key=lambda j: j["mean_transfer_um"])
    assert list(summary.join.transfer_strips) == transfer["strips"]
    assert summary.join.mean_transfer_um == pytest.approx(transfer["mean_transfer_um"])
    assert summary.join.transfer_passed is transfer["transfer_passed"]
    assert math.isfinite(summary.join.mean_transfer_um)
    assert summary.control.rmse_plan == result.control_statistics.rmse_plan
    assert np.isfinite(summary.control_fit.rmse_plan)
