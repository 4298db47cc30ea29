"""Simulated strips and blocks of vertical photos with a known truth.

:func:`simulate_strip` builds one strip and :func:`simulate_block` a block of
parallel strips (same camera, terrain and noise model); the observations,
control and true geometry come back together. They let users try the tool
without data, and they are the ground truth of the package's tests.
docs/simulator.md describes what is modelled, with every parameter and its
unit.

Modules: :mod:`.cameras` (cameras and presets), :mod:`.strip` (one strip),
:mod:`.block` (blocks of strips), :mod:`.writer` (project files).
"""

from __future__ import annotations

# The strip control layouts, for the command line's list (tests compare them).
from ._control import _CONTROL_LAYOUTS as _CONTROL_LAYOUTS
from ._geodesy import LocalFrame
from .block import BlockStrip, SimulatedBlock, simulate_block
from .cameras import CAMERAS, PRESETS, Camera, StripPreset, camera_preset
from .strip import SimulatedStrip, SimulationTruth, simulate_strip

__all__ = [
    "CAMERAS",
    "PRESETS",
    "BlockStrip",
    "Camera",
    "LocalFrame",
    "SimulatedBlock",
    "SimulatedStrip",
    "SimulationTruth",
    "StripPreset",
    "camera_preset",
    "simulate_block",
    "simulate_strip",
]
