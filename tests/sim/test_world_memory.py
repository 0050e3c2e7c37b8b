"""World builds keep no memory: pybullet's leaked references to mesh vertex lists are given back."""

from __future__ import annotations

import gc
import sys
import warnings

import numpy as np
import psutil
import pybullet as p
import pytest

from sim.world import World, mesh_shape


@pytest.fixture()
def client():
    """A DIRECT Bullet client, disconnected after the test."""
    c = p.connect(p.DIRECT)
    yield c
    p.disconnect(c)


def _square_mesh(n: int) -> tuple[list, list]:
    """A flat n x n grid of triangles at z = 0.15 (fresh Python lists, as extrusion_mesh makes)."""
    xs = np.linspace(0.0, 4.0, n + 1)
    verts = [[float(x), float(y), 0.15] for y in xs for x in xs]
    idx = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            idx += [a, a + 1, a + n + 2, a, a + n + 2, a + n + 1]
    return verts, idx


def test_mesh_shape_gives_back_the_references_pybullet_keeps(client: int) -> None:
    verts, idx = _square_mesh(20)  # 441 vertices: indices above 256 are heap ints too
    watched = [verts, idx, verts[0], verts[-1], idx[-1]]
    before = [sys.getrefcount(o) for o in watched]
    gc.collect()
    objects0 = len(gc.get_objects())
    for _ in range(10):
        col = mesh_shape(p.createCollisionShape, verts, idx, physicsClientId=client)
        vis = mesh_shape(p.createVisualShape, verts, idx, rgbaColor=[1, 0, 0, 1], physicsClientId=client)
        hull = mesh_shape(p.createCollisionShape, verts[:30], physicsClientId=client)
    gc.collect()
    # The plain calls would have kept 10 x (441 + 441 + 30) vertex lists alive.
    assert len(gc.get_objects()) - objects0 < 100
    assert [sys.getrefcount(o) for o in watched] == before
    # The plain call keeps references (the bug this works around); if pybullet fixes it, this starts failing
    # and mesh_shape can become a plain call.
    plain = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    n0 = sys.getrefcount(plain)
    p.createCollisionShape(p.GEOM_MESH, vertices=plain, physicsClientId=client)
    assert sys.getrefcount(plain) > n0
    # The shapes are real: a ray down onto the concave mesh hits its top at z = 0.15, and numpy input works.
    p.createMultiBody(0, col, vis, physicsClientId=client)
    p.createMultiBody(0, hull, -1, basePosition=[10, 10, 0], physicsClientId=client)
    hit = p.rayTest([2.0, 2.0, 5.0], [2.0, 2.0, -1.0], physicsClientId=client)[0]
    assert hit[0] >= 0 and hit[3][2] == pytest.approx(0.15, abs=1e-4)
    box = mesh_shape(p.createCollisionShape, np.array(verts[:30]) + [0.0, 0.0, 1.0], physicsClientId=client)
    p.createMultiBody(0, box, -1, basePosition=[20, 20, 0], physicsClientId=client)
    hit = p.rayTest([20.5, 20.1, 5.0], [20.5, 20.1, -1.0], physicsClientId=client)[0]
    assert hit[0] >= 0 and hit[3][2] == pytest.approx(1.15, abs=1e-3)


def test_world_builds_do_not_keep_objects_or_memory(client: int) -> None:
    from sim.scene import generate_scene

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="no catalog was given")
        specs = [generate_scene(None, seed) for seed in range(3)]
    for spec in specs:  # warm-up: Bullet's and the allocator's pools reach their working size
        World(spec, client=client)
    gc.collect()
    objects0, rss0 = len(gc.get_objects()), psutil.Process().memory_info().rss
    for i in range(30):
        World(specs[i % 3], client=client)
    gc.collect()
    # Before the fix every build left ~3,000 vertex lists behind (90,000 here) and ~0.45 MB of RSS (13 MB).
    grown_objects = len(gc.get_objects()) - objects0
    grown_mb = (psutil.Process().memory_info().rss - rss0) / 2**20
    assert grown_objects < 2_000, grown_objects
    assert grown_mb < 5.0, grown_mb


def test_trim_heap_gives_freed_scene_arrays_back() -> None:
    """Scene-sized arrays freed from the heap stay in RSS until `trim_heap` (called after each new scene)."""
    from sim.envs.worlds import _malloc_trim, trim_heap

    if _malloc_trim() is None:
        pytest.skip("no glibc malloc_trim here")
    rss = lambda: psutil.Process().memory_info().rss / 2**20  # noqa: E731
    big = np.ones(2**20)  # 8 MB: mmapped; its free raises glibc's mmap threshold past the arrays below
    del big
    blocks, pins = [], []
    for _ in range(12):
        blocks.append(np.ones(2**19))  # 4 MB, now served from the heap
        pins.append(np.ones(2**13))  # 64 kB above each: the freed blocks are holes, not the heap's top
    del blocks
    before = rss()
    trim_heap()
    assert before - rss() > 24.0, (before, rss())
    del pins
