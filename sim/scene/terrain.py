"""Terrain patches of a generated scene (docs/terrain.md): tree-root heave beside street trees, uneven pavers, entrance
steps against buildings and slick (wet or gravel) ground, at `terrain.density` times a city's typical rate.

Placed after every object, each kind from its own random stream of the scene's seed: terrain never moves an object,
so a scene holds the same objects at any terrain density, and one kind's patches do not reshuffle another's draws.
Rough and slick ground is drivable and may cover the clear path; steps stand in the frontage zone only, against a
building, clear of the kept corridor. No patch meets an object, another patch, a curb ramp or a ramp's approach,
and every patch lies on its sidewalk's slab. `sim.terrain.patches` turns the records into geometry.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Point

from sim.scene.occupancy import GAP, Occupancy, quad_polygon, rect
from sim.scene.placement import Placer
from sim.scene.sidewalks import Sidewalk
from sim.scene.spec import round_points, round_value
from sim.terrain.patches import KINDS

STREAM = 0x7E88A1  # the patches' random streams: np.random.default_rng([seed, STREAM, kind index])
# Per kind at density 1: roots, the share of street trees that heave the walkway beside them (root damage is among
# the commonest sidewalk defects next to trees); the others, patches per 100 m of sidewalk (steps: of sidewalk
# with a frontage zone and a building). Engineering choices, documented in docs/terrain.md.
RATES = {"roots": 0.35, "rough": 2.0, "steps": 5.0, "slick": 1.0}
BUMPS = {"roots": (0.02, 0.04), "rough": (0.02, 0.03)}  # bump height range (m)
TREAD, RISE, LANDING = 0.3, (0.13, 0.17), (0.3, 0.6)  # stair tread, riser height range, landing range (m)
MIN_LANDING = 0.15
RAMP_CLEAR = 0.6  # metres kept around a curb ramp beyond its depth: its flares are cut from the slab there


def patch_record(
    pid: str,
    kind: str,
    surface: str,
    sidewalk_id: str,
    zone: str,
    x: float,
    y: float,
    z: float,
    yaw: float,
    size: tuple[float, float, float],
    **extra: Any,
) -> dict[str, Any]:
    """One terrain record as the spec stores it (0.1 mm), its footprint the rectangle of `size` at (x, y), `yaw`."""
    corners, _ = rect(x, y, math.cos(yaw), math.sin(yaw), size[0], size[1])
    rec = {
        "id": pid,
        "kind": kind,
        "surface": surface,
        "sidewalk_id": sidewalk_id,
        "zone": zone,
        "position": [round_value(x), round_value(y), round_value(z)],
        "yaw": round_value(math.atan2(math.sin(yaw), math.cos(yaw))),
        "size": [round_value(float(v)) for v in size],
        "footprint": round_points(corners),
    }
    rec.update({k: round_value(v) if isinstance(v, float) else v for k, v in extra.items()})
    return rec


class _Terrain:
    """The patches placed so far, what they must keep clear of, and the placement test."""

    def __init__(self, sidewalks: list[Sidewalk], placer: Placer, cfg: dict[str, Any]) -> None:
        self.placer, self.z = placer, round_value(float(cfg["curb_height"]))
        self.tries = max(1, int(cfg["placement_tries"]))
        self.records: list[dict[str, Any]] = []
        self.own = Occupancy()  # placed patches, and keep-outs: the ramps with their flares and their approaches
        ramp = float(cfg["ramp_depth"]) + RAMP_CLEAR
        self.own.set_keep_out(
            [r.buffer(ramp) for sw in sidewalks for r in sw.ramps] + [k for sw in sidewalks for k in sw.keep_out]
        )
        for sw in sidewalks:
            shapely.prepare(sw.polygon)

    def place(
        self,
        sw: Sidewalk,
        kind: str,
        surface: str,
        s: float,
        d: float,
        size: tuple[float, float, float],
        area: Any,
        *,
        corridor: bool,
        **extra: Any,
    ) -> bool:
        """Add a patch at road coordinates (s, d), local x pointing away from the road, if its footprint lies in
        `area`, meets no object, patch or ramp, and (with `corridor`) stays out of the kept clear-path corridor."""
        x, y, heading = sw.roadway.centerline.point_xy(s, d)
        yaw = heading + sw.side * math.pi / 2
        cos, sn = math.cos(yaw), math.sin(yaw)
        corners, pb = rect(x, y, cos, sn, size[0], size[1])
        poly = quad_polygon(corners)
        if not area.contains(poly):
            return False
        check, cb = rect(x, y, cos, sn, size[0] + GAP, size[1] + GAP)
        if not self.placer.occupied.free(poly, pb, check, cb, corridor) or not self.own.free(poly, pb, check, cb, True):
            return False
        self.own.add(check, cb)
        zone = next((z.kind for z in sw.zones if z.d0 <= abs(d) <= z.d1), "sidewalk")
        self.records.append(
            patch_record(f"t{len(self.records)}", kind, surface, sw.id, zone, x, y, self.z, yaw, size, **extra)
        )
        return True


def _count(rng: np.random.Generator, expected: float) -> int:
    """floor(expected), plus one with the probability of its fraction (Placer._count's rounding)."""
    return int(expected) + int(rng.random() < expected - int(expected))


def _lateral(sw: Sidewalk, x: float, y: float) -> tuple[float, float]:
    """Road coordinates (s, |d|) of the point (x, y) beside sidewalk `sw`'s roadway."""
    cl = sw.roadway.centerline
    s = float(cl.project(np.array([[x, y]]))[0])
    px, py, heading = cl.point_xy(s, 0.0)
    return s, abs(-(x - px) * math.sin(heading) + (y - py) * math.cos(heading))


def _roots(terrain: _Terrain, sw: Sidewalk, rng: np.random.Generator, rho: float, trees: list[dict[str, Any]]) -> None:
    """Heave beside a share of the sidewalk's trees: a rough concrete patch on the walkway side of the tree."""
    for tree in trees:
        if rng.random() >= min(1.0, RATES["roots"] * rho):
            continue
        s, d = _lateral(sw, float(tree["position"][0]), float(tree["position"][1]))
        half = 0.5 * max(float(tree["size"][0]), float(tree["size"][1]))
        depth, width = float(rng.uniform(0.8, 1.5)), float(rng.uniform(1.5, 3.0))
        size = (depth, width, float(rng.uniform(*BUMPS["roots"])))
        seed = int(rng.integers(2**31))
        for k in range(terrain.tries):  # smaller each try, until it fits beside the tree's neighbours
            scale = 1.0 - 0.25 * min(k, 2)
            sz = (size[0] * scale, size[1] * scale, size[2])
            if terrain.place(
                sw,
                "roots",
                "concrete",
                s + float(rng.uniform(-0.3, 0.3)),
                sw.side * (d + half + 0.05 + 0.5 * sz[0]),
                sz,
                sw.polygon,
                corridor=False,
                seed=seed,
            ):
                break


def _anywhere(terrain: _Terrain, sw: Sidewalk, rng: np.random.Generator, rho: float, kind: str) -> None:
    """Uneven pavers (`rough`) or slick ground (`slick`: wet or gravel) at random spots of the sidewalk."""
    s0, s1 = sw.s_range
    lo = sw.roadway.half_width + 0.05
    for _ in range(_count(rng, RATES[kind] * rho * (s1 - s0) / 100.0)):
        depth, width = float(rng.uniform(0.8, 2.0)), float(rng.uniform(1.0, 2.5 if kind == "rough" else 3.0))
        if kind == "rough":
            surface, height, extra = "pavers", float(rng.uniform(*BUMPS["rough"])), {"seed": int(rng.integers(2**31))}
        else:
            surface, height, extra = ("wet" if rng.random() < 0.6 else "gravel"), 0.0, {}
        for _ in range(terrain.tries):
            d = float(rng.uniform(lo + 0.5 * depth, max(sw.outer - 0.05 - 0.5 * depth, lo + 0.5 * depth)))
            s = float(rng.uniform(s0 + 0.5 * width, max(s1 - 0.5 * width, s0 + 0.5 * width)))
            if terrain.place(
                sw, kind, surface, s, sw.side * d, (depth, width, height), sw.polygon, corridor=False, **extra
            ):
                break


def _steps(terrain: _Terrain, sw: Sidewalk, rng: np.random.Generator, rho: float) -> None:
    """Entrance stairs of 1-3 steps in the frontage zone, rising to the building line with a landing there."""
    zone = sw.zone("frontage")
    if zone is None or sw.building is None:
        return
    area = terrain.placer.zone_shape(zone)[0]
    s0, s1 = sw.s_range
    for _ in range(_count(rng, RATES["steps"] * rho * (s1 - s0) / 100.0)):
        n_steps, rise, width = int(rng.integers(1, 4)), float(rng.uniform(*RISE)), float(rng.uniform(1.5, 3.0))
        landing = float(rng.uniform(*LANDING))
        while n_steps > 0 and zone.width - 0.05 - n_steps * TREAD < MIN_LANDING:
            n_steps -= 1
        if n_steps == 0:
            return  # the zone is too shallow for a stair
        landing = min(landing, zone.width - 0.05 - n_steps * TREAD)
        depth = n_steps * TREAD + landing
        d = zone.d1 - 0.01 - 0.5 * depth
        for _ in range(terrain.tries):
            s = float(rng.uniform(s0 + 0.5 * width, max(s1 - 0.5 * width, s0 + 0.5 * width)))
            x, y, _ = sw.roadway.centerline.point_xy(s, sw.side * (zone.d1 + 0.3))
            if not sw.building.polygon.contains(Point(x, y)):
                continue  # no building beyond this spot: a stair would lead nowhere
            if terrain.place(
                sw,
                "steps",
                "concrete",
                s,
                sw.side * d,
                (depth, width, n_steps * rise),
                area,
                corridor=True,
                steps=n_steps,
                tread=TREAD,
            ):
                break


def place_terrain(sidewalks: list[Sidewalk], placer: Placer, cfg: dict[str, Any], seed: int) -> list[dict[str, Any]]:
    """The scene's terrain records (docs/scene_spec.md), placed around `placer`'s objects; none at density 0."""
    rho = float(cfg["terrain"]["density"])
    kinds = cfg["terrain"]["kinds"]
    terrain = _Terrain(sidewalks, placer, cfg)
    if rho <= 0 or not kinds:
        return terrain.records
    trees: dict[str, list[dict[str, Any]]] = {}
    for obj in placer.objects:
        if obj["category"] == "tree":
            trees.setdefault(obj["sidewalk_id"], []).append(obj)
    for kind in KINDS:
        if kind not in kinds:
            continue
        rng = np.random.default_rng([int(seed), STREAM, KINDS.index(kind)])
        for sw in sidewalks:
            if kind == "roots":
                _roots(terrain, sw, rng, rho, trees.get(sw.id, []))
            elif kind == "steps":
                _steps(terrain, sw, rng, rho)
            else:
                _anywhere(terrain, sw, rng, rho, kind)
    return terrain.records


def terrain_stats(records: list[dict[str, Any]]) -> dict[str, int]:
    """Patches per kind (every kind, 0 when absent)."""
    counts = Counter(rec["kind"] for rec in records)
    return {k: counts.get(k, 0) for k in KINDS}
