"""Catalog meshes as visual shapes: the textured mesh stands in its object's box, on the surface (not floating)."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from catalogs.reader import CatalogReader
from sim.world import World
from tests.street import street


def _rows_drawn(world: World, body: int, eye: list[float], target: list[float]) -> tuple[int, int, int]:
    """(top row, bottom row, pixel count) of `body` in a 160x160 segmentation render from `eye` to `target`."""
    view = p.computeViewMatrix(eye, target, [0, 0, 1])
    proj = p.computeProjectionMatrixFOV(60.0, 1.0, 0.05, 50.0)
    _, _, _, _, seg = p.getCameraImage(160, 160, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=world.client)
    rows = np.flatnonzero((np.reshape(seg, (160, 160)) == body).any(axis=1))
    return int(rows.min()), int(rows.max()), int((np.reshape(seg, (160, 160)) == body).sum())


@pytest.mark.parametrize("collision", ["box", "convex"])
def test_a_visual_mesh_fills_its_objects_box(small_catalog, collision: str) -> None:
    spec = street()
    bench = next(o for o in spec["objects"] if o["category"] == "bench")
    bench["asset_id"] = "procedural/bench/0000"
    catalog = CatalogReader(small_catalog)
    worlds = [World(spec, collision=collision, catalog=catalog, visual_meshes=v) for v in (False, True)]
    x, y, z = bench["position"]
    # Looking at the bench's long side from 3 m, level with its middle.
    side = bench["yaw"] + math.pi / 2
    eye = [x + 3.0 * math.cos(side), y + 3.0 * math.sin(side), z + 0.45]
    boxed, meshed = (_rows_drawn(w, w.object_ids[spec["objects"].index(bench)], eye, [x, y, z + 0.45]) for w in worlds)
    assert abs(boxed[0] - meshed[0]) <= 3 and abs(boxed[1] - meshed[1]) <= 2  # same top and bottom: in the box
    assert meshed[2] < boxed[2]  # a bench (legs, slats) covers less than its box
    ids = p.getVisualShapeData(worlds[1].object_ids[spec["objects"].index(bench)], physicsClientId=worlds[1].client)
    assert ids[0][2] == p.GEOM_MESH and ids[0][4].decode().endswith("model.obj")  # the textured mesh, not the hull
    for w in worlds:
        w.close()
