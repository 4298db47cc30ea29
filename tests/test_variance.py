"""Variance components of the bundle's observation groups (bundle/variance.py).

A simulated film strip (crs "local", the simulator's truth as start) with
noise of our own, different in each group and unlike the stated sigmas: the
estimates must recover the true sigmas within three of their own standard
deviations (sigma_hat / sigma is about N(1, 1 / (2 r)) for a group of
redundancy r), and the groups' redundancies must add up to the adjustment's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from strip_aerotri.blunders import BlunderOptions
from strip_aerotri.bundle.variance import (
    CONTROL_HEIGHT,
    CONTROL_PLAN,
    IMAGE_MARKS,
    IMAGE_TIES,
    MIN_REDUNDANCY,
    _Sigmas,
    group_statistics,
    refine_frame_weighted,
)
from strip_aerotri.observations import ControlType
from strip_aerotri.simulate import simulate_strip

#: The true sigmas of the groups: tie rays, control marks (mm), control plan
#: and height (m); stated as 5 µm and 1 cm / 1 cm.
TRUE = {IMAGE_TIES: 0.002, IMAGE_MARKS: 0.006, CONTROL_PLAN: 0.04, CONTROL_HEIGHT: 0.08}
STATED_IMAGE_MM, STATED_CONTROL_M = 0.005, 0.01


def _problem(seed: int = 5):
    """Observations with the groups' noise, control (P, 3) with its noise, the
    start (truth) and the stated sigmas."""
    sim = simulate_strip(
        14, seed=seed, crs="local", control="dense", image_noise_mm=0.0, control_noise_m=0.0
    )
    obs, truth, c = sim.observations, sim.truth, sim.control
    rng = np.random.default_rng(seed)
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    full = [i for i, k in enumerate(c.kind) if k is ControlType.FULL]
    idx = np.array([lookup[c.point_ids[i]] for i in full])
    p = obs.n_points
    control = np.full((p, 3), np.nan)
    control[idx] = truth.points_local[idx] + rng.normal(size=(idx.size, 3)) * [
        TRUE[CONTROL_PLAN],
        TRUE[CONTROL_PLAN],
        TRUE[CONTROL_HEIGHT],
    ]
    marks = np.isin(obs.point, idx)
    noise = np.where(marks, TRUE[IMAGE_MARKS], TRUE[IMAGE_TIES])[:, None]
    xy = obs.xy + rng.normal(size=obs.xy.shape) * noise
    observed = dataclasses.replace(obs, xy=xy, sigma=np.full(obs.photo.size, STATED_IMAGE_MM))
    sigma_c = np.where(np.isfinite(control), STATED_CONTROL_M, np.inf)
    start = (truth.photo_centres_local, truth.photo_rotations_local, truth.points_local)
    return observed, control, sigma_c, start


@pytest.fixture(scope="module")
def weighted():
    obs, control, sigma_c, start = _problem()
    fr = refine_frame_weighted(
        obs,
        *start,
        control_xyz=control,
        control_sigma=sigma_c,
        blunders=BlunderOptions(action="off"),
        variance_components=True,
    )
    return obs, fr


def test_groups_recover_their_true_sigmas(weighted):
    _, fr = weighted
    vc = fr.variance_components
    assert vc is not None and vc.converged and vc.applied
    groups = {g.name: g for g in vc.groups}
    assert set(groups) == set(TRUE)
    for name, true in TRUE.items():
        g = groups[name]
        assert g.estimated and g.redundancy >= MIN_REDUNDANCY
        scale = 1000.0 if g.unit == "µm" else 1.0
        rel = g.sigma / (true * scale)
        assert abs(rel - 1.0) < 3.0 / np.sqrt(2.0 * g.redundancy), (name, g)
        # and far from the stated sigma: the test can fail
        stated = (STATED_IMAGE_MM if g.unit == "µm" else STATED_CONTROL_M) * scale
        assert abs(g.sigma / stated - 1.0) > 0.15, (name, g)
    # at the estimated weights the adjustment's sigma0 is 1
    assert fr.sigma0 == pytest.approx(1.0, abs=0.03)


def test_the_groups_split_the_redundancy_and_the_sum_of_squares(weighted):
    obs, fr = weighted
    bundle = fr.bundle
    vc = fr.variance_components
    groups = {g.name: g for g in vc.groups}
    # the last adjustment's sigmas: the stated ones times the estimate's ratio
    image = np.where(
        np.any(fr.control_used, axis=1)[obs.point],
        groups[IMAGE_MARKS].sigma / 1000.0,
        groups[IMAGE_TIES].sigma / 1000.0,
    )
    control = np.where(
        np.isfinite(np.where(fr.control_used, 1.0, np.nan)),
        [groups[CONTROL_PLAN].sigma, groups[CONTROL_PLAN].sigma, groups[CONTROL_HEIGHT].sigma],
        np.inf,
    )
    stats = group_statistics(fr, obs.point, _Sigmas(image, control, None, None))
    assert sum(s.r for s in stats.values()) == pytest.approx(bundle.redundancy, rel=1e-6)
    vpv = sum(s.vpv for s in stats.values())
    assert vpv == pytest.approx(bundle.sigma0**2 * bundle.redundancy, rel=1e-6)


def test_given_weights_change_nothing():
    obs, control, sigma_c, start = _problem(seed=6)
    kwargs = dict(control_xyz=control, control_sigma=sigma_c, blunders=BlunderOptions())
    plain = refine_frame_weighted(obs, *start, **kwargs)
    assert plain.variance_components is None
    from strip_aerotri.bundle.snooping import refine_frame

    direct = refine_frame(obs, *start, **kwargs)
    np.testing.assert_array_equal(plain.points, direct.points)


def test_estimated_only_reports_without_moving_the_solution():
    obs, control, sigma_c, start = _problem(seed=7)
    kwargs = dict(
        control_xyz=control, control_sigma=sigma_c, blunders=BlunderOptions(action="off")
    )
    estimated = refine_frame_weighted(obs, *start, variance_components=True, apply=False, **kwargs)
    given = refine_frame_weighted(obs, *start, **kwargs)
    np.testing.assert_allclose(estimated.points, given.points, atol=1e-9)
    vc = estimated.variance_components
    assert vc is not None and not vc.applied and vc.iterations == 0
    ties = {g.name: g for g in vc.groups}[IMAGE_TIES]
    # one step from the stated 5 µm moves most of the way to the true 2 µm (the
    # control, stated far too precise, still bends the rays: iterating ends it)
    assert TRUE[IMAGE_TIES] * 1000.0 < ties.sigma < 0.6 * STATED_IMAGE_MM * 1000.0


def test_report_gives_every_group_and_the_page_its_section(tmp_path):
    """``weights = "estimated"`` on a strip project: report.json's
    ``bundle.variance_components`` lists the groups with their given and
    estimated sigmas and redundancies (adding up to the adjustment's), and
    the page has the section; without the key neither appears."""
    import json
    import re
    import warnings

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.project import load_project
    from strip_aerotri.project.run import run_project
    from strip_aerotri.report.outputs import build_outputs
    from strip_aerotri.simulate.writer import write_strip_project

    sim = simulate_strip(10, seed=2, crs="local", control="dense")
    toml = write_strip_project(tmp_path / "a", sim.observations, sim.control, sim.crs, name="a")
    plain = toml.read_text()
    pages = {}
    for label, extra in (("given", ""), ("estimated", 'weights = "estimated"\n')):
        toml.write_text(
            re.sub(r"\[adjustment\]\n", f'[adjustment]\nrefine = "bundle"\n{extra}', plain)
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StripAerotriWarning)
            project = load_project(toml)
            result = run_project(project)
            pages[label] = (result, build_outputs(result, project=project, html=True))
    result, files = pages["estimated"]
    record = json.loads(files["report.json"])["bundle"]["variance_components"]
    names = [g["group"] for g in record["groups"]]
    assert names == [IMAGE_TIES, IMAGE_MARKS, CONTROL_PLAN, CONTROL_HEIGHT]
    assert record["applied"] and record["converged"]
    total = sum(g["redundancy"] for g in record["groups"])
    assert total == pytest.approx(result.refined.redundancy, rel=1e-6)
    ties = record["groups"][0]
    assert ties["unit"] == "µm" and ties["sigma_apriori"] == pytest.approx(5.0)
    # the control heights of this strip (stated 2 cm, true 2 cm) have almost no
    # redundancy beside their rays: held at their given sigma, not estimated
    height = record["groups"][3]
    assert not height["estimated"] and height["redundancy"] < MIN_REDUNDANCY
    assert height["sigma"] == pytest.approx(height["sigma_apriori"])
    assert "Observation weights from the data" in files["report.html"].decode()
    _, given_files = pages["given"]
    assert "variance_components" not in json.loads(given_files["report.json"])["bundle"]
    assert "Observation weights" not in given_files["report.html"].decode()


def test_weights_need_the_bundle():
    from strip_aerotri.options import OptionError, adjustment_options

    with pytest.raises(OptionError, match='refine = "bundle"'):
        adjustment_options({"weights": "estimated"})
    with pytest.raises(OptionError, match="estimated"):
        adjustment_options({"weights": "guessed", "refine": "bundle"})
    assert adjustment_options({"weights": "Estimated", "refine": "bundle"}).weights == "estimated"


def test_gnss_group_of_a_block_is_estimated():
    """A drone block with control at its corners and GNSS centres whose noise
    (6 cm in plan and height) is three times the stated 2 cm: the block's
    refinement estimates the GNSS group within three of its standard
    deviations of the truth, and the block's result carries the record."""
    from strip_aerotri.block.strips import adjust_block
    from strip_aerotri.bundle.variance import GNSS
    from strip_aerotri.observations import GnssCentres, StripSpec
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(3, 10, preset="drone", side_overlap=0.4, seed=4, control="corners")
    truth = sim.truth.photo_centres_crs
    noise = np.random.default_rng(3).normal(0.0, 0.06, truth.shape)
    gnss = GnssCentres(
        sim.observations.photo_ids,
        truth + noise,
        np.full(len(truth), 0.02),
        np.full(len(truth), 0.02),
    )
    specs = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    result = adjust_block(
        sim.observations, sim.control, sim.crs, specs, refine=True, gnss=gnss,
        variance_components=True,
    )  # fmt: skip
    vc = result.variance_components
    assert vc is not None and vc.converged
    g = {x.name: x for x in vc.groups}[GNSS]
    assert g.n == 3 * len(truth) and g.estimated and g.sigma_apriori == pytest.approx(0.02)
    assert abs(g.sigma / 0.06 - 1.0) < 3.0 / np.sqrt(2.0 * g.redundancy), g
    plain = adjust_block(sim.observations, sim.control, sim.crs, specs, refine=True, gnss=gnss)
    assert plain.variance_components is None
    # the block's report.json and page carry them too
    import json

    from strip_aerotri.report.block import block_outputs, build_block_report

    files = block_outputs(result, build_block_report(result))
    record = json.loads(files["report.json"])["bundle"]["variance_components"]
    assert [g["group"] for g in record["groups"]][-1] == GNSS
    assert "Observation weights from the data" in files["report.html"].decode()


def test_a_control_blunder_is_still_found_and_leaves_the_estimate():
    """The strip of the first test with 1 m added to one control height: the
    weights' first estimate (robust, untested) does not let it inflate the
    control heights' sigma, the tests then reject it, and the heights'
    estimate stays within three of its standard deviations of the true 8 cm."""
    obs, control, sigma_c, start = _problem()
    rows = np.flatnonzero(np.isfinite(control[:, 2]))
    bad = int(rows[rows.size // 2])
    control[bad, 2] += 1.0
    fr = refine_frame_weighted(
        obs,
        *start,
        control_xyz=control,
        control_sigma=sigma_c,
        blunders=BlunderOptions(),
        variance_components=True,
    )
    rejected = [(r.point, r.component) for r in fr.rejections if r.stage == "control"]
    assert rejected == [(obs.point_ids[bad], "height")]
    g = {x.name: x for x in fr.variance_components.groups}[CONTROL_HEIGHT]
    assert abs(g.sigma / TRUE[CONTROL_HEIGHT] - 1.0) < 3.0 / np.sqrt(2.0 * g.redundancy), g


def test_groups_of_the_callers_own_recover_their_sigmas():
    """``image_groups`` names the groups of the image observations: the tie
    rays of the first and the second half of the strip with 2 and 4 µm of
    noise (stated 5 µm), the control marks with 6 µm; each estimate within
    three of its standard deviations."""
    _, control, sigma_c, start = _problem()
    clean = simulate_strip(
        14, seed=5, crs="local", control="dense", image_noise_mm=0.0, control_noise_m=0.0
    ).observations  # the observations of _problem without their noise
    half = clean.photo >= len(clean.photo_ids) // 2
    marks = np.isin(clean.point, np.flatnonzero(np.any(np.isfinite(control), axis=1)))
    true = np.where(marks, 0.006, np.where(half, 0.004, 0.002))
    xy = clean.xy + np.random.default_rng(11).normal(size=clean.xy.shape) * true[:, None]
    observed = dataclasses.replace(clean, xy=xy, sigma=np.full(clean.photo.size, STATED_IMAGE_MM))
    labels = np.where(marks, "marks", np.where(half, "ties, second half", "ties, first half"))
    fr = refine_frame_weighted(
        observed, *start, control_xyz=control, control_sigma=sigma_c,
        blunders=BlunderOptions(action="off"), variance_components=True, image_groups=labels,
    )  # fmt: skip
    vc = fr.variance_components
    assert vc is not None and vc.converged
    groups = {g.name: g for g in vc.groups}
    assert {"ties, first half", "ties, second half", "marks"} <= set(groups)
    for name, sigma_um in (("ties, first half", 2.0), ("ties, second half", 4.0), ("marks", 6.0)):
        g = groups[name]
        assert g.unit == "µm" and g.estimated
        assert abs(g.sigma / sigma_um - 1.0) < 3.0 / np.sqrt(2.0 * g.redundancy), (name, g)
    assert fr.sigma0 == pytest.approx(1.0, abs=0.03)
