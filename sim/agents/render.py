"""Top-down map frames (PIL, no display): scene surfaces, objects, vehicles, and agents by kind with short trails."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from sim.agents.kinds import AGENT_KINDS
from sim.palette import EGO, OBJECT, ROUTE, SURFACE, VEHICLE, rgb255

ROAD, SIDEWALK, CROSSWALK = (rgb255(SURFACE[k]) for k in ("road", "sidewalk", "crosswalk"))
GROUND, OBJECT_RGB, VEHICLE_RGB, EGO_RGB, ROUTE_RGB = (rgb255(c) for c in (SURFACE["ground"], OBJECT, VEHICLE, EGO, ROUTE))


def draw_top_down(spec: dict[str, Any], centre: tuple[float, float], *, agents: np.ndarray | None = None,
                  trails: np.ndarray | None = None, vehicles: np.ndarray | None = None,
                  ego: tuple[float, float, float, float, float] | None = None, route: np.ndarray | None = None,
                  size: int = 256, view: float = 40.0) -> np.ndarray:
    """RGB (size, size, 3) map of a `view` x `view` m window around `centre`; ego = (x, y, yaw, length, width)."""
    scale = size / view
    cx, cy = centre

    def px(pts: np.ndarray) -> list[tuple[float, float]]:
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
        return list(zip((pts[:, 0] - cx) * scale + size / 2, size / 2 - (pts[:, 1] - cy) * scale))

    img = Image.new("RGB", (size, size), GROUND)
    d = ImageDraw.Draw(img)
    for r in spec.get("roads", []):
        d.polygon(px(r["polygon"]), fill=ROAD)
    for s in spec.get("sidewalks", []):
        d.polygon(px(s["polygon"]), fill=SIDEWALK)
    for c in spec.get("crosswalks", []):
        d.polygon(px(c["polygon"]), fill=CROSSWALK)
    for o in spec.get("objects", []):
        if o.get("footprint"):
            d.polygon(px(o["footprint"]), fill=OBJECT_RGB)
    if route is not None and len(route) > 1:
        d.line(px(route), fill=ROUTE_RGB, width=max(1, int(0.15 * scale)))
    for v in [] if vehicles is None else vehicles:
        d.polygon(px(_box(v["x"], v["y"], v["yaw"], v["length"], v["width"])), fill=VEHICLE_RGB)
    if agents is not None and len(agents):
        colours = [rgb255(AGENT_KINDS[str(k)].color) for k in agents["kind"]]
        if trails is not None:
            for i, col in enumerate(colours):
                faded = tuple(int(0.5 * c + 0.5 * 255) for c in col)
                d.line(px(trails[:, i]), fill=faded, width=max(1, int(0.12 * scale)))
        for a, col in zip(agents, colours):
            (x, y), = px(np.array([a["x"], a["y"]]))
            r = a["radius"] * scale
            d.ellipse([x - r, y - r, x + r, y + r], fill=col, outline=(0, 0, 0))
    if ego is not None:
        x, y, yaw, length, width = ego
        d.polygon(px(_box(x, y, yaw, length, width)), fill=EGO_RGB, outline=(0, 0, 0))
    return np.asarray(img)


def _box(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    corners = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * [length / 2, width / 2]
    return corners @ np.array([[c, s], [-s, c]]) + [x, y]
