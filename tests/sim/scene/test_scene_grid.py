"""Walkable grid helpers: encoding round trip, world/cell conversions, obstacle masks."""

from __future__ import annotations

import numpy as np
from shapely.geometry import box

from sim.scene.grid import decode_walkable, encode_walkable, obstacle_mask, rasterize


def test_rasterize_encode_decode_round_trip() -> None:
    mask, origin = rasterize([(1, [box(0, 0, 4, 2)]), (2, [box(1, 0, 2, 2)])], (0, 0, 5, 3), 0.5)
    grid = decode_walkable({"walkable": encode_walkable(mask, origin, 0.5)})
    assert grid.shape == (6, 10)
    assert np.array_equal(grid.mask, mask)
    assert grid.mask[0, 0] == 1 and grid.mask[0, 2] == 2 and grid.mask[0, 9] == 0 and grid.mask[5, 0] == 0
    assert int((grid.mask > 0).sum()) == 8 * 4  # 4 m x 2 m at 0.5 m


def test_world_cell_conversions_are_inverse() -> None:
    mask, origin = rasterize([(1, [box(-3, -2, 3, 2)])], (-3.1, -2.1, 3.1, 2.1), 0.25)
    grid = decode_walkable({"walkable": encode_walkable(mask, origin, 0.25)})
    rc = np.array([[0, 0], [3, 7], [grid.shape[0] - 1, grid.shape[1] - 1]])
    assert np.array_equal(grid.world_to_cell(grid.cell_to_world(rc)), rc)
    assert grid.is_walkable(np.array([[0.0, 0.0], [10.0, 0.0]])).tolist() == [True, False]


def test_obstacle_mask_inflates_footprints() -> None:
    mask, origin = rasterize([(1, [box(0, 0, 10, 10)])], (0, 0, 10, 10), 0.25)
    grid = decode_walkable({"walkable": encode_walkable(mask, origin, 0.25)})
    obj = {"footprint": [[4, 4], [6, 4], [6, 6], [4, 6]]}
    bare = obstacle_mask(grid, [obj], inflate=0.0)
    grown = obstacle_mask(grid, [obj], inflate=0.5)
    assert bare.sum() == 64  # 2 m x 2 m
    assert grown.sum() > bare.sum() and grown[bare].all()
    assert not grown[grid.world_to_cell([1.0, 1.0])[0], grid.world_to_cell([1.0, 1.0])[1]]


def test_scanline_paint_matches_point_in_polygon_reference() -> None:
    from shapely.geometry import Point

    from sim.scene.grid import paint, paint_reference

    ring = Point(3.1, 2.2).buffer(2.7, quad_segs=7).difference(box(2.0, 1.0, 3.3, 2.9))  # curved, with a hole
    for poly in (ring, box(0, 0, 4, 2), Point(0.6, 0.6).buffer(0.9).union(box(0.5, 0.5, 6.3, 1.1))):
        fast, slow = np.zeros((40, 40), dtype=np.uint8), np.zeros((40, 40), dtype=np.uint8)
        paint(fast, (-1.0, -1.0), 0.25, poly, 2)
        paint_reference(slow, (-1.0, -1.0), 0.25, poly, 2)
        assert np.array_equal(fast, slow) and slow.any()


def test_obstacle_mask_covers_thin_and_hidden_objects_at_their_centroid() -> None:
    mask, origin = rasterize([(1, [box(0, 0, 10, 10)])], (0, 0, 10, 10), 0.5)
    grid = decode_walkable({"walkable": encode_walkable(mask, origin, 0.5)})
    pole = box(2.05, 2.05, 2.15, 2.15)  # thinner than a cell, between cell centres
    big, inner = box(5, 5, 8, 8), box(6, 6, 7, 7)  # inner's cells are all big's
    painted = obstacle_mask(grid, [pole, big, inner], cover_thin=False)
    covered = obstacle_mask(grid, [pole, big, inner])
    pole_cell = tuple(int(c) for c in grid.world_to_cell((2.1, 2.1)))
    assert not painted[pole_cell] and covered[pole_cell]
    assert int(painted.sum()) == 36 and int(covered.sum()) == 37  # big: 3 m x 3 m; + the pole's cell
    # Each object is judged in order against those before it: the inner box alone covers its own 4 cells.
    alone = obstacle_mask(grid, [inner])
    assert int(alone.sum()) == 4
