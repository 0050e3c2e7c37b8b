"""Property tests over many seeds: no overlaps, objects in their zones, passable clear paths, joined crosswalks."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import shapely
from scipy import ndimage
from shapely.geometry import LineString, Polygon
from shapely.strtree import STRtree

from sim.scene import decode_walkable, generate_scene, obstacle_mask
from sim.scene.grid import rasterize

SEEDS = range(12)
CONFIGS = [
    {"blocks": 3},
    {"blocks": "SXT", "templates": "g"},
    {"blocks": "OC", "templates": "ad", "object_density": 2.0},
    # The densest: the MetaUrban-12K preset at twice its object density (rows of furniture 0.55 m apart).
    {"blocks": 3, "preset": "metaurban12k", "object_density": 2.0},
]


@pytest.fixture(scope="module")
def scenes() -> list[dict]:
    """A few dozen scenes across block mixes and templates, generated once for all property tests."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return [generate_scene(cfg, seed) for cfg in CONFIGS for seed in SEEDS]


def test_no_two_footprints_overlap(scenes: list[dict]) -> None:
    for spec in scenes:
        polys = [Polygon(o["footprint"]) for o in spec["objects"]]
        assert polys, f"seed {spec['seed']} placed no objects"
        tree = STRtree(polys)
        a, b = tree.query(polys, predicate="intersects")
        pairs = [(i, j) for i, j in zip(a, b) if i < j]
        areas = [polys[i].intersection(polys[j]).area for i, j in pairs]
        assert max(areas, default=0.0) < 1e-6, f"seed {spec['seed']}: overlapping footprints {pairs}"


def test_every_object_lies_inside_its_zone(scenes: list[dict]) -> None:
    for spec in scenes:
        zones = {
            (s["id"], z["kind"]): Polygon(z["polygon"]).buffer(1e-3) for s in spec["sidewalks"] for z in s["zones"]
        }
        for o in spec["objects"]:
            zone = zones[(o["sidewalk_id"], o["zone"])]
            assert zone.covers(Polygon(o["footprint"])), (
                f"seed {spec['seed']}: {o['id']} ({o['category']}) leaves {o['zone']}"
            )
            assert (o["category"] == "building_facade") == (o["zone"] == "building")


def test_sidewalks_and_zones_do_not_overlap_roads_or_each_other(scenes: list[dict]) -> None:
    for spec in scenes:
        roads = shapely.union_all([Polygon(r["polygon"]) for r in spec["roads"]])
        walks = [Polygon(s["polygon"]) for s in spec["sidewalks"]]
        zones = [Polygon(z["polygon"]) for s in spec["sidewalks"] for z in s["zones"]]
        assert all(p.is_valid for p in walks + zones), f"seed {spec['seed']}: invalid sidewalk or zone polygon"
        assert all(w.intersection(roads).area < 1e-2 for w in walks)
        total = sum(w.area for w in walks)
        assert abs(shapely.union_all(walks).area - total) < 1e-2 * len(walks)


def test_clear_path_is_connected_end_to_end_along_every_sidewalk(scenes: list[dict]) -> None:
    for spec in scenes:
        grid = decode_walkable(spec)
        # A 0.6 m wide agent must get through: obstacles grown by 0.3 m leave half the 1.2 m corridor.
        blocked = obstacle_mask(grid, spec["objects"], inflate=0.3)
        for sw in spec["sidewalks"]:
            own, _ = rasterize([(1, [Polygon(sw["polygon"])])], _bounds(grid), grid.resolution)
            free = (own > 0) & ~blocked
            labels, _ = ndimage.label(free)
            line = LineString(sw["clear_path"])
            ends = np.array([line.interpolate(0.5).coords[0], line.interpolate(line.length - 0.5).coords[0]])
            rc = grid.world_to_cell(ends)
            la, lb = labels[rc[0, 0], rc[0, 1]], labels[rc[1, 0], rc[1, 1]]
            assert la > 0 and la == lb, f"seed {spec['seed']}: clear path of {sw['id']} is cut"


def _bounds(grid) -> tuple[float, float, float, float]:
    x0, y0 = grid.origin
    return (x0, y0, x0 + grid.shape[1] * grid.resolution, y0 + grid.shape[0] * grid.resolution)


def test_crosswalks_join_their_sidewalks(scenes: list[dict]) -> None:
    n = 0
    for spec in scenes:
        grid = decode_walkable(spec)
        labels, _ = ndimage.label(grid.walkable)
        walks = {s["id"]: Polygon(s["polygon"]) for s in spec["sidewalks"]}
        for c in spec["crosswalks"]:
            n += 1
            poly = Polygon(c["polygon"])
            assert len(c["sidewalks"]) == 2 and len(c["ramps"]) == 2
            for sid, end in zip(c["sidewalks"], c["ends"]):
                assert poly.distance(walks[sid]) < 1e-3 and walks[sid].distance(shapely.Point(end)) < 1e-3
            for r in c["ramps"]:
                assert walks[r["sidewalk_id"]].buffer(1e-3).covers(Polygon(r["polygon"]))
            a, b = (walks[s].representative_point().coords[0] for s in c["sidewalks"])
            ra, rb = grid.world_to_cell(np.array([a, b]))
            assert labels[ra[0], ra[1]] == labels[rb[0], rb[1]] > 0, (
                f"seed {spec['seed']}: {c['id']} joins nothing on the grid"
            )
        assert (grid.mask == 2).any() == bool(spec["crosswalks"])
    assert n > 10


def test_walkable_grid_matches_surfaces(scenes: list[dict]) -> None:
    for spec in scenes[:6]:
        grid = decode_walkable(spec)
        area = float(grid.walkable.sum()) * grid.resolution**2
        expected = spec["stats"]["walkable_area_m2"]
        assert abs(area - expected) / expected < 0.05
