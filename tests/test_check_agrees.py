"""``stripaero check`` judges by the run's own rules: where ``run`` accepts a
project, ``check`` finds no problem, and where ``run`` stops, ``check`` names
the same rule (project/check.py against project/run.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from _synthetic import without_ties
from strip_aerotri.errors import GeometryError
from strip_aerotri.observations import ControlType
from strip_aerotri.project import check_project, load_project, run_project
from strip_aerotri.simulate import simulate_block, simulate_strip


def _load(tmp_path, sim, adjustment=""):
    sim.write_project(tmp_path)
    toml = tmp_path / "strip.toml"
    if adjustment:
        text = toml.read_text(encoding="utf-8")
        head = "[adjustment]\n"
        text = text.replace(head, head + adjustment) if head in text else text + head + adjustment
        toml.write_text(text, encoding="utf-8")
    return load_project(toml)


def _run_outcome(project) -> str | None:
    """None when the run succeeds, else its error message."""
    try:
        run_project(project)
    except GeometryError as exc:
        return str(exc)
    return None


def test_a_model_without_ties_is_a_break_for_check_as_for_run(tmp_path):
    """block = "models" (the default) takes a model without tie points as a
    break, each side on its own control: check warns and finds no problem,
    and the run succeeds with the break."""
    project = _load(tmp_path, simulate_strip(16, seed=4))
    project = dataclasses.replace(project, observations=without_ties(project.observations, 6))
    report = check_project(project)
    assert report.problems == []
    assert any("pair 1007-1008 shares no tie point" in w for w in report.warnings)
    result = run_project(project)
    assert result.strip.breaks.tolist() == [6]


def test_j_chain_refuses_a_model_without_ties_in_check_and_run(tmp_path):
    """With J's polynomials (block = "strips") the scale must be carried
    along the chain: check and run both refuse, naming the pair."""
    project = _load(tmp_path, simulate_strip(16, seed=4), 'block = "strips"\npolynomial = 1\n')
    project = dataclasses.replace(project, observations=without_ties(project.observations, 6))
    report = check_project(project)
    assert any("pair 1007-1008 shares no tie point" in p for p in report.problems)
    assert "pair 1007-1008 shares no tie point" in (_run_outcome(project) or "")


def test_a_break_without_control_beyond_it_is_refused_by_check_and_run(tmp_path):
    """The models after a break carry themselves on their own control: with
    the control only before the break, check names the models as the run
    does."""
    project = _load(tmp_path, simulate_strip(16, seed=4))
    obs = without_ties(project.observations, 6)
    first = set(obs.point[obs.photo <= 5].tolist())
    control = project.control
    kinds = tuple(
        k if (k is ControlType.CHECK or obs.point_ids.index(p) in first) else ControlType.CHECK
        for p, k in zip(control.point_ids, control.kind, strict=True)
    )
    project = dataclasses.replace(
        project, observations=obs, control=dataclasses.replace(control, kind=kinds)
    )
    report = check_project(project)
    refusal = _run_outcome(project)
    assert refusal is not None and "too little control" in refusal
    assert any("pair 1007-1008" in p and "too little control" in p for p in report.problems), (
        report.problems
    )


def test_a_block_strip_without_ties_is_a_break_for_check_as_for_run(tmp_path):
    """A strip of a block with a model without tie points: check warns, the
    run takes the break (its neighbours and the control carry the models)."""
    project = _load(tmp_path, simulate_block(2, 8, seed=3, preset="drone"))
    project = dataclasses.replace(project, observations=without_ties(project.observations, 3))
    report = check_project(project)
    assert report.problems == []
    assert any("strip 'S1'" in w and "shares no tie point" in w for w in report.warnings)
    result = run_project(project)
    assert [s.breaks.tolist() for s in result.strips] == [[3], []]


def _strip_only_points(sim, k: int) -> set[str]:
    """The points seen on the photos of strip ``k`` alone."""
    obs = sim.observations
    strip_of = np.full(obs.n_photos, -1)
    for s, ids in enumerate(sim.strip_photo_ids):
        strip_of[[obs.photo_ids.index(p) for p in ids]] = s
    seen = np.zeros((obs.n_points, len(sim.strip_photo_ids)), dtype=bool)
    seen[obs.point, strip_of[obs.photo]] = True
    alone = seen[:, k] & (seen.sum(axis=1) == 1)
    return {obs.point_ids[i] for i in np.flatnonzero(alone)}


@pytest.mark.parametrize("placeable", [True, False])
def test_check_places_a_block_as_the_run_does(tmp_path, placeable):
    """A block whose control is enough in all (two plan, three height) but
    carries no strip by itself cannot be placed: the run stops, and check
    says so by the run's rule; with the control of one strip kept whole both
    accept it."""
    sim = simulate_block(3, 6, seed=2)
    project = _load(tmp_path, sim)
    control = project.control
    first, last = _strip_only_points(sim, 0), _strip_only_points(sim, 2)
    full = [p for p, k in zip(control.point_ids, control.kind, strict=True) if k.value == "full"]
    keep_first = [p for p in full if p in first][: 3 if placeable else 2]
    keep_last = [p for p in full if p in last][:2]
    assert len(keep_first) == (3 if placeable else 2) and len(keep_last) == 2
    kinds = tuple(
        ControlType.FULL
        if p in keep_first
        else ControlType.HEIGHT
        if p in keep_last
        else ControlType.CHECK
        for p in control.point_ids
    )
    project = dataclasses.replace(project, control=dataclasses.replace(control, kind=kinds))
    report = check_project(project)
    refusal = _run_outcome(project)
    if placeable:
        assert refusal is None and report.problems == []
    else:
        assert refusal is not None and "no strip has the control for its own similarity" in refusal
        assert any("no strip has the control for its own similarity" in p for p in report.problems)


def test_the_commands_agree_on_a_block_no_strip_carries(tmp_path):
    """Through the command line: ``stripaero check`` exits 1 with the line
    ``stripaero run`` stops with (a block no strip's own control places)."""
    import csv

    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    sim = simulate_block(3, 6, seed=2)
    sim.write_project(tmp_path)
    first, last = _strip_only_points(sim, 0), _strip_only_points(sim, 2)
    path = tmp_path / "control.csv"
    with path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    full_first = [r["point"] for r in rows if r["type"] == "full" and r["point"] in first][:2]
    full_last = [r["point"] for r in rows if r["type"] == "full" and r["point"] in last][:2]
    for row in rows:
        p = row["point"]
        row["type"] = "full" if p in full_first else "height" if p in full_last else "check"
        if row["type"] == "height":  # a height point gives no plan position
            row["X"] = row["Y"] = ""
    with path.open("w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    toml = tmp_path / "strip.toml"
    checked = CliRunner().invoke(cli, ["-q", "check", str(toml)])
    ran = CliRunner().invoke(cli, ["-q", "run", str(toml), "--out", str(tmp_path / "out")])
    assert (checked.exit_code, ran.exit_code) == (1, 1), (checked.output, ran.output)
    words = "no strip has the control for its own similarity"
    assert words in checked.stderr and words in ran.stderr
    assert not (tmp_path / "out").exists()
