"""Hierarchical layout generation: road blocks, sidewalks and zones, crosswalks, objects -> scene spec JSON.

Public API: `generate_scene`, `DEFAULT_CONFIG`, `dumps`, `load`, `save`, `Scene` (the typed, validated view
of a spec that the simulator reads: `Scene.parse(spec)`, `Scene.load(path)`), and `sim.scene.grid`
(`decode_walkable`, `obstacle_mask`). See docs/scene_spec.md (the contract) and docs/scenes.md (the algorithm).
"""

from sim.scene.config import BLOCK_CODES, DEFAULT_CONFIG, TEMPLATES
from sim.scene.generator import generate_scene
from sim.scene.grid import WalkableGrid, decode_walkable, obstacle_mask
from sim.scene.scene import SPEC_VERSION, Scene, SceneError
from sim.scene.spec import dumps, load, save

__all__ = [
    "BLOCK_CODES",
    "DEFAULT_CONFIG",
    "SPEC_VERSION",
    "TEMPLATES",
    "Scene",
    "SceneError",
    "WalkableGrid",
    "decode_walkable",
    "dumps",
    "generate_scene",
    "load",
    "obstacle_mask",
    "save",
]
