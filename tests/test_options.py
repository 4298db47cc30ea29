"""The one vocabulary of options (options.py): every default written once,
every rule in one place, the same words from the library, the loader, the
simulator and ``stripaero check``, and the options carried on every result."""

from __future__ import annotations

import ast
import json
import shutil
from pathlib import Path

import pytest

from strip_aerotri import options as opts
from strip_aerotri.errors import ConfigError
from strip_aerotri.options import (
    AdjustmentOptions,
    BlunderOptions,
    Construction,
    GroundOptions,
    OptionError,
    adjustment_options,
)

PACKAGE = Path(__file__).parents[1] / "src" / "strip_aerotri"

#: Every default of options.py and the names an option goes by in the code
#: (parameters, keywords, keys, command-line flags).
NAMES: dict[str, set[str]] = {
    "DEFAULT_MAX_ITERATIONS": {"max_iterations", "max_iter"},
    "DEFAULT_RO_TOLERANCE": {"tolerance"},
    "DEFAULT_IMAGE_SIGMA_MM": {"sigma", "sigma_mm", "sigma_left", "sigma_right"},
    "DEFAULT_SIGMA_XY_M": {"sigma_xy", "sigma_xy_m"},
    "DEFAULT_SIGMA_H_M": {"sigma_h", "sigma_h_m"},
    "DEFAULT_LINE_WEIGHT": {"weight", "line_weight"},
    "DEFAULT_POLYNOMIAL": {"polynomial"},
    "DEFAULT_BLOCK_POLYNOMIAL": {"polynomial"},
    "DEFAULT_SECTIONS": {"sections"},
    "DEFAULT_PHOTO_STEP": {"photo_step"},
    "DEFAULT_MIN_BASE_TO_HEIGHT": {"min_base_to_height"},
    "DEFAULT_GNSS_SIGMA_XY_M": {"sigma_xy", "gnss_sigma_xy"},
    "DEFAULT_GNSS_SIGMA_Z_M": {"sigma_z", "gnss_sigma_z"},
    "DEFAULT_IMU_SIGMA_DEG": {"sigma_deg", "imu_sigma_deg"},
    "DEFAULT_ALPHA": {"alpha"},
    "DEFAULT_MAX_FRACTION": {"max_fraction"},
    "DEFAULT_SCALE_TOLERANCE": {"scale_tolerance"},
    "DEFAULT_DIFFERENCE_TOLERANCE": {"difference_tolerance"},
    "DEFAULT_DUPLICATE_TOL_MM": {"duplicate_tol_mm"},
}


def _name(text: str) -> str:
    """``--sigma-mm`` and ``sigma_mm`` alike."""
    return text.lstrip("-").replace("-", "_")


def _literal(node: ast.AST | None) -> object:
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        if not isinstance(node.value, bool):
            return node.value
    return None


def _written(source: str, names: set[str], value: object) -> list[int]:
    """Lines where ``value`` is written as the default of an option called one
    of ``names``: a parameter's default, a dataclass field, an assignment, a
    keyword argument, or a call naming the option in a string
    (``getattr(x, "name", value)``, ``KeySpec(..., "name", default=value)``,
    ``click.option("--name", default=value)``)."""
    found = []

    def same(node: ast.AST | None) -> bool:
        lit = _literal(node)
        return lit is not None and type(lit) is type(value) and lit == value

    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            args = node.args
            positional = args.posonlyargs + args.args
            pairs = list(zip(positional[len(positional) - len(args.defaults) :], args.defaults))
            pairs += [(a, d) for a, d in zip(args.kwonlyargs, args.kw_defaults) if d is not None]
            found += [d.lineno for a, d in pairs if _name(a.arg) in names and same(d)]
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            if _name(node.target.id).lower() in names and same(node.value):
                found.append(node.lineno)
        elif isinstance(node, ast.Assign):
            targets = [t.id.lower() for t in node.targets if isinstance(t, ast.Name)]
            if any(_name(t) in names for t in targets) and same(node.value):
                found.append(node.lineno)
        elif isinstance(node, ast.Call):
            found += [k.value.lineno for k in node.keywords if k.arg in names and same(k.value)]
            strings = {
                _name(a.value)
                for a in node.args
                if isinstance(a, ast.Constant) and isinstance(a.value, str)
            }
            values = [*node.args, *(k.value for k in node.keywords)]
            if strings & names and any(same(v) for v in values):
                found.append(node.lineno)
    return sorted(set(found))


def _occurrences(constant: str) -> list[str]:
    value = getattr(opts, constant)
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        lines = _written(path.read_text(encoding="utf-8"), NAMES[constant], value)
        out += [f"{path.relative_to(PACKAGE)}:{line}" for line in lines]
    return out


def test_every_default_has_its_names():
    defaults = {n for n in vars(opts) if n.startswith("DEFAULT_")}
    assert defaults == set(NAMES)


@pytest.mark.parametrize("constant", sorted(NAMES))
def test_each_default_is_written_once(constant):
    """The default's literal appears once in the source: in options.py."""
    source = (PACKAGE / "options.py").read_text(encoding="utf-8")
    tree = ast.parse(source)
    defined = [
        n.lineno
        for n in tree.body
        if isinstance(n, ast.Assign)
        and any(isinstance(t, ast.Name) and t.id == constant for t in n.targets)
    ]
    assert len(defined) == 1
    assert _occurrences(constant) == []


@pytest.mark.parametrize(
    "source",
    [
        "def f(x, *, sigma=0.005):\n    pass\n",
        "def f(x, alpha=0.001):\n    pass\n",
        "y = getattr(p, 'min_base_to_height', 0.3)\n",
        "y = g(max_iterations=50)\n",
        "KeySpec('blunders', 'max_fraction', default=0.2)\n",
        "click.option('--sigma-mm', default=0.005)\n",
    ],
)
def test_the_default_search_can_fail(source):
    hits = [
        constant
        for constant, names in NAMES.items()
        if _written(source, names, getattr(opts, constant))
    ]
    assert hits, source


# --------------------------------------------------------------------------- rules


@pytest.mark.parametrize(
    ("given", "block", "key", "words"),
    [
        ({"polynomial": 4}, False, "polynomial", 'expected 0, 1, 2, 3 or "auto"'),
        ({"sections": 0}, False, "sections", "expected a positive integer"),
        ({"sections": 2, "polynomial": 0}, False, "sections", "need a polynomial type"),
        ({"polynomial": 2, "block": "models"}, False, "polynomial", 'with block = "models"'),
        ({"sections": 2, "block": "models"}, False, "sections", 'with block = "models"'),
        (
            {"models": "independent", "relative_orientation": "dependent"},
            False,
            "relative_orientation",
            "independent models do not",
        ),
        ({"photo_step": 0}, False, "photo_step", 'a positive integer or "auto"'),
        ({"photo_step": 2}, True, "photo_step", "a block forms its models on every photo"),
        ({"polynomial": "auto", "block": "strips"}, True, "polynomial", "strips share"),
        ({"polynomial": 2}, True, "polynomial", 'with block = "models"'),
        ({"sections": 2, "block": "strips"}, True, "sections", "a block has no sections"),
        ({"max_iterations": True}, False, "max_iterations", "positive integer"),
        ({"min_base_to_height": -1.0}, False, "min_base_to_height", "positive finite"),
        ({"refine": "twice"}, False, "refine", '"none", "bundle"'),
        ({"colour": 1}, False, "colour", "unknown option"),
    ],
)
def test_adjustment_rules(given, block, key, words):
    with pytest.raises(OptionError) as caught:
        adjustment_options(given, block=block)
    assert caught.value.key == key
    assert words in str(caught.value)


def test_adjustment_defaults():
    strip = adjustment_options({})
    assert strip == AdjustmentOptions()
    assert adjustment_options({"polynomial": 2}).block is Construction.STRIPS
    block = adjustment_options({"block": "strips"}, block=True)
    assert block.polynomial == opts.DEFAULT_BLOCK_POLYNOMIAL
    assert adjustment_options({}, block=True).polynomial == 0


DATA = Path(__file__).parent / "data"


def test_library_refuses_in_the_loader_words(tmp_path):
    """GroundOptions and the loader refuse polynomial with models alike."""
    from strip_aerotri.project import load_project

    with pytest.raises(OptionError) as library:
        GroundOptions(polynomial=2, construction="models")
    shutil.copytree(DATA / "minimal", tmp_path / "p")
    toml = tmp_path / "p" / "strip.toml"
    text = toml.read_text(encoding="utf-8") + '\n[adjustment]\nblock = "models"\npolynomial = 2\n'
    toml.write_text(text, encoding="utf-8")

    with pytest.raises(ConfigError) as loader:
        load_project(toml)
    assert str(loader.value) == f"{toml}: [adjustment] {library.value}"


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"alpha": 1.0}, "alpha"),
        ({"alpha": 0.0}, "alpha"),
        ({"max_fraction": 1.5}, "max_fraction"),
        ({"critical_values": {"bundle": -1.0}}, "bundle"),
        ({"critical_values": {"nowhere": 3.0}}, "nowhere"),
        ({"exclude_observations": ("p1-x",)}, "exclude_observations"),
    ],
)
def test_blunder_rules(kwargs, key):
    with pytest.raises(OptionError) as caught:
        BlunderOptions(**kwargs)
    assert caught.value.key == key


def test_blunder_pairs_from_text_or_tuples():
    assert BlunderOptions(exclude_observations=("a/b",)).exclude_observations == (("a", "b"),)
    assert BlunderOptions(exclude_observations=(("a", "b"),)).exclude_observations == (
        ("a", "b"),
    )


# --------------------------------------------------------------------------- results


def _written_project(tmp_path: Path, sim, name: str, **adjustment: object) -> Path:
    folder = tmp_path / name
    sim.write_project(folder, **adjustment)
    return folder / "strip.toml"


def test_results_carry_their_options_and_report_them_alike(tmp_path):
    """A strip's and a block's report.json write ``options`` from the result,
    with the same keys in the same order; ``photo_step = "auto"`` is the
    step the run chose."""
    from strip_aerotri.project import load_project, run_project
    from strip_aerotri.report.block import build_block_report
    from strip_aerotri.report.record import build_report
    from strip_aerotri.simulate import simulate_block, simulate_strip

    strip_sim = simulate_strip(12, preset="drone", forward_overlap=0.9, seed=1, crs="local")
    toml = _written_project(tmp_path, strip_sim, "strip")
    text = toml.read_text(encoding="utf-8") + 'photo_step = "auto"\nrefine = "bundle"\n'
    toml.write_text(text, encoding="utf-8")
    project = load_project(toml)
    assert project.adjustment.photo_step == "auto"
    strip = run_project(project)
    assert strip.options is not None
    assert strip.options.photo_step == strip.strip.photo_step > 1
    assert strip.options.refine.value == "bundle"
    record = json.loads(json.dumps(build_report(strip, project=project)))["options"]
    assert record["photo_step"] == strip.strip.photo_step
    assert record["refine"] == "bundle"

    block_sim = simulate_block(2, 5, seed=2, crs="local")
    project = load_project(_written_project(tmp_path, block_sim, "block"))
    block = run_project(project)
    assert block.options == project.adjustment
    block_record = json.loads(json.dumps(build_block_report(block, project=project)))["options"]
    assert list(block_record) == list(record)
    assert block_record["photo_step"] == 1 and block_record["refine"] == "none"


def test_check_forms_the_strip_as_the_run_does(tmp_path, monkeypatch):
    """``check_project`` and ``run_project`` call one formation
    (:func:`strip_aerotri.pipeline.form_strip_of`) with the project's options."""
    from strip_aerotri import pipeline
    from strip_aerotri.project import check_project, load_project, run_project
    from strip_aerotri.simulate import simulate_strip

    project = load_project(_written_project(tmp_path, simulate_strip(6, seed=3), "s"))
    seen = []
    real = pipeline.form_strip_of

    def spy(observations, options, **kwargs):
        seen.append(options)
        return real(observations, options, **kwargs)

    monkeypatch.setattr(pipeline, "form_strip_of", spy)
    check_project(project)
    run_project(project)
    assert seen == [project.adjustment, project.adjustment]


def _road_and_one_height(tmp_path: Path, sim, extra: str | None) -> Path:
    """The corridor's road points as full control (all in one vertical plane)
    and the height of one other point ``extra``."""
    road = sim.lines[0][0]
    index = {p: i for i, p in enumerate(sim.observations.point_ids)}
    truth = sim.truth.points_crs
    folder = tmp_path / (extra or "road")
    toml = sim.write_project(folder, polynomial=0)
    rows = ["point,X,Y,H,type"]
    rows += [
        f"{p},{truth[index[p], 0]:.4f},{truth[index[p], 1]:.4f},{truth[index[p], 2]:.4f},full"
        for p in road
    ]
    if extra is not None:
        rows.append(f"{extra},,,{truth[index[extra], 2]:.4f},height")
    (folder / "control.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    text = toml.read_text(encoding="utf-8")
    start = text.index("[[straight_line]]")
    toml.write_text(text[:start] + text[text.index("[adjustment]") :], encoding="utf-8")
    return toml


def test_check_judges_height_control_in_one_plane_as_the_run(tmp_path):
    """Road control plus the height of one point at 0 to 900 m off the road:
    ``check`` finds what ``run`` finds (an error, a warning or nothing),
    because both apply the similarity's rule to the formed strip.  Before,
    the check judged from the control's coordinates with its own margin and
    missed the run's warning at 52 m (P0049)."""
    import warnings as _warnings

    from strip_aerotri.errors import StripAerotriError
    from strip_aerotri.project import check_project, load_project, run_project
    from strip_aerotri.simulate import simulate_strip

    sim = simulate_strip(6, preset="corridor", crs="EPSG:32634", seed=4)
    verdicts = []
    for extra in (None, "P0049", "P0019", "P0055"):  # the road alone; 52, 229, 847 m off
        project = load_project(_road_and_one_height(tmp_path, sim, extra))
        report = check_project(project)
        check = (
            "error"
            if any("vertical plane" in p for p in report.problems)
            else "warning"
            if any("vertical plane" in w for w in report.warnings)
            else "none"
        )
        try:
            with _warnings.catch_warnings(record=True) as caught:
                _warnings.simplefilter("always")
                run_project(project)
            said = [str(w.message) for w in caught]
            run = "warning" if any("vertical plane" in s for s in said) else "none"
        except StripAerotriError as exc:
            run = "error" if "vertical plane" in str(exc) else f"other: {exc}"
        verdicts.append((extra, check, run))
    assert [v[1] for v in verdicts] == [v[2] for v in verdicts], verdicts
    assert [v[2] for v in verdicts] == ["error", "warning", "none", "none"], verdicts
