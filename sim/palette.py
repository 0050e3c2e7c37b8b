"""One palette for every picture of a scene: the 3D world and the top-down drawing (`sim/topdown.py`).

Colours are RGB(A) floats in [0, 1]; `rgb255` converts for PIL. Surfaces are the world's colours, so a
top-down map and a camera frame of the same street look alike.
"""

from __future__ import annotations

import numpy as np

SURFACE = {  # RGBA of the world's bodies
    "ground": (0.33, 0.36, 0.33, 1.0),
    "road": (0.22, 0.22, 0.24, 1.0),
    "sidewalk": (0.72, 0.70, 0.66, 1.0),
    "ramp": (0.85, 0.75, 0.35, 1.0),
    "crosswalk": (0.93, 0.93, 0.93, 1.0),
    "building": (0.55, 0.45, 0.40, 1.0),
}
ZONE = {  # sidewalk zones, drawn over the sidewalk in spec plots
    "near_road_buffer": (0.61, 0.80, 0.40),
    "furnishing": (0.84, 0.80, 0.78),
    "clear": (0.93, 0.93, 0.93),
    "frontage_buffer": (0.74, 0.67, 0.64),
    "frontage": (1.00, 0.88, 0.70),
    "building": SURFACE["building"][:3],
}
OBJECT_CLASS = {
    "standard": (0.08, 0.40, 0.75),
    "non_standard": (0.90, 0.32, 0.0),
    "clutter": (0.76, 0.09, 0.36),
    "building": (0.38, 0.49, 0.55),
}
OBJECT = (0.55, 0.39, 0.24)  # an object whose spec names no object class
LANE_LINE = (0.9, 0.85, 0.3)
ISLAND = (0.51, 0.78, 0.52)  # planted median islands
EDGE = (0.26, 0.26, 0.26)  # curb lines and outlines of crosswalks, zones and objects in the scene plot
CLEAR_PATH = (0.56, 0.64, 0.68)  # the dotted centre line of a sidewalk's clear path
ROUTE = (0.1, 0.8, 0.3)
TRAJECTORY = (0.12, 0.43, 1.0)
EGO = (1.0, 0.55, 0.0)
COLLISION = (1.0, 0.24, 0.24)  # the ego while it touches something
VEHICLE = (0.24, 0.24, 0.63)
OUTLINE = (0.0, 0.0, 0.0)
# Terrain surfaces (sim.terrain.wfc.SURFACES) as the runways colour their tiles (sim/terrain/runway.py).
TERRAIN = {
    "asphalt": (0.25, 0.25, 0.27),
    "concrete": (0.7, 0.7, 0.68),
    "pavers": (0.65, 0.45, 0.35),
    "grass": (0.35, 0.6, 0.3),
    "gravel": (0.55, 0.52, 0.47),
    "wet": (0.2, 0.22, 0.3),
}
ROUGH_SHADE = 0.8  # heaved or uneven ground is drawn a shade darker than its surface, so it stands out from the slab


def category_color(category: str) -> tuple[float, float, float, float]:
    """A stable colour per object category (hash-free so it is the same in every process)."""
    h = sum((i + 1) * ord(ch) for i, ch in enumerate(category))
    rng = np.random.default_rng(h)
    r, g, b = rng.uniform(0.25, 0.95, 3)
    return (float(r), float(g), float(b), 1.0)


def rgb255(c: tuple[float, ...]) -> tuple[int, int, int]:
    """The first three channels of a [0, 1] colour as 0-255 integers (PIL)."""
    return (int(255 * c[0]), int(255 * c[1]), int(255 * c[2]))


def terrain_colour(kind: str, surface: str) -> tuple[float, float, float, float]:
    """RGBA of a terrain patch (sim.terrain.patches): its surface's colour, a shade darker when rough."""
    shade = ROUGH_SHADE if kind in ("roots", "rough") else 1.0
    r, g, b = (shade * v for v in TERRAIN.get(surface, SURFACE["sidewalk"][:3]))
    return (r, g, b, 1.0)
