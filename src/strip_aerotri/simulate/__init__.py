"""Simulated strips and blocks of vertical photos with a known truth.

:func:`simulate_strip` builds one strip, and (from the same camera, terrain
and noise model) the observations, control and true geometry come back
together; it lets users try the tool without data, and it is the ground
truth of the package's tests. docs/simulator.md describes what is modelled,
with every parameter and its unit.

Modules: :mod:`.cameras` (cameras and presets), :mod:`.strip` (one strip),
:mod:`.writer` (project files).
"""

from __future__ import annotations

# The strip control layouts, for the command line's list (tests compare them).
from ._control import _CONTROL_LAYOUTS as _CONTROL_LAYOUTS
from ._geodesy import LocalFrame
from .cameras import CAMERAS, PRESETS, Camera, StripPreset, camera_preset
from .strip import SimulatedStrip, SimulationTruth, simulate_strip

__all__ = [
    "CAMERAS",
    "PRESETS",
    "Camera",
    "LocalFrame",
    "SimulatedStrip",
    "SimulationTruth",
    "StripPreset",
    "camera_preset",
    "simulate_strip",
]
