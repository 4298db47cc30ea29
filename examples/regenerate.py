"""Rebuild the bundled example projects from the strip simulator.

Run from anywhere: ``python examples/regenerate.py``.  Each example is
simulated with a fixed seed, so the files written are the same on every run
(on the same numpy and pyproj versions); only ``strip.toml``,
``image_points.csv`` and ``control.csv`` are rewritten, the README.md of each
example is kept.
"""

from __future__ import annotations

from pathlib import Path

import strip_aerotri as sa

HERE = Path(__file__).resolve().parent

EXAMPLES = {
    "film-strip": {
        "simulation": {
            "n_photos": 12,
            "preset": "film",
            "crs": "EPSG:2180",  # Poland CS92 (transverse Mercator on GRS 80)
            "centre_lonlat": (19.0, 52.0),
            "heading_deg": 75.0,
            "seed": 2180,
            "control": "ends",
        },
        "project": {"polynomial": 3, "name": "Film strip 1:8000, 12 photos (simulated)"},
        "map_scale": 5000,
    },
    "drone-corridor": {
        "simulation": {
            "n_photos": 16,
            "preset": "drone",
            "line": True,  # a straight road along the strip: J(18) straight-line condition
            "crs": "EPSG:32634",  # WGS 84 / UTM zone 34N
            "centre_lonlat": (21.5, 50.0),
            "heading_deg": 30.0,
            "seed": 11,
            "control": "ends",
        },
        "project": {"polynomial": 3, "name": "Drone corridor along a straight road (simulated)"},
        "map_scale": 500,
    },
}


def regenerate(name: str) -> Path:
    """Simulate example ``name`` and write its project files; returns strip.toml."""
    spec = EXAMPLES[name]
    sim_args = dict(spec["simulation"])
    n_photos = sim_args.pop("n_photos")
    sim = sa.simulate_strip(n_photos, **sim_args)
    toml_path = sim.write_project(HERE / name, **spec["project"])
    with toml_path.open("a", encoding="utf-8") as fh:
        fh.write(f'\n[output]\ndirectory = "out"\n\n[report]\nmap_scale = {spec["map_scale"]}\n')
    return toml_path


def main() -> None:
    for name in EXAMPLES:
        print(f"wrote {regenerate(name)}")


if __name__ == "__main__":
    main()
