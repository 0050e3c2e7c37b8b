"""The agents' map frame: a window of the one top-down drawing (`sim/topdown.py`) around the ego, agents by kind."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sim.agents.kinds import AGENT_KINDS
from sim.scene.scene import Scene
from sim.topdown import Canvas, draw_agents, draw_ego, draw_route, draw_scene, draw_vehicles


def draw_top_down(
    scene: Scene | Mapping[str, Any],
    centre: tuple[float, float],
    *,
    agents: np.ndarray | None = None,
    trails: np.ndarray | None = None,
    vehicles: np.ndarray | None = None,
    ego: tuple[float, float, float, float, float] | None = None,
    route: np.ndarray | None = None,
    size: int = 256,
    view: float = 40.0,
) -> np.ndarray:
    """RGB (size, size, 3) map of a `view` x `view` m window around `centre`; ego = (x, y, yaw, length, width)."""
    cx, cy = centre
    # Drawn once a step: no supersampling, so a frame costs a few milliseconds and agents keep their exact colour.
    c = Canvas((cx - view / 2, cy - view / 2, cx + view / 2, cy + view / 2), size / view)
    draw_scene(c, scene)
    if route is not None and len(route) > 1:
        draw_route(c, route, max(1.0, 0.15 * c.px_per_m))
    if vehicles is not None:
        draw_vehicles(c, vehicles)
    if agents is not None and len(agents):
        draw_agents(c, agents, [AGENT_KINDS[str(k)].color for k in agents["kind"]], trails)
    if ego is not None:
        draw_ego(c, *ego)
    return c.image()
