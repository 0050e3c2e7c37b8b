"""Where the crowd spawns and how many: spawn areas, sidewalk length, drawing kinds and placing agents."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from kernel.config import ConfigError
from sim.agents.kinds import KIND_NAMES
from sim.agents.navgrid import NavGrid
from sim.scene.scene import Scene, as_scene

SPAWN_AREAS = ("sidewalks", "intersections", "route")


def spawn_region(scene: Scene, config: Mapping[str, Any], route: np.ndarray | None) -> Any:
    """The polygon agents spawn in (None: every sidewalk): around intersections, or along the ego's route."""
    from shapely.geometry import LineString, Polygon
    from shapely.ops import unary_union

    area = config["spawn_area"]
    if area == "sidewalks":
        return None
    if area == "intersections":
        roads = [Polygon(r["polygon"]) for r in scene.roads if r.get("block") in ("X", "T", "O")]
        return unary_union(roads).buffer(float(config["intersection_margin"])) if roads else Polygon()
    if route is None or len(route) < 2:
        raise ConfigError("agents spawn_area 'route' needs the ego's route (SocialNav passes it at reset)")
    return LineString(np.asarray(route)[:, :2]).buffer(float(config["route_band"]))


def sidewalk_length(scene: Scene | Mapping[str, Any]) -> float:
    """Total sidewalk length in metres (clear-path polylines, else curb edges) used by dynamic_density."""
    total = 0.0
    for sw in as_scene(scene).sidewalks:
        line = np.asarray(sw.get("clear_path") or sw.get("edge") or [], dtype=np.float64)
        if len(line) >= 2:
            total += float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum())
    return total


def draw_kinds(
    scene: Scene, config: Mapping[str, Any], area: Any, route_length: float, rng: np.random.Generator
) -> list[str]:
    """The kinds of this episode's agents: the config's counts, else the scene's own, else drawn by density.

    `area` is spawn_region's polygon (None: every sidewalk) and `route_length` the ego's route in metres, the
    lengths a density scales with.
    """
    c = config
    # Explicit counts win, then the scene's own agent groups (a custom scene's `agents`), then the density.
    counts = c["counts"] or scene.spec.get("agents") or {}
    if counts:
        kinds = [k for k in KIND_NAMES for _ in range(int(counts.get(k, 0)))]
    else:
        n = int(round(c["dynamic_density"] * area_length(scene, config, area, route_length) / 100.0))
        names = list(c["mix"])
        p = np.array([c["mix"][k] for k in names], dtype=np.float64)
        kinds = list(rng.choice(names, size=n, p=p / p.sum())) if n else []
    if len(kinds) > c["max_agents"]:
        raise ConfigError(
            f"{len(kinds)} agents requested but max_agents is {c['max_agents']}; "
            "lower dynamic_density/counts or raise max_agents"
        )
    return [str(k) for k in kinds]


def area_length(scene: Scene, config: Mapping[str, Any], area: Any, route_length: float) -> float:
    """Metres of sidewalk (or route) the spawn count scales with: dynamic_density agents per 100 m of it."""
    if area is None:
        return sidewalk_length(scene)
    if config["spawn_area"] == "route":
        return float(route_length)
    from shapely.geometry import LineString

    total = 0.0
    for sw in scene.sidewalks:
        line = sw.get("clear_path") or sw.get("edge") or []
        if len(line) >= 2:
            total += LineString(line).intersection(area).length
    return total


def spawn_positions(
    grid: NavGrid,
    area: Any,
    radius: np.ndarray,
    config: Mapping[str, Any],
    rng: np.random.Generator,
    clear: list[tuple[float, float, float]],
) -> np.ndarray:
    """Positions [n, 2] for agents of `radius` on planning cells in `area` (None: anywhere), outside the `clear`
    discs (x, y, r) and `spawn_clearance` apart; ValueError when they do not all fit."""
    g = grid
    n = len(radius)
    cand = g.node_xy(rng.permutation(g.n_nodes))
    if area is not None:
        import shapely

        cand = cand[shapely.contains_xy(area, cand[:, 0], cand[:, 1])]
    for x, y, r in clear:
        cand = cand[np.hypot(cand[:, 0] - x, cand[:, 1] - y) > r]
    cand = cand + rng.uniform(-0.3, 0.3, cand.shape) * g.res  # off the cell centres, still in the cell
    pos = np.zeros((n, 2))
    placed, k = 0, 0
    while placed < n and k < len(cand):
        p = cand[k]
        k += 1
        if placed:
            d = np.linalg.norm(pos[:placed] - p, axis=1)
            if np.any(d < radius[:placed] + radius[placed] + config["spawn_clearance"]):
                continue
        pos[placed] = p
        placed += 1
    if placed < n:
        raise ValueError(
            f"only {placed} of {n} agents fit on this scene's walkable area; "
            "lower dynamic_density or the explicit counts"
        )
    return pos
