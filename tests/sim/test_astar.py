"""A* (sim/astar.py) against scipy's Dijkstra on the route planner's graph: the same shortest-path costs."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from sim.astar import astar_chain
from sim.route import RoutePlanner
from sim.scene import generate_scene


@pytest.fixture(scope="module")
def planner() -> RoutePlanner:
    return RoutePlanner(generate_scene({"blocks": 2, "object_density": 2.0}, 3), half_width=0.3)


def test_astar_cost_is_dijkstras(planner: RoutePlanner) -> None:
    rng = np.random.default_rng(0)
    n = planner.graph.shape[0]
    g = planner.graph
    for start in rng.integers(n, size=6):
        dist = dijkstra(g, indices=int(start))
        for goal in rng.integers(n, size=8):
            cost, chain = astar_chain(
                g, planner.rows, planner.cols, planner.grid.resolution, int(start), int(goal), np.inf
            )
            assert cost == pytest.approx(dist[goal], rel=1e-12, abs=1e-12)
            # The chain is a path of graph edges whose weights add up to the cost.
            assert chain[0] == start and chain[-1] == goal
            assert sum(g[a, b] for a, b in pairwise(chain)) == pytest.approx(cost, rel=1e-12, abs=1e-12)


def test_astar_limit(planner: RoutePlanner) -> None:
    g = planner.graph
    dist = dijkstra(g, indices=0)
    goal = int(np.argmax(np.where(np.isfinite(dist), dist, -1)))
    args = (g, planner.rows, planner.cols, planner.grid.resolution, 0, goal)
    assert astar_chain(*args, dist[goal] * 0.99) == (np.inf, [])
    assert astar_chain(*args, dist[goal] * 1.01)[0] == pytest.approx(dist[goal])


def test_sample_is_deterministic_and_in_range(planner: RoutePlanner) -> None:
    a = [planner.sample(np.random.default_rng(7), 10.0, 40.0) for _ in range(2)]
    assert np.array_equal(a[0].points, a[1].points)
    rng = np.random.default_rng(1)
    for _ in range(10):
        assert 10.0 <= planner.sample(rng, 10.0, 40.0).length <= 40.0
