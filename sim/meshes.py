"""Triangle meshes for PyBullet: extruded polygons (surfaces with curb walls) and a leak-free mesh-shape call."""

from __future__ import annotations

import ctypes
import sys
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

from kernel.quiet import pybullet as p

_py_decref = ctypes.pythonapi.Py_DecRef
_py_decref.argtypes = [ctypes.py_object]
_py_decref.restype = None


def mesh_shape(create: Callable[..., int], vertices: Sequence, indices: Sequence | None = None, **kwargs: Any) -> int:
    """`create(GEOM_MESH, vertices=..., indices=...)` (p.createCollisionShape/createVisualShape) without its leak.

    pybullet (3.2.7 and earlier) reads `vertices` and `indices` through new references it never releases: two
    extra references to the vertex list, to every vertex in it and to the index list per call (measured with
    sys.getrefcount), so every mesh's Python lists stayed alive for good: 0.4-0.7 MB per world build, +125 MB
    over 200 envs. Bullet itself copies the numbers (it frees its shapes on resetSimulation/disconnect), so
    the references pybullet gained during the call are dead weight: count them per object and give them back.
    A pybullet that stops leaking gains none, and then nothing is given back.
    """
    # Private copies: no other code (or thread) holds these lists, so any reference they gain during the call
    # is pybullet's, and an object listed twice cannot be given back twice. Index items are small shared ints
    # that pybullet does not keep; they are not counted.
    verts = [list(v) for v in vertices]
    held = [verts, *verts]
    idx = None
    if indices is not None:
        idx = indices.tolist() if isinstance(indices, np.ndarray) else list(indices)
        held.append(idx)
    before = list(map(sys.getrefcount, held))
    try:
        if idx is None:
            return create(p.GEOM_MESH, vertices=verts, **kwargs)
        return create(p.GEOM_MESH, vertices=verts, indices=idx, **kwargs)
    finally:
        # `held` and the counts exist before and after the call alike, so only the call's references differ.
        after = list(map(sys.getrefcount, held))
        deque(map(_py_decref, [o for o, b, a in zip(held, before, after) for _ in range(a - b)]), maxlen=0)


def _triangles(poly: Polygon) -> list[np.ndarray]:
    """Counter-clockwise triangles (3x2 arrays) covering `poly`, holes respected."""
    tris = []
    for t in shapely.constrained_delaunay_triangles(poly).geoms:
        xy = np.asarray(t.exterior.coords)[:3]
        area2 = (xy[1, 0] - xy[0, 0]) * (xy[2, 1] - xy[0, 1]) - (xy[2, 0] - xy[0, 0]) * (xy[1, 1] - xy[0, 1])
        if abs(area2) < 1e-9:
            continue
        tris.append(xy if area2 > 0 else xy[::-1])
    return tris


def extrusion_mesh(poly: Polygon, z0: float, z1: float, *, walls: bool = True) -> tuple[list, list]:
    """Vertices and triangle indices of `poly` extruded from z0 to z1 (top plus outward-facing side walls)."""
    poly = orient(poly, 1.0)
    verts: list[list[float]] = []
    idx: list[int] = []
    for tri in _triangles(poly):
        base = len(verts)
        verts.extend([[float(x), float(y), z1] for x, y in tri])
        idx.extend([base, base + 1, base + 2])
    if walls and z1 > z0:
        for ring in [poly.exterior, *poly.interiors]:
            pts = np.asarray(ring.coords)
            for a, b in zip(pts[:-1], pts[1:]):
                base = len(verts)
                verts.extend([[a[0], a[1], z0], [b[0], b[1], z0], [b[0], b[1], z1], [a[0], a[1], z1]])
                idx.extend([base, base + 1, base + 2, base, base + 2, base + 3])
    return verts, idx


def welded(vertices: Sequence, indices: Sequence[int]) -> tuple[list[list[float]], list[int]]:
    """The same triangles over shared vertices: each distinct point once, the indices pointing into that list.

    Bullet finds a triangle's neighbours through shared vertex indices; `GEOM_CONCAVE_INTERNAL_EDGE` (its internal
    edge utility) needs them to tell an edge between two coplanar triangles from a real one. Without it, a wheel
    rolling over a flat triangulated slab at 8 m/s meets the edges as steps: tilts of 30 degrees and 7.5 cm of
    bounce, against 0.1 degrees and 0.1 mm welded (`tests/sim/test_world.py`)."""
    index: dict[tuple[float, ...], int] = {}
    points: list[list[float]] = []
    out: list[int] = []
    for i in indices:
        key = tuple(float(c) for c in vertices[i])
        k = index.get(key)
        if k is None:
            k = index[key] = len(points)
            points.append(list(key))
        out.append(k)
    return points, out


def polygons(geom: Any) -> list[Polygon]:
    """The non-empty polygons of a (multi)polygon or collection."""
    if geom.is_empty:
        return []
    if isinstance(geom, Polygon):
        return [geom]
    return [g for g in getattr(geom, "geoms", []) if isinstance(g, Polygon) and not g.is_empty]
